"""Preview feed-forward: the chord law of the trailer a preview distance ahead on the kingpin's path.

The chord law (:mod:`controller.path_following`, *Feed-forward*) gives the virtual axle's zero-slip steer that
keeps the follow point on the kingpin's path *now*: the trailer on the chord from the path point ``L_fp`` behind the
kingpin (straight-line distance) to the kingpin. The steer reaches the trailer late: the axles are rate limited, the
tyres build their force over a relaxation length and the trailer's yaw has inertia, and where the law asks for more
than the lock the trailer is not where the next stretch needs it. The preview law asks instead for the chord law's
steer of the configuration the trailer will have ``d`` metres further on::

    kingpin:        driven d further on its current curvature κ5 (a circular arc; straight for κ5 = 0)
    follow point:   the path point L_fp (straight-line) behind that kingpin: on the recorded kingpin path for
                    d < L_fp, the stretch already driven between the follow point and the kingpin
    tan δ_ff = tan β_k* − (L_v/L_fp)·(tan β_k* − tan φ_f*)     (the chord law on that chord)

The follow point's end of the chord, the part the steer depends on most (the trailer's rear), comes from the
kingpin's recorded path and is known causally; only the kingpin's own ``d`` metres are extrapolated, on the
curvature it is driving. The law is the preview (look-ahead) form of a feed-forward on a known reference path
(Sharp, Casanova & Symonds 2000, Vehicle System Dynamics 33(5), a driver model steering on the path's preview;
here the preview is of the trailer's own reference, the kingpin's path). In a steady turn the configuration ahead
is the present one turned about the centre, so the law equals the steady law (docs/vehicle_dynamics.md §6.2) for
any ``d``; from a straight into an arc it reaches the steady steer when the follow point is ``d`` short of the arc,
where the chord law reaches it as the follow point enters. ``d = 0`` is the chord law itself.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = [
    "arc_ahead",
    "chord_law",
    "chord_tangent",
    "interpolated_chord_end",
    "preview_tangent",
    "straight_chord_end",
    "wrap_clipped",
]

PathPoint = tuple[float, float, float]
"""A point of the kingpin's path: ``(x, y, θ)``, position [m] and direction of travel [rad]."""


def wrap_clipped(angle: float) -> float:
    """Angle wrapped to (−π, π], then clipped to ±1.4 rad (keeps tangents finite)."""
    wrapped = math.atan2(math.sin(angle), math.cos(angle))
    return min(max(wrapped, -1.4), 1.4)


def arc_ahead(kingpin: PathPoint, curvature: float, distance: float, spacing: float) -> list[PathPoint]:
    """Points of the circular arc of ``curvature`` driven ``distance`` on from ``kingpin``, every ``spacing``.

    Parameters
    ----------
    kingpin
        ``(x, y, θ)`` of the start [m, m, rad].
    curvature
        Signed curvature [1/m], positive to the left; a straight line below 1e-9 /m.
    distance
        Arc length [m] ≥ 0.
    spacing
        Largest arc length between two returned points [m] > 0.

    Returns
    -------
    list of tuple
        The arc's points after the start, the last one ``distance`` along (empty for ``distance = 0``).
    """
    x0, y0, t0 = kingpin
    n = math.ceil(distance / spacing) if distance > 0 else 0
    points = []
    for k in range(1, n + 1):
        s = distance * k / n
        theta = t0 + curvature * s
        if abs(curvature) > 1e-9:
            x = x0 + (math.sin(theta) - math.sin(t0)) / curvature
            y = y0 - (math.cos(theta) - math.cos(t0)) / curvature
        else:
            x, y = x0 + s * math.cos(t0), y0 + s * math.sin(t0)
        points.append((x, y, theta))
    return points


def chord_tangent(path: Sequence[PathPoint], kingpin: PathPoint, follow_point_offset: float, lv: float) -> float:
    """``tan δ_ff`` of the chord law for a kingpin at ``kingpin`` whose path so far is ``path`` (oldest first).

    The chord's far end is the last crossing, searched back from the kingpin, of the circle of radius ``L_fp``
    about it, interpolated between the two path points either side; a path that never reaches ``L_fp`` is taken as
    straight behind its oldest point (the run starts straight).

    Parameters
    ----------
    path
        Kingpin path points ``(x, y, θ)``, oldest first, ending at or near ``kingpin``; not empty.
    kingpin
        ``(x, y, θ_k)`` of the kingpin.
    follow_point_offset
        ``L_fp`` [m] > 0.
    lv
        Virtual-axle distance ``L_v`` [m].

    Returns
    -------
    float
        ``tan β_k* − (L_v/L_fp)(tan β_k* − tan φ_f*)``.
    """
    lfp = follow_point_offset
    px, py, _ = kingpin
    far = None
    newer = None
    for point in reversed(path):
        d = math.hypot(point[0] - px, point[1] - py)
        if d >= lfp:
            far = (point, d)
            break
        newer = (point, d)
    if far is not None and newer is not None:
        end = interpolated_chord_end(far[0], far[1], newer[0], newer[1], lfp)
    elif far is not None:
        end = far[0]
    else:
        end = straight_chord_end(path[0], kingpin, lfp)
    return chord_law(kingpin, end, lfp, lv)


def interpolated_chord_end(
    far: PathPoint, far_distance: float, near: PathPoint, near_distance: float, lfp: float
) -> PathPoint:
    """The chord's far end ``(x, y, θ_f)``: the point at straight-line distance ``lfp`` from the kingpin,
    interpolated between the path points ``far`` (at ``far_distance`` ≥ ``lfp``) and ``near`` (nearer the kingpin)."""
    x0, y0, t0 = far
    x1, y1, t1 = near
    w = (far_distance - lfp) / (far_distance - near_distance) if far_distance > near_distance else 0.0
    return x0 + w * (x1 - x0), y0 + w * (y1 - y0), t0 + w * (t1 - t0)


def straight_chord_end(oldest: PathPoint, kingpin: PathPoint, lfp: float) -> PathPoint:
    """The chord's far end ``(x, y, θ_f)`` on a path recorded for less than ``lfp``: the path taken as straight behind
    its ``oldest`` point (the run starts straight), the point there at straight-line distance ``lfp`` from the
    kingpin."""
    x0, y0, t0 = oldest
    px, py = kingpin[0], kingpin[1]
    dx, dy = math.cos(t0), math.sin(t0)
    wx, wy = x0 - px, y0 - py
    along = wx * dx + wy * dy
    t = along + math.sqrt(max(along * along - (wx * wx + wy * wy) + lfp * lfp, 0.0))
    return x0 - t * dx, y0 - t * dy, t0


def chord_law(kingpin: PathPoint, chord_end: PathPoint, lfp: float, lv: float) -> float:
    """``tan δ_ff = tan β_k* − (L_v/L_fp)(tan β_k* − tan φ_f*)``: the chord law with the trailer on the chord from
    ``chord_end`` ``(x, y, θ_f)`` to the ``kingpin`` ``(x, y, θ_k)``, ``β_k* = θ_k − ψ*``, ``φ_f* = θ_f − ψ*`` in the
    chord's direction ``ψ*`` (:mod:`controller.path_following`, *Feed-forward*)."""
    px, py, theta_k = kingpin
    cx, cy, theta_f = chord_end
    psi_chord = math.atan2(py - cy, px - cx)
    tan_k = math.tan(wrap_clipped(theta_k - psi_chord))
    tan_f = math.tan(wrap_clipped(theta_f - psi_chord))
    return tan_k - (lv / lfp) * (tan_k - tan_f)


def preview_tangent(
    path: Sequence[PathPoint],
    kingpin: PathPoint,
    curvature: float,
    preview_distance: float,
    follow_point_offset: float,
    lv: float,
    spacing: float,
) -> float:
    """``tan δ_ff`` of the preview law (module docstring): the chord law with the kingpin ``preview_distance``
    further on its current ``curvature``, the follow point's end on the recorded ``path``.

    Parameters
    ----------
    path
        Kingpin path points ``(x, y, θ)`` recorded so far, oldest first; not empty.
    kingpin
        ``(x, y, θ_k)`` of the kingpin now.
    curvature
        The kingpin path's curvature now, ``κ5`` [1/m].
    preview_distance
        ``d`` [m] ≥ 0.
    follow_point_offset
        ``L_fp`` [m].
    lv
        Virtual-axle distance ``L_v`` [m].
    spacing
        Spacing of the extrapolated arc's points [m] (the recorded path's).

    Returns
    -------
    float
        ``tan δ_ff`` of the configuration ``preview_distance`` ahead.
    """
    ahead = arc_ahead(kingpin, curvature, preview_distance, spacing)
    if not ahead:
        return chord_tangent(path, kingpin, follow_point_offset, lv)
    return chord_tangent([*path, kingpin, *ahead], ahead[-1], follow_point_offset, lv)
