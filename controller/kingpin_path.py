"""The kingpin's path over the last trailer length, dead-reckoned from the towing unit's signals.

The chord feed-forward (:mod:`controller.path_following`, *Feed-forward*) and its preview form
(:mod:`controller.preview`) place the trailer on the kingpin's own recent path. The controller cannot see that path:
it integrates it from the towing unit's yaw rate and the kingpin's velocity in the towing unit's axes (zero-slip
kinematics of the tractor's signals, or the truth), in a frame of its own that starts at the first tick::

    ψ̂ ← ψ̂ + ½(r_prev + r)·Δt                       (trapezoidal heading)
    p̂ ← p̂ + Δt·R(ψ̂_mid)·½(v_prev + v),   ψ̂_mid = ψ̂_prev + ¼(r_prev + r)·Δt
    θ_k = ψ̂ + atan2(v_y, v_x)                        (the path's direction at the kingpin)

A point ``(x, y, θ)`` is stored every :data:`PATH_SPACING` metres; points more than one trailer length (``L_fp``,
straight-line) behind the kingpin are dropped but one, so the chord's far end can be interpolated. Reversing clears
the path (the law is for forward travel).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from .preview import chord_law, interpolated_chord_end, straight_chord_end

__all__ = ["PATH_SPACING", "DeadReckonedKingpinPath"]

PATH_SPACING = 0.05
"""Spacing [m] of the stored points of the dead-reckoned kingpin path (chord feed-forward)."""


class DeadReckonedKingpinPath:
    """The kingpin's path over the last trailer length, integrated tick by tick.

    Parameters
    ----------
    follow_point_offset : float
        ``L_fp`` [m]: how far back (straight-line) the path is kept.

    Attributes
    ----------
    points : collections.deque of (float, float, float)
        ``(x, y, θ)`` of the path, oldest first [m, m, rad].
    direction : float
        ``θ_k``, the path's direction at the kingpin on the last tick [rad].
    """

    def __init__(self, follow_point_offset: float) -> None:
        self.follow_point_offset = follow_point_offset
        self.reset()

    def reset(self) -> None:
        """No path, heading zero, kingpin at the origin."""
        self._heading = 0.0  # dead-reckoned towing-unit heading ψ̂ [rad]
        self._position = np.zeros(2)  # dead-reckoned kingpin position [m]
        self.points: deque[tuple[float, float, float]] = deque()
        self.direction = 0.0
        self._last_motion: tuple[float, float, float] | None = None  # (r, v_kx, v_ky) of the previous tick

    def __bool__(self) -> bool:
        return bool(self.points)

    @property
    def kingpin(self) -> tuple[float, float, float]:
        """``(x, y, θ_k)`` of the kingpin on the last tick."""
        return float(self._position[0]), float(self._position[1]), self.direction

    def record(self, tow_yaw_rate: float, vx: float, vy: float, dt: float, forward: bool) -> None:
        """Advance the path by one tick (module docstring); clear it when not driving forward.

        Parameters
        ----------
        tow_yaw_rate : float
            The towing unit's yaw rate [rad/s].
        vx, vy : float
            The kingpin's velocity in the towing unit's axes [m/s].
        dt : float
            The tick [s].
        forward : bool
            Whether the combination drives forward.
        """
        if not forward:
            self.points.clear()
            self._last_motion = None
            return
        if self._last_motion is not None:
            r_prev, vx_prev, vy_prev = self._last_motion
            mid = self._heading + 0.25 * (r_prev + tow_yaw_rate) * dt
            self._heading += 0.5 * (r_prev + tow_yaw_rate) * dt
            c, s = math.cos(mid), math.sin(mid)
            mx, my = 0.5 * (vx + vx_prev), 0.5 * (vy + vy_prev)
            self._position += dt * np.array([c * mx - s * my, s * mx + c * my])
        self._last_motion = (tow_yaw_rate, vx, vy)
        self.direction = self._heading + math.atan2(vy, vx)
        px, py = float(self._position[0]), float(self._position[1])
        if not self.points or math.hypot(px - self.points[-1][0], py - self.points[-1][1]) >= PATH_SPACING:
            self.points.append((px, py, self.direction))
        while len(self.points) > 2 and math.hypot(self.points[1][0] - px, self.points[1][1] - py) >= (
            self.follow_point_offset
        ):
            self.points.popleft()

    def chord_tangent(self, virtual_axle_distance: float) -> float:
        """``tan δ_ff`` of the chord law on the recorded path (:mod:`controller.path_following`, *Feed-forward*).

        The trailer is placed on the chord from the path point ``L_fp`` behind the kingpin (in straight-line
        distance) to the kingpin; the kingpin moves along the path direction ``θ_k`` and the follow point along
        the path direction ``θ_f`` at the chord point, so in the chord's frame ``tan δ_ff = tan β_k* −
        (L_v/L_fp)(tan β_k* − tan φ_f*)`` with ``β_k* = θ_k − ψ2*``, ``φ_f* = θ_f − ψ2*``. Needs one recorded point.
        """
        lfp = self.follow_point_offset
        kingpin = self.kingpin
        oldest = self.points[0]
        d0 = math.hypot(oldest[0] - kingpin[0], oldest[1] - kingpin[1])
        if len(self.points) >= 2 and d0 >= lfp:
            # The oldest point is the last one at least L_fp away (pruning keeps one): interpolate to L_fp.
            near = self.points[1]
            d1 = math.hypot(near[0] - kingpin[0], near[1] - kingpin[1])
            end = interpolated_chord_end(oldest, d0, near, d1, lfp)
        else:
            end = straight_chord_end(oldest, kingpin, lfp)  # less than one trailer length recorded
        return chord_law(kingpin, end, lfp, virtual_axle_distance)
