"""The truth of a recorded run from its reference: camera poses turned into the trailer's path, or a given series.

Camera poses ``T_ref←camera`` (sampled at the run's rows, :func:`sensor.recordings.poses.interpolate_poses`) give
the trailer's poses through the camera's mounting ``X = T_trailer←camera``: relative to the first row,
``T_trailer0←trailer_k = X·inv(T_ref←cam_0)·T_ref←cam_k·inv(X)``. Its origin is the kingpin (the trailer frame's
origin, docs/design.md §5), its yaw the trailer's heading. The truth is then computed as a simulated run's
(:class:`scenarios.loop.estimators.GroundTruth`): the path buffer fed with the exact increments between rows
(de Saxe & Cebon 2018, eqs 3–7; :func:`vehicle_model.offtracking.increments_from_poses`), and the geometric
intersection of the kingpin's path with the trailer's lateral line at the follow point
(:func:`vehicle_model.offtracking.offtracking_series`). A reference off-tracking series is interpolated at the rows
(no geometric truth then).
"""

from __future__ import annotations

import math

import numpy as np

from sensor.recordings.poses import interpolate_poses
from vehicle_model.offtracking import OfftrackingBuffer, increments_from_poses, offtracking_series

__all__ = ["reference_columns", "trailer_path"]


def trailer_path(camera_poses: np.ndarray, camera_in_trailer: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kingpin positions ``(n, 2)`` [m] and trailer headings ``(n,)`` [rad] in the first pose's trailer frame, from
    camera poses ``T_ref←camera`` ``(n, 4, 4)`` (module notes); NaN rows stay NaN."""
    poses = np.asarray(camera_poses, dtype=float)
    x = np.asarray(camera_in_trailer, dtype=float)
    ok = np.all(np.isfinite(poses.reshape(len(poses), -1)), axis=1)
    kingpin = np.full((len(poses), 2), np.nan)
    heading = np.full(len(poses), np.nan)
    if not ok.any():
        return kingpin, heading
    first = poses[np.flatnonzero(ok)[0]]
    relative = np.linalg.solve(first, poses[ok])  # inv(T_0)·T_k
    trailer = x @ relative @ np.linalg.inv(x)
    kingpin[ok] = trailer[:, :2, 3]
    heading[ok] = np.unwrap(np.arctan2(trailer[:, 1, 0], trailer[:, 0, 0]))
    return kingpin, heading


def reference_columns(
    row_times: np.ndarray,
    follow_point_offset: float,
    camera_in_trailer: np.ndarray,
    poses: tuple[np.ndarray, np.ndarray] | None,
    offtracking: tuple[np.ndarray, np.ndarray] | None,
) -> dict[str, np.ndarray]:
    """The truth's columns at the rows: ``offtracking_truth``, ``offtracking_truth_geometric`` and, from poses,
    ``kingpin_x``, ``kingpin_y``, ``trailer_heading`` of the reference and ``camera_pose`` ``(n, 4, 4)`` (NaN where
    the reference does not reach)."""
    n = len(row_times)
    out = {name: np.full(n, np.nan) for name in ("offtracking_truth", "offtracking_truth_geometric")}
    if offtracking is not None:
        t, values = offtracking
        inside = (row_times >= t[0]) & (row_times <= t[-1])
        out["offtracking_truth"] = np.where(inside, np.interp(row_times, t, values), np.nan)
        return out
    if poses is None:
        return out
    camera_pose = interpolate_poses(poses[0], poses[1], row_times)
    kingpin, heading = trailer_path(camera_pose, camera_in_trailer)
    out.update(kingpin_x=kingpin[:, 0], kingpin_y=kingpin[:, 1], trailer_heading=heading)
    out["camera_pose"] = camera_pose
    ok = np.flatnonzero(np.isfinite(heading))
    if ok.size < 2:
        return out
    span = slice(int(ok[0]), int(ok[-1]) + 1)  # the reference's span of rows (interpolation leaves no hole inside)
    buffer = OfftrackingBuffer(follow_point_offset)
    truth = np.full(n, np.nan)
    increments = increments_from_poses(kingpin[span], heading[span])
    for k, increment in zip(range(span.start + 1, span.stop), increments, strict=True):
        buffer.push(*increment)
        value = buffer.offtracking()
        truth[k] = math.nan if value is None else value
    out["offtracking_truth"] = truth
    geometric = np.full(n, np.nan)
    geometric[span] = offtracking_series(kingpin[span], heading[span], follow_point_offset)
    out["offtracking_truth_geometric"] = geometric
    return out
