"""How good a visual odometry is against reference poses: the relative pose error per frame and the KITTI metric.

* **Relative pose error** (:func:`relative_pose_error`): per frame, the estimated motion ``Tr_delta`` (libviso2's:
  a point of the previous camera frame in the current one; docs/visual_odometry.md §10) against the true one
  ``inv(T_k)·T_{k−1}`` from the poses ``T_ref←camera``: ``E = inv(Tr_true)·Tr_est``, its translation's length [m]
  and its rotation's angle ``acos((tr R − 1)/2)`` [rad] (Sturm et al. 2012's RPE over one frame).
* **KITTI odometry metric** (:func:`kitti_segment_errors`, :func:`kitti_metric`; Geiger, Lenz & Urtasun 2012, the
  devkit's ``evaluate_odometry``): from every 10th frame, for each segment length ``L``, the first frame at least
  ``L`` of path further on; the error of the estimated segment against the true one,
  ``E = inv(inv(P_a)·P_b)·(inv(G_a)·G_b)``, gives the translation error ``‖t_E‖/L`` and the rotation error
  ``angle(R_E)/L``; averaged over all segments of all lengths. KITTI's lengths are 100, 200, …, 800 m
  (:data:`KITTI_LENGTHS`); a shorter sequence is also scored over :data:`SHORT_LENGTHS`, reported apart.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "KITTI_LENGTHS",
    "KITTI_STEP",
    "SHORT_LENGTHS",
    "chain_motions",
    "kitti_metric",
    "kitti_segment_errors",
    "path_distances",
    "relative_pose_error",
    "true_motions",
]

KITTI_LENGTHS: tuple[float, ...] = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)
"""Segment lengths of the KITTI odometry benchmark [m] (Geiger, Lenz & Urtasun 2012)."""
SHORT_LENGTHS: tuple[float, ...] = (5.0, 10.0, 20.0, 50.0)
"""Shorter segments [m] for sequences too short for KITTI's (a rendered run, a yard test)."""
KITTI_STEP = 10
"""First frames of the segments: every 10th, as the devkit."""


def _angle(rotation: np.ndarray) -> float:
    """Rotation angle of a 3×3 rotation [rad]: the devkit's ``rotationError``, ``acos((tr R − 1)/2)``, written as
    ``atan2(‖R − Rᵀ‖/(2√2), (tr R − 1)/2)`` — the same angle, without acos losing half the digits near zero."""
    r = np.asarray(rotation, dtype=float)[:3, :3]
    sine = 0.5 * math.sqrt((r[2, 1] - r[1, 2]) ** 2 + (r[0, 2] - r[2, 0]) ** 2 + (r[1, 0] - r[0, 1]) ** 2)
    return math.atan2(sine, 0.5 * (float(np.trace(r)) - 1.0))


def relative_pose_error(motion: np.ndarray | None, true_motion: np.ndarray) -> tuple[float, float]:
    """Translation [m] and rotation [rad] error of one frame's ``Tr_delta`` (NaN, NaN without a motion)."""
    if motion is None:
        return math.nan, math.nan
    error = np.linalg.solve(np.asarray(true_motion, dtype=float), np.asarray(motion, dtype=float))
    return float(np.linalg.norm(error[:3, 3])), _angle(error)


def true_motions(poses: np.ndarray) -> np.ndarray:
    """True ``Tr_delta`` of each frame after the first, ``inv(T_k)·T_{k−1}``: ``(n − 1, 4, 4)``."""
    poses = np.asarray(poses, dtype=float)
    return np.linalg.solve(poses[1:], poses[:-1])


def chain_motions(motions: Sequence[np.ndarray]) -> np.ndarray:
    """Camera poses in the first frame's frame from the frames' ``Tr_delta``: ``T_k = T_{k−1}·inv(Tr_delta_k)``."""
    poses = [np.eye(4)]
    for motion in motions:
        poses.append(poses[-1] @ np.linalg.inv(motion))
    return np.array(poses)


def path_distances(poses: np.ndarray) -> np.ndarray:
    """Distance travelled along the poses' positions from the first [m] (the devkit's ``trajectoryDistances``)."""
    steps = np.linalg.norm(np.diff(np.asarray(poses)[:, :3, 3], axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])


def kitti_segment_errors(
    truth: np.ndarray, estimate: np.ndarray, lengths: Sequence[float] = KITTI_LENGTHS, step: int = KITTI_STEP
) -> list[dict[str, float]]:
    """Every segment's error (module notes): ``first``, ``length`` [m], ``translation`` [m/m], ``rotation``
    [rad/m], ``frames``."""
    truth = np.asarray(truth, dtype=float)
    estimate = np.asarray(estimate, dtype=float)
    dist = path_distances(truth)
    out = []
    for first in range(0, len(truth), step):
        for length in lengths:
            beyond = np.flatnonzero(dist[first:] > dist[first] + length)  # the devkit's lastFrameFromSegmentLength
            if beyond.size == 0:
                continue
            last = first + int(beyond[0])
            delta_true = np.linalg.solve(truth[first], truth[last])
            delta_est = np.linalg.solve(estimate[first], estimate[last])
            error = np.linalg.solve(delta_est, delta_true)
            out.append(
                {
                    "first": first,
                    "length": float(length),
                    "translation": float(np.linalg.norm(error[:3, 3])) / length,
                    "rotation": _angle(error) / length,
                    "frames": last - first,
                }
            )
    return out


def kitti_metric(
    truth: np.ndarray, estimate: np.ndarray, lengths: Sequence[float] = KITTI_LENGTHS, step: int = KITTI_STEP
) -> dict[str, Any]:
    """The mean translation error [%] and rotation error [°/m] over all segments of ``lengths``, and per length.

    Returns
    -------
    dict
        ``lengths_m``, ``segments``, ``translation_percent``, ``rotation_deg_per_m`` (NaN without a segment) and
        ``per_length``: ``{length: {segments, translation_percent, rotation_deg_per_m}}``.
    """
    segments = kitti_segment_errors(truth, estimate, lengths, step)

    def mean(rows: list[dict[str, float]]) -> dict[str, Any]:
        if not rows:
            return {"segments": 0, "translation_percent": math.nan, "rotation_deg_per_m": math.nan}
        return {
            "segments": len(rows),
            "translation_percent": 100.0 * float(np.mean([r["translation"] for r in rows])),
            "rotation_deg_per_m": math.degrees(float(np.mean([r["rotation"] for r in rows]))),
        }

    per_length = {f"{length:g}": mean([r for r in segments if r["length"] == length]) for length in lengths}
    return {"lengths_m": [float(v) for v in lengths], **mean(segments), "per_length": per_length}
