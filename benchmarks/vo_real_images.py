"""The visual odometry's stages on real stereo images, beside the rendered benchmark, one thread.

No real driving sequence ships with a package, but real stereo pairs do: the Middlebury 2014 motorcycle pair in
scikit-image's data (``skimage.data.stereo_motorcycle``, 741×500) and the Middlebury 2006 aloe pair and a street
pair in OpenCV's samples (Debian ``opencv-doc``: ``aloeL.jpg``/``aloeR.jpg`` 1282×1110, cut here to a 1282×391
band like a road camera's; ``left.jpg``/``right.jpg`` 612×459). Each pair becomes a short sequence by zooming both
images about their centre by 1.5 % per frame and panning 1 px (a camera driving towards the scene: real texture,
plausible flow and disparity); the rendered ``roundabout-3`` frames of ``offtrack bench vo`` run beside them. Per
sequence the thread CPU time of each stage per frame (the fastest of ``--passes``; median over the frames after the
first), the features per image, the matches and the inliers, and the matching stage cut into its parts (sparse
circle, dense circle, outlier removal, prior ranges, bucketing, refinement)::

    .venv/bin/python benchmarks/vo_real_images.py [--frames 12] [--passes 3] [--refinement 1] [--json]

With ``--baseline COMMIT`` it times the odometry of that commit (``sensor/`` extracted with ``git archive``, as
``benchmarks/vo_speed_against_baseline.py`` does) against this tree's on the same frames instead, the two
interleaved pass by pass (per frame the fastest pass counts), checks that both give the same matches and motions, and
prints the ratios current / baseline of the total, the matching stage's and each of its parts' CPU time per frame.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread, before numpy is imported

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
OPENCV_DATA = Path("/usr/share/doc/opencv-doc/examples/data")

PARTS = {
    "circle": "sensor.vo.matching.circle",
    "outliers": "sensor.vo.matching.remove_outliers",
    "prior_ranges": "sensor.vo.matching.compute_prior_ranges",
    "bucketing": "sensor.vo.matching.bucket_matches",
    "refinement": "sensor.vo.matching.refine_matches",
    "positions": "sensor.vo.matching.positions",
}


def real_pairs() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The real stereo pairs found on this machine, grey uint8 (module notes)."""
    import cv2

    pairs: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    try:
        from skimage import data

        left, right, _ = data.stereo_motorcycle()
        pairs["middlebury-motorcycle"] = tuple(cv2.cvtColor(im, cv2.COLOR_RGB2GRAY) for im in (left, right))
    except ImportError:
        print("scikit-image not installed: no Middlebury motorcycle pair", file=sys.stderr)
    for name, (a, b), band in (
        ("middlebury-aloe", ("aloeL.jpg", "aloeR.jpg"), (360, 751)),
        ("opencv-street", ("left.jpg", "right.jpg"), None),
    ):
        paths = [OPENCV_DATA / a, OPENCV_DATA / b]
        if not all(p.is_file() for p in paths):
            print(f"{paths[0]} not found (apt-get install opencv-doc): no {name} pair", file=sys.stderr)
            continue
        images = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in paths]
        if band is not None:
            images = [im[band[0] : band[1]] for im in images]
        pairs[name] = (images[0], images[1])
    return pairs


def zoom_sequence(left: np.ndarray, right: np.ndarray, frames: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """``frames`` pairs: both images zoomed about their centre by 1.5 % per frame and panned 1 px."""
    import cv2

    h, w = left.shape
    out_l, out_r = [], []
    for k in range(frames):
        scale = 1.0 + 0.015 * k
        matrix = cv2.getRotationMatrix2D((0.5 * (w - 1), 0.5 * (h - 1)), 0.0, scale)
        matrix[0, 2] += k
        out_l.append(cv2.warpAffine(left, matrix, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT))
        out_r.append(cv2.warpAffine(right, matrix, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT))
    return out_l, out_r


@contextmanager
def part_clock() -> Iterator[dict[str, float]]:
    """Thread CPU time of the matching stage's parts, accumulated while the block runs."""
    import importlib

    spent: dict[str, float] = defaultdict(float)
    saved = []
    for part, dotted in PARTS.items():
        module_name, name = dotted.rsplit(".", 1)
        module = importlib.import_module(module_name)
        original = getattr(module, name)

        def timed(*args: Any, _f: Callable[..., Any] = original, _p: str = part, **kwargs: Any) -> Any:
            c0 = time.thread_time()
            try:
                return _f(*args, **kwargs)
            finally:
                spent[_p] += time.thread_time() - c0

        setattr(module, name, timed)
        saved.append((module, name, original))
    try:
        yield spent
    finally:
        for module, name, original in saved:
            setattr(module, name, original)


def profile(left: list[np.ndarray], right: list[np.ndarray], passes: int, refinement: int = 1) -> dict[str, Any]:
    """Stage CPU times per frame (fastest pass, median over frames 1…), features, matches, the matching parts."""
    import cv2

    from sensor.vo import StereoOdometry, VOConfig

    h, w = left[0].shape
    config = VOConfig(f=0.8 * w, cu=0.5 * (w - 1), cv=0.5 * (h - 1), baseline=0.5, refinement=refinement)
    cv2.setNumThreads(1)
    n = len(left)
    stages = np.full((n, 4), np.inf)
    parts = [defaultdict(lambda: np.inf) for _ in range(n)]
    vo = StereoOdometry(config, seed=0)
    results = []
    for k in range(passes + 1):
        vo.reset()
        results = []
        for i in range(n):
            with part_clock() as spent:
                c0 = time.thread_time()
                result = vo.process(left[i], right[i])
                total = time.thread_time() - c0
            results.append(result)
            if k == 0:
                continue  # warm-up: kernels loaded, caches filled
            stages[i] = np.minimum(stages[i], [total, result.cpu_features, result.cpu_matching, result.cpu_motion])
            for part, value in spent.items():
                parts[i][part] = min(parts[i][part], value)
    from sensor.vo.features import extract_features

    feats = extract_features(left[0], config)
    steady = slice(1, None)
    names = sorted({p for frame in parts[1:] for p in frame})
    return {
        "width": w,
        "height": h,
        "frames": n,
        "cpu_ms_total": 1e3 * float(np.median(stages[steady, 0])),
        "cpu_ms_features": 1e3 * float(np.median(stages[steady, 1])),
        "cpu_ms_matching": 1e3 * float(np.median(stages[steady, 2])),
        "cpu_ms_motion": 1e3 * float(np.median(stages[steady, 3])),
        "matching_parts_ms": {p: 1e3 * float(np.median([frame.get(p, 0.0) for frame in parts[1:]])) for p in names},
        "features_dense": len(feats.dense),
        "features_sparse": len(feats.sparse),
        "features_per_megapixel": len(feats.dense) / (w * h / 1e6),
        "mean_matches": float(np.mean([r.n_matches for r in results[1:]])),
        "mean_inliers": float(np.mean([r.n_inliers for r in results[1:]])),
        "valid_fraction": float(np.mean([r.valid for r in results[1:]])),
    }


def compare(left: list[np.ndarray], right: list[np.ndarray], passes: int, refinement: int, old: Any) -> dict:
    """Per-frame CPU time of the baseline's and this tree's odometry and of their matching parts
    (:data:`PARTS`), interleaved; identical output checked."""
    import cv2

    from sensor.vo import StereoOdometry, VOConfig, odometry

    h, w = left[0].shape
    settings = {"f": 0.8 * w, "cu": 0.5 * (w - 1), "cv": 0.5 * (h - 1), "baseline": 0.5, "refinement": refinement}
    cv2.setNumThreads(1)
    impls = {
        "baseline": old[0].StereoOdometry(old[1].VOConfig(**settings), 0),
        "current": StereoOdometry(VOConfig(**settings), 0),
    }
    names = list(PARTS)  # the matching stage's parts, each timed in both trees
    spent = {name: dict.fromkeys(names, 0.0) for name in impls}
    patched = []
    for name, module in (("baseline", old[0]), ("current", odometry)):
        scope = module.match_frames.__globals__  # the matching module of that tree
        for part in names:
            attribute = PARTS[part].rsplit(".", 1)[1]
            if attribute not in scope:
                continue
            original = scope[attribute]

            def timed(*args: Any, _f: Callable[..., Any] = original, _name: str = name, _part: str = part) -> Any:
                c0 = time.thread_time()
                try:
                    return _f(*args)
                finally:
                    spent[_name][_part] += time.thread_time() - c0

            scope[attribute] = timed
            patched.append((scope, attribute, original))
    n = len(left)
    columns = ("total", "matching", *names)
    cpu = {name: np.full((n, len(columns)), np.inf) for name in impls}
    outputs: dict[str, list] = {}
    try:
        for k in range(passes + 1):
            for name, vo in impls.items():
                vo.reset()
                outputs[name] = []
                for i in range(n):
                    spent[name] = dict.fromkeys(names, 0.0)
                    c0 = time.thread_time()
                    result = vo.process(left[i], right[i])
                    total = time.thread_time() - c0
                    outputs[name].append(
                        (result.matches.tobytes(), None if result.motion is None else result.motion.tobytes())
                    )
                    if k:
                        row = [total, result.cpu_matching, *(spent[name][p] for p in names)]
                        cpu[name][i] = np.minimum(cpu[name][i], row)
    finally:
        for scope, attribute, original in patched:
            scope[attribute] = original
    same = outputs["baseline"] == outputs["current"]
    med = {name: 1e3 * np.median(values[1:], axis=0) for name, values in cpu.items()}
    parts = columns
    return {
        "width": w,
        "height": h,
        "identical_output": same,
        "baseline_ms": {p: float(med["baseline"][j]) for j, p in enumerate(parts)},
        "current_ms": {p: float(med["current"][j]) for j, p in enumerate(parts)},
        **{
            f"ratio_{p}": float(med["current"][j] / med["baseline"][j])
            for j, p in enumerate(parts)
            if med["baseline"][j]
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=12)
    parser.add_argument("--passes", type=int, default=3)
    parser.add_argument("--refinement", type=int, default=1, help="1 as offtrack bench vo (libviso2's); 2 as the loop")
    parser.add_argument("--baseline", help="a commit: time its odometry against this tree's, interleaved")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    from scenarios.bench.vo import rendered_sequence

    if args.baseline:
        import tempfile

        from vo_speed_against_baseline import load_baseline

        with tempfile.TemporaryDirectory(prefix="offtrack-vo-baseline-") as tmp:
            old = load_baseline(Path(tmp), args.baseline)
            sequences = {"rendered-roundabout-3": rendered_sequence(max(args.frames, 2), 0)}
            out = {"rendered-roundabout-3": compare(list(sequences["rendered-roundabout-3"].left),
                                                    list(sequences["rendered-roundabout-3"].right),
                                                    args.passes, args.refinement, old)}  # fmt: skip
            for name, (left, right) in real_pairs().items():
                out[name] = compare(*zoom_sequence(left, right, args.frames), args.passes, args.refinement, old)
        if args.json:
            print(json.dumps({"benchmark": "vo_real_images_ab", "baseline": args.baseline, "sequences": out}))
            return
        shown = ("total", "matching", *PARTS)
        print(f"baseline {args.baseline} → this tree: ms per frame (ratio)")
        print("| sequence | " + " | ".join(shown) + " | same |")
        print("|---|" + "---|" * (len(shown) + 1))
        for name, r in out.items():
            b, c = r["baseline_ms"], r["current_ms"]
            cells = [f"{b[p]:.2f} → {c[p]:.2f} ({r.get('ratio_' + p, float('nan')):.3f})" for p in shown]
            print(f"| {name} | " + " | ".join(cells) + f" | {r['identical_output']} |")
        return

    rows = {}
    rendered = rendered_sequence(max(args.frames, 2), 0)
    rows["rendered-roundabout-3"] = profile(list(rendered.left), list(rendered.right), args.passes, args.refinement)
    for name, (left, right) in real_pairs().items():
        rows[name] = profile(*zoom_sequence(left, right, args.frames), args.passes, args.refinement)
    if args.json:
        print(json.dumps({"benchmark": "vo_real_images", "sequences": rows}))
        return
    print("| sequence | size | features (/MP) | total ms | features ms | matching ms | motion ms | matches | inliers |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, r in rows.items():
        print(
            f"| {name} | {r['width']}×{r['height']} | {r['features_dense']} ({r['features_per_megapixel']:.0f}) | "
            f"{r['cpu_ms_total']:.2f} | {r['cpu_ms_features']:.2f} | {r['cpu_ms_matching']:.2f} | "
            f"{r['cpu_ms_motion']:.2f} | {r['mean_matches']:.0f} | {r['mean_inliers']:.0f} |"
        )
    print()
    for name, r in rows.items():
        print(name, " ".join(f"{p} {v:.2f}" for p, v in r["matching_parts_ms"].items()))


if __name__ == "__main__":
    main()
