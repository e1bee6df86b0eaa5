"""The high-speed stability steer of a semi-trailer: gain-scheduled static feedback of the gyros and the articulation.

At highway speed the steered trailer's objective is not its path but its sway: how much it amplifies the tractor's
lateral acceleration (rearward amplification) and how fast its yaw mode decays (yaw damping). With
``high_speed_mode = "stability"`` (:class:`~controller.path_following_config.PathFollowingConfig`) the path-following
command's fade above the crossover (:func:`~controller.steer_output.high_speed_fade`) is complemented by this
command, which fades in on the same schedule::

    δ_s = −(1 − f_pf(u))·K(u)·y,   y = [r1, r2, Γ]                     (every steerable axle of the unit)

``y`` is what the combination measures: the tractor's and the trailer's yaw-rate gyros and the articulation angle
(its rate is ``Γ̇ = r1 − r2``, so it adds nothing to a static feedback of ``y``). ``K(u)`` is interpolated linearly in
speed between gains designed at :func:`design_speeds` (held at the ends). A combination with more towed units has
its own design, on the nonlinear model's Jacobian (:mod:`controller.high_speed_chain`).

Design (:func:`design_gain`)
----------------------------
The plant is the linear tractor–semi-trailer of :func:`vehicle_model.linearise.linear_yaw_plane_model`
(docs/vehicle_dynamics.md §2.1, states ``x = [v1, r1, r2, Γ]``), with the stability steer ``δ_s`` applied alike to
every steerable trailer axle through a first-order actuator lag ``τ_a`` and a disturbance ``w`` (unit white noise) at
the tractor's steer through a first-order low-pass of bandwidth ``ω_w`` (the driver's steer; it also keeps the
lateral accelerations, which the steer reaches directly, free of a white-noise feed-through)::

    ẋ = A x + b_1 δ_1 + b_s δ_s,   δ̇_1 = ω_w (w − δ_1),   δ̇_s = (δ_c − δ_s)/τ_a,   δ_c = −K y

The cost is the closed loop's H2 norm from ``w`` to ``z``, the variance of ``z`` under the white-noise steer
(Zhou, Doyle & Glover, *Robust and Optimal Control*, 1996: ``‖G‖₂² = tr(C P Cᵀ)``, ``A P + P Aᵀ + B Bᵀ = 0``)::

    z = [ (a_y2 − a_y1)/a_ref,  q_Γ̇·(r1 − r2)/r_ref,  q_δ·δ_c,  q_δ̇·δ̇_s/ω_w ]

``a_y1 = v̇1 + u r1`` and ``a_y2 = v̇1 − h1 ṙ1 − h2 ṙ2 + u r1`` are the two units' lateral accelerations at their
CGs (the time derivative of the trailer CG's lateral velocity ``v2 = v1 − h1 r1 − h2 r2 + uΓ`` of the linear model,
plus ``u r2``); ``a_ref`` and ``r_ref`` are the tractor's steady lateral acceleration and yaw rate per radian of its
steer at that speed, so each term is relative to what the tractor does: the first is the trailer's lateral
acceleration relative to the tractor's (rearward amplification above one, a sway that goes on after the tractor's
has stopped), the second the articulation rate, the third and fourth the steer effort and its rate per radian of the
tractor's steer (the rate over the disturbance's bandwidth). The static output-feedback gain that minimises it is
found numerically from zero (the unsteered trailer, stable at every speed of the grid), as in Levine & Athans (1970,
IEEE Trans. Automatic Control 15(1)), here by a quasi-Newton search (BFGS, numerical gradient); an unstable closed
loop costs :data:`UNSTABLE_COST`. The actuator lag and the rate term make the problem well posed: without them the
cost falls without bound as the gain grows along the direction that holds ``K y`` finite.
Why this cost and not an LQR gain projected on the outputs: docs/controller_design.md §3.5 (*The stability mode*).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize

from vehicle_model.errors import InputError
from vehicle_model.linearise import linear_yaw_plane_model
from vehicle_model.parameters import VehicleParams

__all__ = [
    "MEASURED",
    "StabilityPlant",
    "StabilitySteer",
    "StabilityWeights",
    "design_gain",
    "design_speeds",
    "h2_cost",
    "stability_plant",
    "weighted_h2",
]

MEASURED = ("r1", "r2", "gamma")
"""The signals the stability steer feeds back, in the order of its gains: the two gyros and the articulation."""

UNSTABLE_COST = 1e12
"""Cost of a gain whose closed loop has a pole at or right of ``−STABILITY_MARGIN``."""

STABILITY_MARGIN = 1e-3
"""Smallest decay rate [1/s] a designed closed loop's poles must have."""

GRID_STEP = 5.0
"""Spacing [m/s] of the design speeds above the crossover's lower speed."""

GRID_TOP = 35.0
"""Highest design speed [m/s] (126 km/h); the gain is held above it."""


@dataclass(frozen=True)
class StabilityWeights:
    """Weights and shaping of the stability steer's H2 cost (module docstring).

    Parameters
    ----------
    articulation_rate : float
        ``q_Γ̇``, weight of the articulation rate relative to the tractor's steady yaw rate.
    steer : float
        ``q_δ``, weight of the commanded steer per radian of the tractor's steer.
    steer_rate : float
        ``q_δ̇``, weight of the steer's rate per radian of the tractor's steer over the disturbance's bandwidth.
    disturbance_bandwidth : float
        ``ω_w`` [rad/s] of the tractor's steer disturbance (1 Hz: above the lane change's 0.4 Hz and the trailer's
        yaw mode near 2.4 rad/s).
    actuator_lag : float
        ``τ_a`` [s] of the steer actuator in the design (a 10 rad/s servo; it bounds the gain, module docstring).
    """

    articulation_rate: float = 0.1
    steer: float = 0.1
    steer_rate: float = 0.1
    disturbance_bandwidth: float = 2.0 * math.pi
    actuator_lag: float = 0.1

    def __post_init__(self) -> None:
        for name in ("articulation_rate", "steer", "steer_rate", "disturbance_bandwidth", "actuator_lag"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise InputError(f"StabilityWeights.{name} = {value!r} must be finite and ≥ 0")
        if not (self.steer > 0.0 and self.disturbance_bandwidth > 0.0 and self.actuator_lag > 0.0):
            raise InputError("StabilityWeights.steer, disturbance_bandwidth and actuator_lag must be > 0")


@dataclass(frozen=True)
class StabilityPlant:
    """The design plant at one speed: state ``[v1, r1, r2, Γ, δ_1, δ_s]`` (module docstring).

    Attributes
    ----------
    a : numpy.ndarray
        ``(6, 6)`` open-loop matrix (no feedback).
    b_w : numpy.ndarray
        ``(6,)`` input of the white-noise disturbance.
    b_c : numpy.ndarray
        ``(6,)`` input of the commanded steer ``δ_c``.
    c_y : numpy.ndarray
        ``(3, 6)`` the measured signals :data:`MEASURED`.
    c_relative : numpy.ndarray
        ``(6,)`` the lateral acceleration of the trailer's CG minus the tractor's, ``a_y2 − a_y1`` [m/s²].
    c_articulation_rate : numpy.ndarray
        ``(6,)`` ``Γ̇ = r1 − r2``.
    c_steer : numpy.ndarray
        ``(6,)`` the actuator's steer ``δ_s``.
    reference_acceleration, reference_yaw_rate : float
        The tractor's steady lateral acceleration [m/s²] and yaw rate [rad/s] per radian of its steer.
    """

    a: np.ndarray
    b_w: np.ndarray
    b_c: np.ndarray
    c_y: np.ndarray
    c_relative: np.ndarray
    c_articulation_rate: np.ndarray
    c_steer: np.ndarray
    reference_acceleration: float
    reference_yaw_rate: float


def _semitrailer(params: VehicleParams) -> None:
    if params.n_units != 2:
        raise InputError(
            f"StabilitySteer is designed on the tractor–semi-trailer's linear model; vehicle {params.name!r} has "
            f"{params.n_units} units (controller.high_speed_chain.ChainStabilitySteer designs for it)"
        )


def stability_plant(params: VehicleParams, speed: float, weights: StabilityWeights | None = None) -> StabilityPlant:
    """The linear design plant of the stability steer at ``speed`` [m/s] (module docstring).

    Parameters
    ----------
    params
        A tractor–semi-trailer with at least one steerable trailer axle and a steerable tractor axle.
    speed
        Forward speed [m/s] > 0.
    weights
        Disturbance bandwidth and actuator lag (defaults of :class:`StabilityWeights`).

    Returns
    -------
    StabilityPlant
    """
    _semitrailer(params)
    if not (math.isfinite(speed) and speed > 0.0):
        raise InputError(f"speed = {speed!r} must be > 0 m/s")
    w = StabilityWeights() if weights is None else weights
    model = linear_yaw_plane_model(params, speed)
    a4, b4 = np.asarray(model.A), np.asarray(model.B)
    labels = list(model.input_labels)
    table = params.axle_table
    steered = [(f"steer_{n}", unit) for n, unit, s in zip(table.names, table.unit, table.steerable, strict=True) if s]
    tractor = [name for name, unit in steered if unit == 0]
    trailer = [name for name, unit in steered if unit == 1]
    if not tractor or not trailer:
        raise InputError(f"vehicle {params.name!r} needs a steerable tractor axle and a steerable trailer axle")
    b1 = b4[:, [labels.index(n) for n in tractor]].sum(axis=1)
    bs = b4[:, [labels.index(n) for n in trailer]].sum(axis=1)
    a = np.zeros((6, 6))
    a[:4, :4] = a4
    a[:4, 4] = b1
    a[:4, 5] = bs
    a[4, 4] = -w.disturbance_bandwidth
    a[5, 5] = -1.0 / w.actuator_lag
    b_w = np.zeros(6)
    b_w[4] = w.disturbance_bandwidth
    b_c = np.zeros(6)
    b_c[5] = 1.0 / w.actuator_lag
    c_y = np.zeros((3, 6))
    c_y[0, 1] = c_y[1, 2] = c_y[2, 3] = 1.0
    # a_y2 − a_y1 = (v̇1 − h1 ṙ1 − h2 ṙ2 + u r1) − (v̇1 + u r1) = −h1 ṙ1 − h2 ṙ2 (module docstring).
    c_relative = np.array([0.0, -params.h1, -params.h2, 0.0]) @ a[:4]
    c_articulation_rate = np.array([0.0, 1.0, -1.0, 0.0, 0.0, 0.0])
    steady = -np.linalg.solve(a4, b1)  # [v1, r1, r2, Γ] per radian of the tractor's steer, held
    reference_acceleration = abs(speed * steady[1])  # a_y1 = u r1 in the steady turn
    c_steer = np.zeros(6)
    c_steer[5] = 1.0
    return StabilityPlant(
        a, b_w, b_c, c_y, c_relative, c_articulation_rate, c_steer, reference_acceleration, abs(steady[1])
    )


def h2_cost(gain: np.ndarray, plant: StabilityPlant, weights: StabilityWeights | None = None) -> float:
    """The closed loop's squared H2 norm from the tractor's steer disturbance to the weighted outputs.

    Parameters
    ----------
    gain
        ``K``, ``(3,)`` on :data:`MEASURED`: ``δ_c = −K y``.
    plant
        :func:`stability_plant`.
    weights
        The cost's weights.

    Returns
    -------
    float
        ``tr(C_z P C_zᵀ)`` with ``A_cl P + P A_clᵀ + b_w b_wᵀ = 0`` (module docstring); :data:`UNSTABLE_COST` when
        a closed-loop pole has a decay rate below :data:`STABILITY_MARGIN`.
    """
    w = StabilityWeights() if weights is None else weights
    feedback = -np.asarray(gain, dtype=float) @ plant.c_y  # δ_c = feedback · x
    a_cl = plant.a + np.outer(plant.b_c, feedback)
    if not np.all(np.isfinite(a_cl)) or np.max(np.linalg.eigvals(a_cl).real) > -STABILITY_MARGIN:
        return UNSTABLE_COST
    relative = plant.c_relative / plant.reference_acceleration
    rate, reference = plant.c_articulation_rate, plant.reference_yaw_rate
    return weighted_h2(a_cl, plant.b_w, w, relative, rate, reference, feedback, plant.c_steer)


def weighted_h2(
    a_cl: np.ndarray,
    b_w: np.ndarray,
    weights: StabilityWeights,
    relative_acceleration: np.ndarray,
    c_articulation_rate: np.ndarray,
    reference_yaw_rate: float,
    feedback: np.ndarray,
    c_steer: np.ndarray,
) -> float:
    """``tr(C_z P C_zᵀ)`` with ``A_cl P + P A_clᵀ + b_w b_wᵀ = 0``: the squared H2 norm of the closed loop ``a_cl``
    from the disturbance ``b_w`` to the weighted outputs ``z`` (module docstring; Zhou, Doyle & Glover 1996).

    The rows of ``z`` per state: ``relative_acceleration`` (the units' lateral accelerations relative to the
    tractor's, over ``a_ref``), ``c_articulation_rate`` (the couplings' rates, weighted and over ``r_ref`` here),
    ``feedback`` (``−K·C_y``, the commanded steer) and the steer's rate from ``c_steer`` (the applied steer's row).
    """
    w = weights
    c_z = np.vstack(
        [
            relative_acceleration,
            w.articulation_rate * c_articulation_rate / reference_yaw_rate,
            w.steer * feedback,
            w.steer_rate * (feedback - c_steer) / (w.actuator_lag * w.disturbance_bandwidth),
        ]
    )
    covariance = scipy.linalg.solve_continuous_lyapunov(a_cl, -np.outer(b_w, b_w))
    return float(np.trace(c_z @ covariance @ c_z.T))


def design_gain(params: VehicleParams, speed: float, weights: StabilityWeights | None = None) -> np.ndarray:
    """The static output-feedback gain ``K`` on :data:`MEASURED` that minimises :func:`h2_cost` at ``speed`` [m/s].

    Found from ``K = 0`` (module docstring); ``K = 0`` (the unsteered trailer) when the search ends on a cost no lower
    than it. Raises :class:`~vehicle_model.errors.InputError` when the unsteered trailer is itself unstable at that
    speed (no stable start).
    """
    plant = stability_plant(params, speed, weights)
    start = np.zeros(len(MEASURED))
    open_loop = h2_cost(start, plant, weights)
    if open_loop >= UNSTABLE_COST:
        raise InputError(f"the unsteered combination is unstable at {speed:.1f} m/s: no stability steer designed")
    found = scipy.optimize.minimize(h2_cost, start, args=(plant, weights), method="BFGS")
    if not found.fun < open_loop:
        return start
    return np.asarray(found.x, dtype=float)


def design_speeds(crossover_start: float) -> np.ndarray:
    """The design speeds [m/s]: the crossover's lower speed, then the multiples of :data:`GRID_STEP` more than half a
    step above it, up to :data:`GRID_TOP`."""
    if not (math.isfinite(crossover_start) and 0.0 < crossover_start < GRID_TOP):
        raise InputError(f"crossover start = {crossover_start!r} m/s must be in (0, {GRID_TOP}) for the design grid")
    multiples = np.arange(1, math.floor(GRID_TOP / GRID_STEP) + 1) * GRID_STEP
    return np.concatenate([[crossover_start], multiples[multiples > crossover_start + 0.5 * GRID_STEP]])


class StabilitySteer:
    """The gain-scheduled stability steer of a semi-trailer (module docstring).

    Parameters
    ----------
    params
        A tractor–semi-trailer.
    crossover_start
        The crossover's lower speed [m/s], the lowest design speed (below it the command is not used).
    weights
        The cost's weights (:class:`StabilityWeights`).

    Attributes
    ----------
    speeds : numpy.ndarray
        Design speeds [m/s].
    gains : numpy.ndarray
        ``(len(speeds), 3)`` gains on :data:`MEASURED` [rad/(rad/s), rad/(rad/s), rad/rad].
    """

    def __init__(self, params: VehicleParams, crossover_start: float, weights: StabilityWeights | None = None) -> None:
        _semitrailer(params)
        self.weights = StabilityWeights() if weights is None else weights
        self.speeds = design_speeds(crossover_start)
        self.gains = np.array([design_gain(params, float(u), self.weights) for u in self.speeds])

    def gain(self, speed: float) -> np.ndarray:
        """``K(u)``: the designed gains interpolated linearly in speed, held outside the grid."""
        return np.array([np.interp(speed, self.speeds, column) for column in self.gains.T])

    def __call__(self, speed: float, tractor_yaw_rate: float, trailer_yaw_rate: float, articulation: float) -> float:
        """The stability steer ``−K(u)·y`` [rad] of every steerable trailer axle, before its fade.

        Parameters
        ----------
        speed
            Forward speed ``u`` [m/s].
        tractor_yaw_rate, trailer_yaw_rate
            The gyros' ``r1``, ``r2`` [rad/s].
        articulation
            ``Γ`` [rad], the tractor's heading minus the trailer's.
        """
        return -float(self.gain(speed) @ np.array([tractor_yaw_rate, trailer_yaw_rate, articulation]))
