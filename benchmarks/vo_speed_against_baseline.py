"""The visual odometry's CPU time and accuracy in this tree against a baseline commit's, on the same frames.

The baseline (``--baseline``, default :data:`BASELINE`, the VO the speed target of ``offtrack bench vo`` is set
against, benchmarks/README.md) is any commit of this repository. Extracts ``sensor/`` of the baseline commit
with ``git archive`` into a temporary folder, imports its odometry next to the current one (in this process,
under its own module objects) and runs both, one thread each (OpenCV, BLAS and numba limited to one thread), on the
cached rendered ``roundabout-3`` sequences of :func:`scenarios.bench.vo.rendered_sequence` for several seeds. Each pass
runs the baseline and then the current implementation over a sequence; per frame the fastest of the passes counts
(thread CPU time, robust to other processes on a shared machine). Prints the CPU-time ratio and, per implementation, the
relative pose error per frame (translation [mm], rotation [mdeg]) against the rendered ground truth, mean inliers and
valid frames, with the differences to the baseline (goal: within 3 %). Run from the repository root::

    .venv/bin/python benchmarks/vo_speed_against_baseline.py [--baseline COMMIT] [--seeds 5] [--frames 40] \
        [--passes 3] [--json]
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread, before numpy is imported

import argparse  # noqa: E402
import importlib  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tarfile  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from types import ModuleType  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
BASELINE = "ccc8e1e"
"""The default baseline commit: the odometry before the speed work of benchmarks/README.md, "Visual odometry"."""
HEADER = "| seed | CPU ms baseline | CPU ms current | t RPE mm (b / c) | r RPE mdeg (b / c) | inliers (b / c) | valid |"
sys.path.insert(0, str(REPO))


def load_baseline(folder: Path, commit: str = BASELINE) -> tuple[ModuleType, ModuleType]:
    """``sensor.vo.odometry`` and ``sensor.vo.config`` of ``commit``, imported beside the current ones.

    The current ``sensor`` modules are set aside while the baseline's are imported from ``folder``
    and put back afterwards; the baseline's functions keep their own module globals.
    """
    archive = subprocess.run(
        ["git", "-C", str(REPO), "archive", "--format=tar", commit, "sensor"], check=True, capture_output=True
    ).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    ours = {k: v for k, v in sys.modules.items() if k == "sensor" or k.startswith("sensor.")}
    for key in ours:
        del sys.modules[key]
    sys.path.insert(0, str(folder))
    try:
        odometry = importlib.import_module("sensor.vo.odometry")
        config = importlib.import_module("sensor.vo.config")
    finally:
        sys.path.remove(str(folder))
        for key in [k for k in sys.modules if k == "sensor" or k.startswith("sensor.")]:
            del sys.modules[key]
        sys.modules.update(ours)
    return odometry, config


def _run(vo: Any, sequence: Any) -> tuple[np.ndarray, list]:
    vo.reset()
    cpu, results = [], []
    for left, right in zip(sequence.left, sequence.right, strict=True):
        c0 = time.thread_time()
        results.append(vo.process(left, right))
        cpu.append(time.thread_time() - c0)
    return np.array(cpu), results


def _accuracy(results: list, truth: np.ndarray) -> dict[str, Any]:
    from scenarios.bench.vo import frame_errors

    errors = frame_errors(results, truth)
    valid = np.isfinite(errors[:, 0])
    return {
        "t_rpe_mm": 1e3 * float(np.mean(errors[valid, 0])) if valid.any() else math.nan,
        "r_rpe_mdeg": 1e3 * math.degrees(float(np.mean(errors[valid, 1]))) if valid.any() else math.nan,
        "mean_inliers": float(np.mean([r.n_inliers for r in results[1:]])),
        "valid_frames": int(valid.sum()),
    }


def compare(seeds: int = 5, frames: int = 40, passes: int = 3, baseline: str = BASELINE) -> dict[str, Any]:
    """Speed ratio and accuracy of the baseline and the current odometry over ``seeds`` sequences."""
    import cv2

    from scenarios.bench.vo import relative_motions, rendered_sequence, vo_calibration
    from sensor.vo import StereoOdometry, VOConfig

    cv2.setNumThreads(1)
    with tempfile.TemporaryDirectory(prefix="offtrack-vo-baseline-") as tmp:
        old_odometry, old_config = load_baseline(Path(tmp), baseline)
        rows, cpu_old, cpu_new = [], [], []
        for seed in range(seeds):
            sequence = rendered_sequence(frames, seed)
            calibration = vo_calibration(sequence)
            impls = {
                "baseline": old_odometry.StereoOdometry(old_config.VOConfig.from_horizontal_fov(*calibration), seed),
                "current": StereoOdometry(VOConfig.from_horizontal_fov(*calibration), seed),
            }
            for vo in impls.values():
                _run(vo, sequence)  # warm-up: JIT cache load, allocator, OpenCV
            best = {name: np.full(len(sequence), np.inf) for name in impls}
            last: dict[str, list] = {}
            for _ in range(passes):
                for name, vo in impls.items():
                    cpu, last[name] = _run(vo, sequence)
                    best[name] = np.minimum(best[name], cpu)
            truth = relative_motions(sequence.poses)
            same = sum(
                a.matches.shape == b.matches.shape
                and np.array_equal(a.matches, b.matches)
                and np.array_equal(a.inliers, b.inliers)
                for a, b in zip(last["baseline"][1:], last["current"][1:], strict=True)
            )
            cpu_old.append(best["baseline"][1:])
            cpu_new.append(best["current"][1:])
            rows.append(
                {
                    "seed": seed,
                    "frames": len(sequence),
                    "cpu_ms_baseline": 1e3 * float(np.median(best["baseline"][1:])),
                    "cpu_ms_current": 1e3 * float(np.median(best["current"][1:])),
                    "identical_frames": int(same),
                    "baseline": _accuracy(last["baseline"], truth),
                    "current": _accuracy(last["current"], truth),
                }
            )
    old_all, new_all = np.concatenate(cpu_old), np.concatenate(cpu_new)
    summary = {}
    for key in ("t_rpe_mm", "r_rpe_mdeg", "mean_inliers"):
        old = float(np.mean([r["baseline"][key] for r in rows]))
        new = float(np.mean([r["current"][key] for r in rows]))
        summary[key] = {"baseline": old, "current": new, "relative_change": (new - old) / old}
    return {
        "benchmark": "vo_speed_against_baseline",
        "baseline": baseline,
        "seeds": seeds,
        "frames_per_seed": frames,
        "passes": passes,
        "cpu_ms_median_baseline": 1e3 * float(np.median(old_all)),
        "cpu_ms_median_current": 1e3 * float(np.median(new_all)),
        "cpu_ms_p90_baseline": 1e3 * float(np.percentile(old_all, 90)),
        "cpu_ms_p90_current": 1e3 * float(np.percentile(new_all, 90)),
        "cpu_ratio": float(np.median(old_all) / np.median(new_all)),
        "cpu_ratio_total": float(old_all.sum() / new_all.sum()),
        "identical_frames": int(sum(r["identical_frames"] for r in rows)),
        "compared_frames": int(sum(r["frames"] - 1 for r in rows)),
        "accuracy": summary,
        "per_seed": rows,
    }


def _print_table(result: dict[str, Any]) -> None:
    print(
        f"VO CPU time per frame (median of {result['compared_frames']} frames, one thread): "
        f"{result['baseline']} {result['cpu_ms_median_baseline']:.2f} ms, "
        f"current {result['cpu_ms_median_current']:.2f} ms, "
        f"ratio {result['cpu_ratio']:.2f}× (total {result['cpu_ratio_total']:.2f}×); "
        f"identical matches and inliers in {result['identical_frames']}/{result['compared_frames']} frames"
    )
    print(HEADER)
    print("|---|---|---|---|---|---|---|")
    for r in result["per_seed"]:
        b, c = r["baseline"], r["current"]
        print(
            f"| {r['seed']} | {r['cpu_ms_baseline']:.2f} | {r['cpu_ms_current']:.2f} | "
            f"{b['t_rpe_mm']:.3f} / {c['t_rpe_mm']:.3f} | {b['r_rpe_mdeg']:.2f} / {c['r_rpe_mdeg']:.2f} | "
            f"{b['mean_inliers']:.1f} / {c['mean_inliers']:.1f} | {b['valid_frames']} / {c['valid_frames']} |"
        )
    for key, figures in result["accuracy"].items():
        print(
            f"{key}: baseline {figures['baseline']:.4g}, current {figures['current']:.4g}, "
            f"change {100 * figures['relative_change']:+.2f} %"
        )


def main(argv: list[str] | None = None) -> None:
    """Command-line entry."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--baseline", default=BASELINE, help=f"commit to compare with (default {BASELINE})")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--passes", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    args = parser.parse_args(argv)
    result = compare(args.seeds, args.frames, args.passes, args.baseline)
    if args.json:
        print(json.dumps(result))
    else:
        _print_table(result)


if __name__ == "__main__":
    main()
