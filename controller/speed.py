"""Longitudinal speed controller producing the combination's force demand: drive when positive, service brake when
negative."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field


@dataclass
class SpeedController:
    """PI speed controller with a force limit and conditional-integration anti-windup.

    ``F = m·(k_p·e + k_i·∫e dt)``, ``e = u_ref − u``, clipped to ``±max_force``; the integral is
    frozen while the output saturates in the direction of the error. A positive ``F`` is the driven axles' drive
    force, a negative one the service brake of every axle (the vehicle model shares each over its axles).

    Parameters
    ----------
    mass
        Mass the gains are scaled by [kg] (the combination's total mass).
    kp
        Proportional gain [1/s] (acceleration per speed error).
    ki
        Integral gain [1/s²].
    max_force
        Force limit [N] (positive); the vehicle model also caps each axle's drive and brake force at its
        friction.
    """

    mass: float
    kp: float = 1.0
    ki: float = 0.3
    max_force: float = 60_000.0
    integral: float = field(default=0.0, init=False)

    def __post_init__(self) -> None:
        if self.mass <= 0 or self.kp < 0 or self.ki < 0 or self.max_force <= 0:
            raise ValueError("SpeedController needs mass > 0, kp ≥ 0, ki ≥ 0 and max_force > 0")

    def reset(self) -> None:
        """Clear the integral."""
        self.integral = 0.0

    def __call__(
        self,
        speed_ref: float,
        speed: float,
        dt: float,
        force_limit: float | None = None,
        feedforward: float = 0.0,
        brake_limit: float | None = None,
    ) -> float:
        """Force demand [N] for the next control period of length ``dt``: drive when positive, brake when negative.

        ``force_limit`` lowers the limit for this period (traction control: see :func:`traction_limit`);
        ``brake_limit`` lowers the limit on braking (:func:`service_brake_limit`; ``force_limit`` when omitted);
        ``feedforward`` [N] is added before the limit (a grade's load, :func:`grade_feedforward`), so the integral
        only takes up what it does not foresee.
        """
        # Called every control tick: the comparisons below are min/max (same operands, same order,
        # NaN included) without the builtins' call overhead.
        error = speed_ref - speed
        limit = self.max_force
        if force_limit is not None and force_limit < limit:
            limit = force_limit
        lower = limit
        if brake_limit is not None:
            lower = self.max_force if brake_limit > self.max_force else brake_limit  # min(brake_limit, max_force)
        integral = self.integral
        unsat = self.mass * (self.kp * error + self.ki * (integral + error * dt))
        if feedforward:
            unsat += feedforward
        force = -lower if -lower > unsat else unsat  # max(unsat, -lower)
        if limit < force:  # min(force, limit)
            force = limit
        if force == unsat or (force > 0) != (error > 0):
            self.integral = integral + error * dt
        return force


def traction_limit(mu: float, drive_axle_load: float, fraction: float = 0.6) -> float:
    """Drive force allowed by traction control [N]: ``fraction·μ·F_z`` of the driven axles.

    A traction-control system keeps the drive wheels' longitudinal slip small, which by the
    friction ellipse leaves them ``sqrt(1 − fraction²)`` of their lateral grip (80 % at 0.6).
    """
    return fraction * mu * drive_axle_load


def service_brake_limit(mu: float, total_axle_load: float, fraction: float = 0.6) -> float:
    """Brake force allowed by the anti-lock brakes [N]: ``fraction·μ·F_z`` of every axle together.

    The service brake acts on every axle in proportion to its static load (:mod:`vehicle_model.dynamics`), so at
    ``fraction`` of the combination's friction each axle is at the same ``fraction`` of its own: the anti-lock
    system keeps the wheels' slip as small as traction control does (:func:`traction_limit`), with the same lateral
    grip left.
    """
    return fraction * mu * total_axle_load


def grade_feedforward(mass: float, gravity_along: float) -> float:
    """Drive force [N] that holds ``mass`` [kg] against gravity's part along the direction of travel.

    ``gravity_along`` [m/s²] is that part per unit mass (negative uphill: it pulls the vehicle back; the simulator's
    ``tractor_gravity()[0]``), so the force is ``−m·g_x``: ``m·g·sin θ`` up a grade θ, a braking force down one.
    """
    return -mass * gravity_along


def combination_grade_feedforward(
    masses: Sequence[float], gravity_along: Sequence[float], articulations: Sequence[float]
) -> float:
    """Drive force [N] that holds a combination against gravity where its units stand on different slopes.

    ``F = −Σ_k m_k·g_x,k·cos(Σ_{i<k} Γ_i)``: unit ``k`` (0 the tractor) of mass ``m_k`` [kg] is pulled along its own
    heading by gravity's in-plane part ``g_x,k`` [m/s²] (in-plane gravity per body, docs/vehicle_dynamics.md §1.3;
    the simulator's ``unit_gravity(k, ψ_k)[0]``), and a towed unit's pull reaches the tractor through the couplings
    along the tractor's axis by the cosine of its heading against the tractor's, the sum of the articulation angles
    ``Γ_i`` [rad] ahead of it (its lateral part is the tyres'). With every unit on one slope and in line it is
    :func:`grade_feedforward` of the combination's mass; where the units stand on different slopes (undulations
    shorter than the combination) it is the load the grade puts on the combination, which the tractor's slope alone
    is not.

    Parameters
    ----------
    masses
        Each unit's mass [kg], the tractor first.
    gravity_along
        Gravity's in-plane part along each unit's own heading [m/s²] (negative uphill).
    articulations
        Each coupling's articulation angle, front to rear [rad] (one fewer than the units).

    Returns
    -------
    float
        The drive force [N]: positive uphill, a braking force downhill.

    Raises
    ------
    ValueError
        ``gravity_along`` not one value per mass, or ``articulations`` not one fewer.
    """
    if len(gravity_along) != len(masses) or len(articulations) != len(masses) - 1:
        raise ValueError(
            f"gravity_along ({len(gravity_along)}) must give one value per unit ({len(masses)}) and articulations "
            f"({len(articulations)}) one per coupling ({len(masses) - 1})"
        )
    force = -masses[0] * gravity_along[0]
    relative = 0.0
    for mass, along, angle in zip(masses[1:], gravity_along[1:], articulations, strict=True):
        relative += angle
        force -= mass * along * math.cos(relative)
    return force
