"""Reference trajectories and off-tracking series given with a recording: KITTI and TUM poses, an off-tracking CSV.

* KITTI (``poses.txt``, Geiger, Lenz & Urtasun 2012): one line per frame, the 3×4 pose ``T_ref←camera`` row-major.
* TUM (Sturm et al. 2012, "A benchmark for the evaluation of RGB-D SLAM systems"): ``time tx ty tz qx qy qz qw`` per
  line, ``#`` comments; the times on the recording's clock.
* An off-tracking series: a CSV with the columns ``time_s`` and ``offtracking_m`` (ISO sign: positive when the follow
  point is right of the kingpin's path; docs/design.md §6).

The poses are those of the camera whose motion the odometry reports (the rectified left camera, as KITTI's); only
their motion relative to the first is used (:func:`relative_poses`), so the reference frame may be any.
:func:`interpolate_poses` samples a trajectory at other times (linear translation, spherical rotation).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from vehicle_model.errors import InputError

__all__ = ["interpolate_poses", "read_kitti_poses", "read_offtracking_series", "read_tum_poses", "relative_poses"]


def _rows(path: Path, what: str) -> list[list[float]]:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: not found; allowed: {what}")
    rows = []
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot be read ({exc})") from None
    for number, line in enumerate(lines, 1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        try:
            rows.append([float(v) for v in text.replace(",", " ").split()])
        except ValueError:
            raise InputError(f"{path}: line {number} holds something other than numbers; allowed: {what}") from None
    return rows


def _checked(path: Path, rows: list[list[float]], width: int, what: str) -> np.ndarray:
    for number, row in enumerate(rows, 1):
        if len(row) != width:
            raise InputError(f"{path}: pose {number} has {len(row)} numbers; allowed: {what}")
    data = np.array(rows, dtype=float).reshape(-1, width)
    if data.size == 0:
        raise InputError(f"{path}: no pose; allowed: {what}")
    if not np.all(np.isfinite(data)):
        raise InputError(f"{path}: holds a number that is not finite")
    return data


def read_kitti_poses(path: Path, frames: int | None = None) -> np.ndarray:
    """``(n, 4, 4)`` poses of a KITTI ``poses.txt`` (``frames``: the count it must have, one per frame)."""
    what = "KITTI poses, 12 numbers per line (3×4 row-major), one line per frame"
    data = _checked(Path(path), _rows(Path(path), what), 12, what)
    if frames is not None and len(data) != frames:
        raise InputError(f"{path}: {len(data)} poses for {frames} frames; allowed: {what}")
    poses = np.tile(np.eye(4), (len(data), 1, 1))
    poses[:, :3, :] = data.reshape(-1, 3, 4)
    return poses


def read_tum_poses(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times [s] and ``(n, 4, 4)`` poses of a TUM trajectory, sorted by time (times must be distinct)."""
    from scipy.spatial.transform import Rotation

    what = "TUM poses, 'time tx ty tz qx qy qz qw' per line"
    data = _checked(Path(path), _rows(Path(path), what), 8, what)
    order = np.argsort(data[:, 0], kind="stable")
    data = data[order]
    if np.any(np.diff(data[:, 0]) <= 0.0):
        raise InputError(f"{path}: two poses with one time; allowed: {what}, distinct times")
    norms = np.linalg.norm(data[:, 4:8], axis=1)
    if np.any(np.abs(norms - 1.0) > 1e-3):
        raise InputError(
            f"{path}: a quaternion is not of unit length (|q| = {norms[np.argmax(np.abs(norms - 1))]:.4g})"
        )
    poses = np.tile(np.eye(4), (len(data), 1, 1))
    poses[:, :3, :3] = Rotation.from_quat(data[:, 4:8]).as_matrix()  # scipy's (x, y, z, w) order, as TUM's
    poses[:, :3, 3] = data[:, 1:4]
    return data[:, 0], poses


def relative_poses(poses: np.ndarray) -> np.ndarray:
    """Each pose in the first one's frame: ``inv(T_0)·T_k``."""
    poses = np.asarray(poses, dtype=float)
    return np.linalg.solve(poses[0], poses)


def interpolate_poses(times: np.ndarray, poses: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Poses at the times ``at``: translation linear, rotation spherical (scipy ``Slerp``) between the neighbours;
    NaN outside the trajectory's time span."""
    from scipy.spatial.transform import Rotation, Slerp

    times = np.asarray(times, dtype=float)
    at = np.asarray(at, dtype=float)
    out = np.full((at.size, 4, 4), np.nan)
    inside = (at >= times[0]) & (at <= times[-1])
    if not inside.any():
        return out
    if times.size == 1:
        out[inside] = poses[0]
        return out
    rotations = Slerp(times, Rotation.from_matrix(poses[:, :3, :3]))(at[inside]).as_matrix()
    out[inside, :3, :3] = rotations
    for axis in range(3):
        out[inside, axis, 3] = np.interp(at[inside], times, poses[:, axis, 3])
    out[inside, 3, :] = [0.0, 0.0, 0.0, 1.0]
    return out


def read_offtracking_series(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times [s] and off-tracking [m] of a reference CSV with the columns ``time_s`` and ``offtracking_m``."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: not found; allowed: a CSV with the columns time_s and offtracking_m")
    try:
        with path.open(newline="") as fh:
            reader = csv.DictReader(fh)
            fields = reader.fieldnames or []
            if "time_s" not in fields or "offtracking_m" not in fields:
                raise InputError(
                    f"{path}: columns {', '.join(fields) or 'none'}; allowed: a CSV with time_s and offtracking_m"
                )
            rows = [(float(r["time_s"]), float(r["offtracking_m"] or "nan")) for r in reader]
    except (OSError, UnicodeDecodeError, ValueError, TypeError) as exc:
        raise InputError(f"{path}: cannot be read as a CSV of numbers ({exc})") from None
    data = np.array(rows, dtype=float).reshape(-1, 2)
    if data.size == 0 or not np.all(np.isfinite(data[:, 0])) or np.any(np.diff(data[:, 0]) <= 0):
        raise InputError(f"{path}: time_s must hold finite, strictly increasing times")
    return data[:, 0], data[:, 1]
