"""Slip-compensated feed-forward: the steered axles' slip that carries the trailer's lateral force in a turn.

The chord law (:mod:`controller.preview`, :mod:`controller.path_following`) is kinematic: it asks for the
virtual axle's zero-slip steer. In a turn the trailer's axle group must carry the lateral force of the trailer's
centripetal acceleration, and a tyre carries a lateral force only at a slip angle; without it the trailer swings
out until its axles slip enough, and the feedback has to find that steer from the error. The steady-state
balance gives it directly.

With the trailer's motion held on the chord law's (its yaw rate and kingpin velocity, so each axle's velocity
direction fixed), the yaw moment about the kingpin in a steady turn (no yaw acceleration) is::

    Σ_j F_j·L_j = m·L_cg·a_y,        a_y = v²·κ

(``L`` behind the kingpin, ``m``, ``L_cg`` the unit's mass and centre of gravity, ``F_j`` the axles' lateral forces
to the left); the hitch takes the rest of the lateral force. An unsteered axle's slip is fixed by the motion, so
the moment ``m·L_cg·a_y`` falls on the steered axles, each at the extra slip its extra steer gives it,
``F_s = C_s·Δδ_s`` (linear tyres, ``C_s`` the axle's static cornering stiffness,
:meth:`vehicle_model.parameters.VehicleParams.axle_cornering_stiffness`, independent of the friction in the
tyre model). The steer reaches the axles through the controller's own distribution, ``Δδ_s = (∂δ_s/∂tan δ_v)·Δt``
for a change ``Δt`` of the virtual axle's tangent, so::

    Δt = m·L_cg·v²·κ / Σ_s C_s·L_s·(∂δ_s/∂tan δ_v)

the derivative taken by central differences of :class:`~controller.axle_steer_distribution.AxleSteerDistribution`
at the command's operating point (with the fixed-axle compensation the sum is ``Σ_all C_j L_j²/L_v``). It is the
trailer's counterpart of the tractor's zero-slip point moving with speed
(:attr:`vehicle_model.parameters.VehicleParams.tractor_rear_point_gradient`).

Outside a steady turn each part of the trailer accelerates on the curvature of the path under it. With the mass
spread evenly over a length ``ℓ = 2·L_cg`` behind the kingpin (the same mass and centre of gravity; a laden
semi-trailer's load is spread over its deck) and each point ``x`` behind the kingpin on the curvature of the kingpin
path there, ``κ(s − x)`` (the trailer on the path its kingpin drove), the moment about the kingpin is::

    m·v²·(1/ℓ)·∫₀^ℓ κ(s − x)·x dx  =  m·L_cg·v²·κ_m,    κ_m = (1/ℓ)∫₀^ℓ κ(s − x)·x dx / L_cg

``κ_m`` is the path's curvature weighted by the distance behind the kingpin, equal to ``κ`` in a steady turn; it
also carries the trailer's yaw acceleration as the turn begins or ends (the part of the trailer still in the turn
still needs its force). Signals: the speed ``v`` and the curvature ``κ`` are the kingpin's (the controller's
dead-reckoned kinematics, recorded by distance driven). No trailer state, no friction. The extra steer of each
steered axle is bounded by the slip-angle limit (``max_slip_angle``); the lock is the output stage's.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from vehicle_model.parameters import VehicleParams

from .axle_steer_distribution import AxleSteerDistribution

__all__ = ["SlipFeedforward", "steady_slip_tangent"]

MASS_POINTS = 32
"""Points of the trailer's length at which the path's curvature is taken (midpoint rule of the moment's integral)."""

LIMIT_ITERATIONS = 8
"""Rescalings of the extra tangent to the slip-angle limit: the distribution's curvature shrinks each excess by
orders of magnitude, so a few leave it at the limit to far below a microradian."""

TANGENT_STEP = 1e-4
"""Step of the central difference of the distribution in ``tan δ_v``."""


def steady_slip_tangent(moment_per_acceleration: float, speed: float, curvature: float, gain: float) -> float:
    """``Δt = m·L_cg·v²·κ / G`` (module docstring): the virtual axle's extra tangent whose steer carries the yaw
    moment of a steady turn.

    Parameters
    ----------
    moment_per_acceleration
        ``m·L_cg`` [kg·m] of the steered unit.
    speed
        ``v`` [m/s].
    curvature
        ``κ`` [1/m], positive to the left.
    gain
        ``G = Σ_s C_s·L_s·∂δ_s/∂tan δ_v`` [N·m] > 0: the steered axles' yaw moment per unit tangent.
    """
    return moment_per_acceleration * speed * speed * curvature / gain


class SlipFeedforward:
    """The slip-compensated term of one steered unit's feed-forward (module docstring).

    Parameters
    ----------
    params
        The combination.
    unit
        The steered towed unit (1 the first).
    distribution
        The controller's distribution of that unit.
    max_slip_angle
        Largest extra steer [rad] of any steered axle (``None``: unbounded).
    """

    def __init__(
        self,
        params: VehicleParams,
        unit: int,
        distribution: AxleSteerDistribution,
        max_slip_angle: float | None,
    ) -> None:
        towed = params.trailers[unit - 1]
        self.centre_distance = -float(towed.cg_x)
        self.moment_per_acceleration = float(towed.mass) * self.centre_distance
        self.length = 2.0 * self.centre_distance
        self._stations = self.length * (np.arange(MASS_POINTS) + 0.5) / MASS_POINTS  # behind the kingpin [m]
        self.distribution = distribution
        stiffness = np.asarray(distribution.stiffness, dtype=float)
        distances = np.asarray(distribution.distances, dtype=float)
        self._moment_arms = (stiffness * distances)[distribution.steerable]
        self.max_slip_angle = max_slip_angle
        self.reset()

    def reset(self) -> None:
        """Forget the recorded curvature."""
        self._history: deque[tuple[float, float]] = deque()  # (distance driven [m], κ [1/m]), oldest first
        self.curvature = 0.0
        self.tangent = 0.0

    def record(self, distance: float, curvature: float) -> None:
        """Record the kingpin's curvature ``κ`` [1/m] at ``distance`` [m] driven; keep the trailer's length ``2·L_cg``
        of path (and one point before it)."""
        if not self._history or distance > self._history[-1][0]:
            self._history.append((distance, curvature))
        while len(self._history) > 2 and self._history[1][0] <= distance - self.length:
            self._history.popleft()

    def moment_curvature(self, distance: float) -> float:
        """The trailer's curvature ``κ_m`` [1/m]: the kingpin path's curvature under the trailer, weighted by each
        point's distance behind the kingpin (module docstring); the oldest recorded before the path began."""
        if not self._history:
            return 0.0
        stations = [s for s, _ in self._history]
        curvatures = [k for _, k in self._history]
        under = np.interp(distance - self._stations, stations, curvatures)  # held at the ends
        return float(np.mean(under * self._stations)) / self.centre_distance

    def gain(self, tan_virtual: float, tan_kingpin: float) -> float:
        """``G = Σ_s C_s·L_s·∂δ_s/∂tan δ_v`` [N·m] at the operating point, by central differences."""
        up = self.distribution(tan_virtual + TANGENT_STEP, tan_kingpin)
        down = self.distribution(tan_virtual - TANGENT_STEP, tan_kingpin)
        return float(np.sum(self._moment_arms * (up - down))) / (2.0 * TANGENT_STEP)

    def __call__(self, distance: float, speed: float, tan_virtual: float, tan_kingpin: float) -> float:
        """The extra tangent ``Δt`` of the virtual axle, bounded so that no steered axle gets more than the slip-angle
        limit of extra steer.

        Parameters
        ----------
        distance
            Distance the kingpin has driven [m] (where its curvature was last recorded).
        speed
            Kingpin speed [m/s].
        tan_virtual
            The kinematic feed-forward's ``tan δ_v`` (the operating point).
        tan_kingpin
            ``tan β_k``, the kingpin's direction in the trailer frame.
        """
        self.curvature = self.moment_curvature(distance)
        gain = self.gain(tan_virtual, tan_kingpin)
        if gain <= 0.0 or self.curvature == 0.0:
            self.tangent = 0.0
            return 0.0
        tangent = steady_slip_tangent(self.moment_per_acceleration, speed, self.curvature, gain)
        if self.max_slip_angle is not None:  # scaled until the largest extra steer is at the limit (monotone law)
            base = self.distribution(tan_virtual, tan_kingpin)
            for _ in range(LIMIT_ITERATIONS):
                extra = float(np.max(np.abs(self.distribution(tan_virtual + tangent, tan_kingpin) - base)))
                if extra <= self.max_slip_angle:
                    break
                tangent *= self.max_slip_angle / extra
        self.tangent = tangent if math.isfinite(tangent) else 0.0
        return self.tangent
