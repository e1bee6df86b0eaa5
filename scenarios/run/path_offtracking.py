"""The combination's off-tracking: its last unit's rear against the path of the steer axle.

De Saxe & Cebon's off-tracking ``e_tr`` (eqs (3)–(7), the run's ``offtracking_truth`` and each further unit's
``offtracking_truth<k>``) is a trailer's follow point against the path of its *own* coupling: what each trailer's
steering can correct. The road sees the whole combination: how far the last unit's rear runs from where the
tractor's steer axle went. That is measured here, from the recorded poses, for any combination (the first towed
unit's rear for a tractor and one semi-trailer):

* the reference is the path of the centre of the tractor's (or rigid truck's) steer axle, station 0 of the first
  unit (``vehicle_model.geometry.tractor_points``), as the run traced it;
* the point is the last unit's follow point (``follow_x``/``follow_y``, or ``follow<k>_x``/``follow<k>_y``: on its
  centre line at its follow-point offset behind its coupling, the point the paper's definition places at the rear);
* the value at each tick is the signed distance from the point to the part of the steer axle's path traced *before*
  that tick, measured to the nearest point of that polyline (:func:`offsets_from_path`), with the sign of ``e_tr``
  (docs/usage.md, "Off-tracking and the estimators"; ISO 8855 axes): positive when the point is to the right of the
  path, so that an unsteered combination's rear cutting in on a left turn is negative. It is NaN until the point has
  come level with the start of the traced path.

On a steady turn about a fixed centre the value is the difference of the two radii, ``R_rear − R_steer`` for a left
turn (``−(R_rear − R_steer)`` for a right one); for the kinematic chain that gives those radii see docs/vehicles.md.
"""

from __future__ import annotations

import numpy as np

from vehicle_model.geometry import tractor_points
from vehicle_model.parameters import VehicleParams

__all__ = ["combination_offtracking", "offsets_from_path", "rear_point", "rear_point_columns"]


def rear_point_columns(params: VehicleParams) -> tuple[str, str]:
    """The recorded columns of the last unit's follow point (``follow_x``, ``follow_y`` for two units)."""
    suffix = "" if params.n_units == 2 else str(params.n_units)
    return f"follow{suffix}_x", f"follow{suffix}_y"


def rear_point(params: VehicleParams, columns: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The last unit's follow point over the run, global X and Y [m] (the first towed unit's for two units)."""
    x, y = rear_point_columns(params)
    return np.asarray(columns[x], dtype=float), np.asarray(columns[y], dtype=float)


def offsets_from_path(path: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Signed distance of each point to the path traced before it (module docstring for the sign).

    Parameters
    ----------
    path
        ``(n, 2)``: the reference point's positions, one per tick [m].
    points
        ``(n, 2)``: the followed point's positions on the same ticks [m].

    Returns
    -------
    numpy.ndarray
        ``(n,)`` [m]: for tick ``i``, the distance from ``points[i]`` to the polyline ``path[:i + 1]`` at its
        nearest segment, positive to the right of the path's direction there; NaN while the point's nearest place
        is behind the start of the path (it has not reached the path yet), and where a position is not finite.

    Notes
    -----
    The nearest segment is followed forward from tick to tick (a point that trails the reference moves along its
    path monotonically), so a path that crosses itself, as a figure of eight does, is measured against the part of
    it that the point is following, not against another part that happens to lie closer.
    """
    path = np.asarray(path, dtype=float)
    points = np.asarray(points, dtype=float)
    if path.shape != points.shape or path.ndim != 2 or path.shape[1] != 2:
        raise ValueError(f"path {path.shape} and points {points.shape} must both be (n, 2)")
    n = len(path)
    out = np.full(n, np.nan)
    keep = np.all(np.isfinite(path), axis=1)
    track, ticks = path[keep], np.flatnonzero(keep)
    if len(track) < 2:
        return out
    start = track[:-1]
    step = track[1:] - start
    length2 = np.einsum("ij,ij->i", step, step)
    moving = length2 > 1e-18
    j = 0  # nearest segment so far
    for i in range(n):
        p = points[i]
        last = int(np.searchsorted(ticks, i, side="right")) - 1  # the path traced by tick i ends at track[last]
        if last < 1 or not np.all(np.isfinite(p)):
            continue
        j = min(j, last - 1)

        def gap(k: int, p: np.ndarray = p) -> tuple[float, float]:
            t = float(np.dot(p - start[k], step[k]) / length2[k]) if moving[k] else 0.0
            clipped = min(max(t, 0.0), 1.0)
            d = p - (start[k] + clipped * step[k])
            return float(np.dot(d, d)), t

        best, t = gap(j)
        while j + 1 <= last - 1:
            ahead, t_ahead = gap(j + 1)
            if ahead > best:
                break
            j, best, t = j + 1, ahead, t_ahead
        if j == 0 and t < 0.0:
            continue  # still behind the start of the path
        k = j
        while not moving[k] and k > 0:
            k -= 1
        if not moving[k]:
            continue
        direction = step[k] / np.sqrt(length2[k])
        d = p - start[j]
        out[i] = -(direction[0] * d[1] - direction[1] * d[0])  # right of the path: positive
    return out


def combination_offtracking(params: VehicleParams, columns: dict[str, np.ndarray]) -> np.ndarray:
    """The last unit's rear against the steer axle's path at every tick [m] (module docstring)."""
    steer = tractor_points(
        params,
        np.asarray(columns["X"], dtype=float),
        np.asarray(columns["Y"], dtype=float),
        np.asarray(columns["psi1"], dtype=float),
        np.zeros((1, 2)),
    )[:, 0, :]
    return offsets_from_path(steer, np.column_stack(rear_point(params, columns)))
