"""Cheng's zero-slip (model-based) off-tracking estimator.

The estimator assumes that no tyre slips sideways (docs/vehicle_dynamics.md §2.3, §7.2; Cheng 2009):

* the tractor's rear point, ``L1`` behind the steer axle (:data:`RearPoint`: the mean station of the rear axles,
  or their stiffness-weighted equivalent wheelbase ``ΣC_j L_j² / ΣC_j L_j``, the point that has no lateral
  velocity when no force acts at the fifth wheel), has no lateral velocity, so the kingpin, ``e`` behind it
  (negative when ahead), moves at ``(u, −e·r1)`` in tractor axes;
* the tractor yaw rate ``r1`` comes either from the gyro (``yaw_rate`` variant) or from the front
  steer angle, ``r1 = u·tan δ_f / L1`` (``steer_angle`` variant);
* the trailer heading follows from the tractor's and the measured articulation, ``ψ2 = ψ1 − Γ``.

A unit further back (a B-double's rear trailer, an A-double's dolly and second trailer) is estimated the same way
against its own coupling's path: the kingpin's zero-slip velocity is carried down the chain as rigid-body motion
(:func:`~vehicle_model.kinematics.coupling_velocity`), each unit's yaw rate being the tractor's less the rates of
the articulations ahead of it (``ψ_k = ψ1 − Γ − Γ2 − …``, from the sensor at each coupling, the
``rear_articulation`` signal), so the only zero-slip assumption stays the tractor's.

Each control period it turns the kingpin's motion into an increment in the trailer frame and
feeds the same :class:`~vehicle_model.offtracking.OfftrackingBuffer` as the ground truth. It is
blind to slip by construction: tractor crab on a camber, sideslip on ice and the scrub of the tractor's
drive and tag axles under a trailer's hitch force all go unseen (docs/vehicle_dynamics.md §6.4–6.6). That is
the phenomenon the product exists to show. On a terrain (docs/terrain.md, "The zero-slip estimate on terrain") the wheel
speed is measured along the ground and taken as horizontal, which moves a steady turn's estimate inwards by
``L_fp²/(2·R5)·(1/cos θ − 1)``, unless the grade ``θ`` is estimated from the tractor's longitudinal accelerometer
(``grade="accelerometer"``, :class:`~controller.grade_estimate.GradeEstimator`) and the wheel speed taken as
``u·cos θ̂``; a crossfall's crab and a grade's drive or brake force through the hitch are slip it does not see. With the
equivalent wheelbase and a trailer that pushes nothing through the hitch it follows the truth closely at walking pace
(§6.6); the scrub of a fixed tri-axle, or of steered trailer axles at their lock, moves the tractor's true rear point
0.1–0.2 m along its axis, which a follow point 12–14 m behind shows as 0.1–0.2 m of off-tracking error whichever point
the estimator assumes.

Variants: Cheng's estimator used the measured yaw rate of the tractor with the articulation
angle (unverified: the thesis could not be consulted, docs/vehicle_dynamics.md §7.1); here ``yaw_rate`` is the default
because the steer-angle variant is additionally wrong for a 6x2 tractor with a tag axle, whose
scrub makes the tractor turn tighter than ``tan δ/L1`` (docs/vehicle_dynamics.md §2.3 compares the kingpin radii).
"""

from __future__ import annotations

import math
from typing import Literal, get_args

import numpy as np

from vehicle_model.kinematics import RearPoint, coupling_velocity, tractor_kingpin_velocity
from vehicle_model.offtracking import OfftrackingBuffer
from vehicle_model.parameters import VehicleParams

from .grade_estimate import GradeEstimator

ZeroSlipVariant = Literal["yaw_rate", "steer_angle"]
GradeSource = Literal["none", "accelerometer"]
REAR_POINT_NOTES = """Which rear point (:data:`~vehicle_model.kinematics.RearPoint`) the zero-slip estimator is best
with. A trailer in a turn pushes on the fifth wheel and moves the real point ahead of the equivalent wheelbase
(docs/vehicle_dynamics.md §6.6, which gives the figures): at speed on a dry road the zero-slip-fed loop is closer
to the truth with ``axle_mean`` than with ``equivalent``, while at walking pace with the trailer's axles at their
lock (the roundabout test) ``equivalent`` is the closer. ``speed_compensated`` (``L1 − K·u²``) is closer than
either at speed; it does not see a camber's crab or the scrub of a fixed group at walking pace.
``lateral_acceleration`` sees the camber's crab through the tractor's accelerometer (docs/vehicle_dynamics.md
§6.7). ``axle_mean`` is the default, and the rear point of every study of the project (README, "The zero-slip
baseline")."""


class ZeroSlipEstimator:
    """Off-tracking from tractor signals and zero-slip kinematics.

    Parameters
    ----------
    params
        Vehicle parameters (tractor axles, fifth-wheel position, follow point).
    variant
        ``yaw_rate`` (gyro, default) or ``steer_angle``.
    rear_point
        The tractor's point without lateral velocity (:data:`~vehicle_model.kinematics.RearPoint`, and
        :data:`REAR_POINT_NOTES`): ``axle_mean`` (default), ``equivalent``, ``speed_compensated`` or
        ``lateral_acceleration`` (which needs the ``tractor_lateral_acceleration`` signal).
    unit
        The towed unit estimated: 1 the first (default), 2 the one it tows, … (module docstring).
    grade
        ``none`` (default): the wheel speed taken as horizontal; ``accelerometer``: made horizontal, ``u·cos θ̂``,
        with the grade estimated from the ``tractor_longitudinal_acceleration`` signal and the wheel speed
        (:class:`~controller.grade_estimate.GradeEstimator`).
    """

    def __init__(
        self,
        params: VehicleParams,
        variant: ZeroSlipVariant = "yaw_rate",
        rear_point: RearPoint = "axle_mean",
        unit: int = 1,
        grade: GradeSource = "none",
    ) -> None:
        if variant not in ("yaw_rate", "steer_angle"):
            raise ValueError(f"zero-slip variant {variant!r} must be 'yaw_rate' or 'steer_angle'")
        if rear_point not in get_args(RearPoint):
            raise ValueError(f"zero-slip rear point {rear_point!r} must be one of {get_args(RearPoint)}")
        if not 1 <= unit < params.n_units:
            raise ValueError(f"unit {unit} is not a towed unit of {params.name!r} (1..{params.n_units - 1})")
        if grade not in get_args(GradeSource):
            raise ValueError(f"zero-slip grade source {grade!r} must be one of {get_args(GradeSource)}")
        self.grade_estimator = GradeEstimator() if grade == "accelerometer" else None
        self.variant = variant
        self.params = params
        self.unit = unit
        self.rear_point = rear_point
        self.wheelbase = (
            params.tractor_wheelbase() if rear_point == "axle_mean" else params.tractor_equivalent_wheelbase()
        )
        self._cg_ahead = self.wheelbase + params.tractor.cg_x  # the CG ahead of the rear point [m]
        self.buffer = OfftrackingBuffer(params.trailers[unit - 1].follow_point_offset)
        # (u, r1, f_y, articulations) of the previous sample
        self._last: tuple[float, float, float, np.ndarray] | None = None

    def reset(self) -> None:
        """Forget the path."""
        self.buffer.reset()
        self._last = None
        if self.grade_estimator is not None:
            self.grade_estimator.reset()

    def update(self, signals: dict[str, np.ndarray], dt: float) -> float | None:
        """Feed one control period of signals; return the off-tracking estimate [m] or ``None``.

        ``signals`` holds at least ``wheel_speed``, ``front_steer``, ``tractor_yaw_rate`` and
        ``articulation`` (see :mod:`sensor.signals`), ``rear_articulation`` for a unit behind the first and
        ``tractor_longitudinal_acceleration`` with the accelerometer's grade.
        """
        u = float(signals["wheel_speed"][0])
        if self.grade_estimator is not None:
            # the accelerometer reads u̇ − v·r + g·sin θ; without slip the CG moves sideways at v = b·r (b: the CG
            # ahead of the rear point), so the grade filter takes the reading plus b·r²
            gyro = float(signals["tractor_yaw_rate"][0])
            f_x = float(signals["tractor_longitudinal_acceleration"][0]) + self._cg_ahead * gyro * gyro
            sine = self.grade_estimator.update(f_x, u, dt)
            u = u * math.sqrt(1.0 - min(sine * sine, 1.0))  # the wheel's speed along the ground made horizontal
        f_y = float(signals["tractor_lateral_acceleration"][0]) if self.rear_point == "lateral_acceleration" else 0.0
        gammas = signals["articulation"][:1]
        if self.unit > 1:
            gammas = np.concatenate([gammas, signals["rear_articulation"][: self.unit - 1]])
        if self.variant == "yaw_rate":
            r1 = float(signals["tractor_yaw_rate"][0])
        else:
            r1 = u * math.tan(float(signals["front_steer"][0])) / self.wheelbase
        if self._last is None:
            self._last = (u, r1, f_y, gammas)
            return self.buffer.offtracking()
        u_prev, r1_prev, f_y_prev, gammas_prev = self._last
        self._last = (u, r1, f_y, gammas)
        # Trapezoidal rule over the interval between the two samples.
        u_mid, r1_mid = 0.5 * (u + u_prev), 0.5 * (r1 + r1_prev)
        # Kingpin velocity (tractor axes) with the rear point's lateral velocity as set.
        vk1 = tractor_kingpin_velocity(self.params, self.rear_point, u_mid, r1_mid, 0.5 * (f_y + f_y_prev))
        # Down the chain to the unit's coupling, in the axes of the unit ahead, at mid-interval; ψ_k = ψ_(k-1) − Γ.
        dpsi2 = r1_mid * dt
        mids: list[float] = []
        rates: list[float] = []
        for gamma, gamma_prev in zip(gammas.tolist(), gammas_prev.tolist(), strict=True):
            delta_gamma = gamma - gamma_prev
            dpsi2 = dpsi2 - delta_gamma
            mids.append(gamma - 0.5 * delta_gamma)
            rates.append(dpsi2 / dt)
        vk1 = coupling_velocity(self.params, self.unit, vk1, mids, rates)
        # Into the unit's axes at mid-interval, R(Γ), then into its previous frame, R(Δψ/2).
        g_mid = mids[-1]
        vk2x = math.cos(g_mid) * vk1[0] - math.sin(g_mid) * vk1[1]
        vk2y = math.sin(g_mid) * vk1[0] + math.cos(g_mid) * vk1[1]
        half = 0.5 * dpsi2
        dx = (math.cos(half) * vk2x - math.sin(half) * vk2y) * dt
        dy = (math.sin(half) * vk2x + math.cos(half) * vk2y) * dt
        self.buffer.push(dx, dy, dpsi2)
        return self.buffer.offtracking()
