"""``offtrack vo-eval SEQUENCE``: the visual odometry alone on a KITTI-format sequence with poses, scored.

:func:`evaluate_vo` runs :class:`sensor.vo.StereoOdometry` (the loop's settings: sub-pixel refinement, seed 0, unless
told otherwise) over every frame of the sequence in order — raw images rectified with a calibration first, as
``offtrack estimate`` does; a frame without images skipped, the next one measured over the actual gap — and scores
it against the poses (:mod:`sensor.recordings.vo_metrics`):

* per frame, the relative pose error (translation [m], rotation [°]) against the true motion since the frame
  measured before (Sturm et al. 2012), and the reason of every failed frame;
* the KITTI odometry metric over 100–800 m segments (Geiger, Lenz & Urtasun 2012) and, labelled apart, over
  5–50 m segments (a short sequence has none of KITTI's lengths), on the trajectory chained from the motions — a
  failed frame is bridged by the motion before it (constant velocity; counted in ``bridged_frames``);
* the drift figure (:func:`plot_drift`): the trajectories from above, the error per frame, the error per segment
  length.

The result is one JSON-ready dict (``offtrack vo-eval --json`` prints it as one object; ``--out`` writes
``vo_eval.json`` and ``drift.png``).
"""

from __future__ import annotations

import math
import time as wallclock
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sensor.recordings.kitti import KittiFolder
from sensor.recordings.poses import read_kitti_poses
from sensor.recordings.vo_metrics import (
    KITTI_LENGTHS,
    SHORT_LENGTHS,
    chain_motions,
    kitti_metric,
    path_distances,
    relative_pose_error,
)
from sensor.vo import StereoOdometry
from vehicle_model.errors import InputError

from .inputs import camera_model, open_recording

__all__ = ["evaluate_vo", "plot_drift"]


def evaluate_vo(
    sequence: Path,
    *,
    poses: Path | None = None,
    calibration: Path | None = None,
    calib: Path | None = None,
    refinement: int = 2,
    seed: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The odometry on a KITTI-format sequence against its poses (module notes).

    Parameters
    ----------
    sequence : Path
        A KITTI-odometry folder (``image_0/``, ``image_1/``, ``times.txt``; ``calib.txt`` for rectified images).
    poses : Path, optional
        The left camera's poses, KITTI format (default: the folder's ``poses.txt``).
    calibration, calib : Path, optional
        As ``offtrack estimate``: an OpenCV YAML for raw images, or a KITTI ``calib.txt``.
    refinement, seed : int
        The odometry's match refinement and RANSAC seed.
    progress : callable, optional
        ``progress(frames done, frames in all)``.

    Returns
    -------
    (dict, dict)
        The JSON-ready result and the arrays behind the figure (``truth``, ``estimate`` poses, ``rpe``).

    Raises
    ------
    InputError
        Not a KITTI folder, no poses or a count that is not one per frame, no camera model — before any work.
    """
    started = wallclock.perf_counter()
    if refinement not in (0, 1, 2):
        raise InputError(f"--refinement {refinement!r}: allowed: 0 (none), 1 (pixel), 2 (sub-pixel)")
    recording = open_recording(Path(sequence))
    if not isinstance(recording, KittiFolder):
        raise InputError(f"SEQUENCE {sequence}: allowed: a KITTI-odometry folder (image_0/, image_1/, times.txt)")
    pose_file = Path(poses) if poses is not None else recording.poses_file
    if pose_file is None:
        raise InputError(f"SEQUENCE {sequence}: has no poses.txt; give --poses FILE (KITTI format, one per frame)")
    truth = read_kitti_poses(pose_file, len(recording.slots))
    camera, cal = camera_model(recording, calibration, calib)
    vo = StereoOdometry(camera.vo_config(refinement=refinement), seed=seed)
    n = len(recording.slots)
    rpe = np.full((n, 2), np.nan)
    codes = [""] * n
    motions: list[np.ndarray] = []
    measured: list[int] = []  # the frames whose images were there, in order
    bridged = 0
    cpu = []
    for slot, left, right in recording.pairs():
        if left is None or right is None:
            codes[slot.index] = slot.missing or "image_missing"
            continue
        if cal is not None:
            left, right = cal.rectify(left, right)
        c0 = wallclock.thread_time()
        result = vo.process(left, right)
        cpu.append(wallclock.thread_time() - c0)
        if measured:
            true_motion = np.linalg.solve(truth[slot.index], truth[measured[-1]])  # inv(T_k)·T_{k−1}
            motion = result.motion if result.valid else None
            rpe[slot.index] = relative_pose_error(motion, true_motion)
            if motion is None:
                codes[slot.index] = result.code or "vo_failed"
                bridged += 1
                motion = motions[-1] if motions else np.eye(4)  # constant velocity over a failed frame
            motions.append(motion)
        measured.append(slot.index)
        if progress is not None:
            progress(slot.index + 1, n)
    estimate_measured = chain_motions(motions)
    truth_measured = np.linalg.solve(truth[measured[0]], truth[measured])  # in the first measured frame's frame
    length = float(path_distances(truth_measured)[-1])
    kitti = kitti_metric(truth_measured, estimate_measured, KITTI_LENGTHS)
    short = kitti_metric(truth_measured, estimate_measured, SHORT_LENGTHS)
    valid = np.isfinite(rpe[:, 0])
    failed = {}
    for code in codes:
        if code:
            failed[code] = failed.get(code, 0) + 1
    result_dict: dict[str, Any] = {
        "benchmark": "vo_eval",
        "sequence": str(Path(sequence)),
        "poses": str(pose_file),
        "frames": n,
        "measured_frames": len(measured),
        "valid_frames": int(valid.sum()),
        "bridged_frames": bridged,
        "failures": failed,
        "length_m": length,
        "kitti": {"label": "KITTI 100–800 m segments (Geiger, Lenz & Urtasun 2012)", **kitti},
        "short": {"label": "short 5–50 m segments (not KITTI's lengths)", **short},
        "rpe": {
            "frames": int(valid.sum()),
            "translation_mean_m": float(np.mean(rpe[valid, 0])) if valid.any() else math.nan,
            "translation_rms_m": float(np.sqrt(np.mean(rpe[valid, 0] ** 2))) if valid.any() else math.nan,
            "rotation_mean_deg": math.degrees(float(np.mean(rpe[valid, 1]))) if valid.any() else math.nan,
            "rotation_rms_deg": math.degrees(float(np.sqrt(np.mean(rpe[valid, 1] ** 2)))) if valid.any() else math.nan,
            "per_frame": [
                {
                    "frame": k,
                    "translation_m": float(rpe[k, 0]),
                    "rotation_deg": math.degrees(float(rpe[k, 1])),
                    "reason": codes[k],
                }
                for k in range(n)
            ],
        },
        "cpu_ms_median": 1e3 * float(np.median(cpu[1:])) if len(cpu) > 1 else math.nan,
        "settings": {"refinement": refinement, "seed": seed, "f_px": camera.f, "baseline_m": camera.baseline},
        "wall_s": wallclock.perf_counter() - started,
    }
    arrays = {"truth": truth_measured, "estimate": estimate_measured, "rpe": rpe, "frames": np.array(measured)}
    return result_dict, arrays


def plot_drift(path: Path, result: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    """``drift.png``: the trajectories from above (x right, z forward of the first camera), the relative pose error
    per frame, and the segment errors per length."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..run.plots import save_figure

    truth, estimate, rpe = arrays["truth"], arrays["estimate"], arrays["rpe"]
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    ax = axes[0]
    ax.plot(truth[:, 0, 3], truth[:, 2, 3], "k-", lw=1.2, label="reference")
    ax.plot(estimate[:, 0, 3], estimate[:, 2, 3], color="tab:blue", lw=1.0, label="odometry")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m] (right of the first camera)")
    ax.set_ylabel("z [m] (ahead of the first camera)")
    ax.set_title(f"trajectory, {result['length_m']:.1f} m", fontsize=9)
    ax.legend(fontsize=8)
    ax = axes[1]
    frames = np.arange(len(rpe))
    ax.plot(frames, 1e3 * rpe[:, 0], color="tab:blue", lw=0.9, label="translation [mm]")
    ax2 = ax.twinx()
    ax2.plot(frames, np.degrees(rpe[:, 1]) * 1e3, color="tab:orange", lw=0.9, label="rotation [mdeg]")
    ax.set_xlabel("frame")
    ax.set_ylabel("translation error [mm]", color="tab:blue")
    ax2.set_ylabel("rotation error [mdeg]", color="tab:orange")
    r = result["rpe"]
    ax.set_title(
        f"relative pose error per frame: {1e3 * r['translation_mean_m']:.2f} mm, "
        f"{1e3 * r['rotation_mean_deg']:.2f} mdeg mean",
        fontsize=9,
    )
    ax = axes[2]
    for key, marker in (("short", "o"), ("kitti", "s")):
        per = result[key]["per_length"]
        lengths = [float(k) for k, v in per.items() if v["segments"]]
        values = [per[f"{v:g}"]["translation_percent"] for v in lengths]
        if lengths:
            ax.plot(lengths, values, marker=marker, label=result[key]["label"])
    ax.set_xscale("log")
    ax.set_xlabel("segment length [m]")
    ax.set_ylabel("translation error [%]")
    ax.set_title("drift per segment length", fontsize=9)
    ax.legend(fontsize=7)
    fig.suptitle(f"vo-eval {result['sequence']}", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def result_lines(result: dict[str, Any]) -> list[str]:
    """What ``offtrack vo-eval`` prints without ``--json``."""
    lines = [
        f"{result['sequence']}: {result['frames']} frames, {result['valid_frames']} with a motion, "
        f"{result['length_m']:.1f} m; failures: "
        + (", ".join(f"{code} {n}" for code, n in result["failures"].items()) or "none")
    ]
    for key in ("kitti", "short"):
        block = result[key]
        if block["segments"]:
            per = ", ".join(
                f"{k} m {v['translation_percent']:.2f} %" for k, v in block["per_length"].items() if v["segments"]
            )
            lines.append(
                f"{block['label']}: translation {block['translation_percent']:.2f} %, rotation "
                f"{block['rotation_deg_per_m']:.4f} °/m over {block['segments']} segments ({per})"
            )
        else:
            lines.append(f"{block['label']}: no segment (the sequence is {result['length_m']:.1f} m long)")
    r = result["rpe"]
    lines.append(
        f"relative pose error per frame: translation {1e3 * r['translation_mean_m']:.3f} mm mean "
        f"({1e3 * r['translation_rms_m']:.3f} RMS), rotation {1e3 * r['rotation_mean_deg']:.2f} mdeg mean "
        f"({1e3 * r['rotation_rms_deg']:.2f} RMS) over {r['frames']} frames; {result['cpu_ms_median']:.1f} ms CPU "
        "per frame (median)"
    )
    return lines
