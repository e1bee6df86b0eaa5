"""The high-speed stability steer of a combination with several towed units (a B-double, an A-double).

The tractor–semi-trailer's stability steer (:mod:`controller.high_speed`) generalised to a chain of ``N`` units with
any of its towed units steerable: one steer per steered unit ``k`` (the same angle on each of its steerable axles),
fading in above the crossover as path following fades out, from a static feedback of everything the combination
measures::

    δ_s,k = −(1 − f_pf(u))·K_k(u)·y,   y = [r1, r2, …, rN, Γ1, …, Γ_{N−1}]

the yaw-rate gyro of every unit and every articulation angle (``Γ_j = ψ_j − ψ_{j+1}``). ``K(u)``, ``(n_steered, 2N −
1)``, is interpolated linearly in speed between gains designed at :func:`~controller.high_speed.design_speeds`
(held at the ends). For two units the tractor–semi-trailer's design of :mod:`controller.high_speed` is used instead
(its linear model, :func:`~vehicle_model.linearise.linear_yaw_plane_model`, covers two units only).

Design (:func:`design_chain_gain`)
----------------------------------
The plant is the nonlinear model's Jacobian (:func:`vehicle_model.linearise.linearise`) in straight running at the
design speed on a dry road (μ = 0.8), its lateral states ``x`` (``v1``, every yaw rate and articulation, every
axle's transient slip; ``u`` decouples from them in straight running and is dropped), augmented as in
:mod:`controller.high_speed` with the tractor's steer ``δ_1`` (white noise ``w`` through a low-pass of bandwidth
``ω_w``) and each steered unit's actuator ``δ_s,k`` (first-order lag ``τ_a``)::

    ẋ = A x + b_1 δ_1 + Σ_k b_k δ_s,k,   δ̇_1 = ω_w (w − δ_1),   δ̇_s,k = (δ_c,k − δ_s,k)/τ_a,   δ_c = −K y

The cost is the closed loop's squared H2 norm from ``w`` (Zhou, Doyle & Glover, *Robust and Optimal Control*, 1996:
``‖G‖₂² = tr(C P Cᵀ)``, ``A P + P Aᵀ + B Bᵀ = 0``) to::

    z = [ q_a,k·(a_y,k − a_y1)/a_ref  (each towed unit k with a term, below),
          q_Γ̇·Γ̇_j/r_ref             (each coupling j),
          q_δ·δ_c,k,  q_δ̇·δ̇_s,k/ω_w (each steered unit k) ]

with the weights, ``a_ref`` and ``r_ref`` of :class:`~controller.high_speed.StabilityWeights` and
:mod:`controller.high_speed` (the tractor's steady lateral acceleration and yaw rate per radian of its steer). Each
unit's CG lateral velocity is linear in the yaw rates (the chain's lever arms ``λ_kj`` of
:mod:`vehicle_model.chain`, eq. C2, linearised: ``v_k = v1 + Σ_j λ_kj r_j + u Σ_{j<k} Γ_j``), so its lateral
acceleration relative to the tractor's is::

    a_y,k − a_y1 = Σ_j λ_kj ṙ_j                                          (v̇_k + u r_k − v̇_1 − u r_1)

The acceleration terms: the rearmost unit's with ``q_a = 1`` (rearward amplification, what the standards measure,
ISO 14791; the tractor–semi-trailer's only term) and every other steered unit's with ``q_a =``
:data:`INNER_ACCELERATION_WEIGHT`. A steered unit ahead of the rearmost has a term of its own: it is a laden unit
that sways and can roll over too, and the rearmost unit's relative acceleration is reached through its coupling,
so a design blind to it may buy the rear's with the lead's. Its weight is the rearmost's: on the steered B-double's
88 km/h lane change a lower one gave both units more rearward amplification for less steer (docs/controller_design.md
§3.5, *The B-double*). The static output-feedback gain that minimises the cost is found from ``K = 0`` (every unit
unsteered) as in Levine & Athans (1970, IEEE Trans. Automatic Control 15(1)), by a
quasi-Newton search (BFGS, numerical gradient); an unstable closed loop costs
:data:`~controller.high_speed.UNSTABLE_COST`, and so does one with a pole of damping ratio below
``min(MIN_DAMPING, OPEN_LOOP_DAMPING_SHARE·ζ_open)`` (a conic sector of the left half-plane, the pole region of
Chilali & Gahinet 1996, IEEE Trans. Automatic Control 41(3); ``ζ_open`` the unsteered combination's least damping
ratio). Without the sector the H2 optimum of this plant, whose tyres' transient slip and actuator lag are states, sits
on the stability boundary: an actuator–tyre mode that the disturbance barely excites is left undamped
(docs/controller_design.md §3.5, *The stability mode on the B-double*, gives the measured case). The floor is 0.3
where the unsteered combination is better damped and nine tenths of its damping where it is not, so that ``K = 0``
lies inside the admissible gains.

Where the unsteered combination's least damped pole lies close to the floor, every descent direction from ``K = 0``
leaves the admissible gains within a step and the search stalls (the steered A-double at 25 m/s ends on ``K = 0``).
When the search from ``K = 0`` leaves any design speed's cost above :data:`STALL_SHARE` of the unsteered one, the
schedule is designed again by :func:`~controller.high_speed_chain_search.continued_schedule` (continuation over
speed, a logarithmic barrier at the pole region's boundary, a gain-norm guard; the region also bounds the decay
rate and holds for an actuator without lag) and that schedule is used if its interpolated gains stay in the region
between the design speeds (:func:`~controller.high_speed_chain_search.schedule_admissible`); otherwise the search
from ``K = 0`` is kept. On the steered B-double the search from ``K = 0`` lowers every speed's cost by more than a
tenth and is used unchanged.

The design assumes every towed unit with a steerable axle is steered with this mode (the configuration refuses a
steerable unit left unsteered, ``scenarios.configuration``).

A schedule is designed once per machine and kept in the project's cache (:func:`schedule_key`,
:mod:`vehicle_model.disk_cache`): a combination's design takes seconds (docs/controller_design.md §3.5).
"""

from __future__ import annotations

import functools
import math
import platform
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

import casadi
import numpy as np
import scipy
import scipy.optimize

import vehicle_model
from vehicle_model.disk_cache import (
    entry_path,
    exact_text,
    key_of,
    numpy_runtime,
    read_entry,
    sources_digest,
    write_entry,
)
from vehicle_model.dynamics import VehicleModel
from vehicle_model.errors import InputError
from vehicle_model.linearise import linearise
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import initial_state

from .high_speed import STABILITY_MARGIN, UNSTABLE_COST, StabilityWeights, design_speeds, weighted_h2
from .high_speed_chain_search import continued_schedule, schedule_admissible

__all__ = [
    "INNER_ACCELERATION_WEIGHT",
    "MIN_DAMPING",
    "OPEN_LOOP_DAMPING_SHARE",
    "ChainPlant",
    "ChainStabilitySteer",
    "chain_h2_cost",
    "chain_plant",
    "design_chain_gain",
    "measured_signals",
    "steered_units",
]

INNER_ACCELERATION_WEIGHT = 1.0
"""``q_a`` of a steered unit's relative lateral acceleration ahead of the rearmost unit (module docstring)."""

MIN_DAMPING = 0.3
"""Damping ratio every closed-loop pole of a design must reach, unless the unsteered combination's is lower
(:data:`OPEN_LOOP_DAMPING_SHARE`; module docstring)."""

OPEN_LOOP_DAMPING_SHARE = 0.9
"""Share of the unsteered combination's least damping ratio a design's poles must keep where it is below
:data:`MIN_DAMPING` (below one, so that ``K = 0`` lies inside the admissible gains and the search can leave it)."""

STALL_SHARE = 0.9
"""Share of the unsteered cost above which a design speed's search from ``K = 0`` counts as stalled (module
docstring)."""

DESIGN_FRICTION = 0.8
"""Road friction of the design's operating point (dry)."""


def steered_units(params: VehicleParams) -> tuple[int, ...]:
    """The towed units with a steerable axle (1 the first towed unit, as :attr:`~vehicle_model.parameters.AxleTable.
    unit`), front to rear."""
    return tuple(k for k, towed in enumerate(params.trailers, start=1) if any(a.steerable for a in towed.axles))


def measured_signals(params: VehicleParams) -> tuple[str, ...]:
    """The state names of ``y``, in the order of the gains' columns: every unit's yaw rate, then every
    articulation (``r1, r2, …, gamma, gamma2, …``)."""
    rates = tuple(f"r{k}" for k in range(1, params.n_units + 1))
    return rates + tuple("gamma" if j == 1 else f"gamma{j}" for j in range(1, params.n_units))


def _lever_arms(params: VehicleParams) -> np.ndarray:
    """``λ_kj`` [m] of :mod:`vehicle_model.chain` (C2), ``(N, N)``: unit ``k``'s CG lateral velocity per yaw rate
    of unit ``j`` (row 0, the tractor, is zero)."""
    hinges = params.hinge_distances()  # (f_k, e_k) per unit
    n = params.n_units
    arms = np.zeros((n, n))
    for k in range(1, n):
        arms[k, 0] = -hinges[0][1]
        for j in range(1, k):
            arms[k, j] = -(hinges[j][0] + hinges[j][1])
        arms[k, k] = -hinges[k][0]
    return arms


@dataclass(frozen=True)
class ChainPlant:
    """The design plant at one speed: state ``[x, δ_1, δ_s,1, …]`` (module docstring).

    Attributes
    ----------
    a : numpy.ndarray
        ``(n, n)`` open-loop matrix (no feedback).
    b_w : numpy.ndarray
        ``(n,)`` input of the white-noise disturbance.
    b_c : numpy.ndarray
        ``(n, n_steered)`` inputs of the commanded steers ``δ_c``.
    c_y : numpy.ndarray
        ``(n_measured, n)`` the measured signals :func:`measured_signals`.
    c_acceleration : numpy.ndarray
        ``(n_terms, n)`` the weighted relative lateral accelerations ``q_a,k·(a_y,k − a_y1)`` [m/s²].
    c_articulation_rate : numpy.ndarray
        ``(N − 1, n)`` every coupling's ``Γ̇_j``.
    c_steer : numpy.ndarray
        ``(n_steered, n)`` the actuators' steers ``δ_s,k``.
    reference_acceleration, reference_yaw_rate : float
        The tractor's steady lateral acceleration [m/s²] and yaw rate [rad/s] per radian of its steer.
    min_damping : float
        Least damping ratio a designed closed loop's poles must have: :data:`MIN_DAMPING`, or
        :data:`OPEN_LOOP_DAMPING_SHARE` of the open loop's least if that is lower.
    """

    a: np.ndarray
    b_w: np.ndarray
    b_c: np.ndarray
    c_y: np.ndarray
    c_acceleration: np.ndarray
    c_articulation_rate: np.ndarray
    c_steer: np.ndarray
    reference_acceleration: float
    reference_yaw_rate: float
    min_damping: float


def _damping(a: np.ndarray) -> float:
    """The least damping ratio ``−Re λ/|λ|`` of the poles of ``a``."""
    poles = np.linalg.eigvals(a)
    return float(np.min(-poles.real / np.maximum(np.abs(poles), 1e-12)))


def _check_chain(params: VehicleParams) -> tuple[int, ...]:
    units = steered_units(params)
    if not units:
        raise InputError(
            f"controller.high_speed_mode = 'stability' steers the towed units' steerable axles; vehicle "
            f"{params.name!r} has none (use high_speed_mode = 'unsteered')"
        )
    return units


def chain_plant(params: VehicleParams, speed: float, weights: StabilityWeights | None = None) -> ChainPlant:
    """The linear design plant of the combination's stability steer at ``speed`` [m/s] (module docstring).

    Parameters
    ----------
    params
        A combination with a steerable tractor axle and at least one steerable towed axle.
    speed
        Forward speed [m/s] > 0.
    weights
        Disturbance bandwidth and actuator lag (defaults of :class:`~controller.high_speed.StabilityWeights`).

    Returns
    -------
    ChainPlant
    """
    units = _check_chain(params)
    if not (math.isfinite(speed) and speed > 0.0):
        raise InputError(f"speed = {speed!r} must be > 0 m/s")
    w = StabilityWeights() if weights is None else weights
    model = VehicleModel(params, compile=False)
    layout = model.layout
    table = params.axle_table
    unit_of = dict(zip(table.names, table.unit, strict=True))
    tractor = [f"steer_{n}" for n in layout.steerable_axles if unit_of[n] == 0]
    if not tractor:
        raise InputError(f"vehicle {params.name!r} needs a steerable tractor axle for the stability steer's design")
    steers = [[f"steer_{n}" for n in layout.steerable_axles if unit_of[n] == k] for k in units]
    x0 = initial_state(layout, speed=speed).to_vector()
    u0 = np.zeros(layout.n_inputs)
    u0[layout.mu_slice] = DESIGN_FRICTION
    # The drive force that holds the speed: ∂u̇/∂F_drive is constant in straight running.
    u_row = layout.state_index("u")
    resistance = float(np.asarray(model.rhs(x0, u0)).ravel()[u_row])
    u0[layout.drive_index] = 1.0
    per_newton = float(np.asarray(model.rhs(x0, u0)).ravel()[u_row]) - resistance
    u0[layout.drive_index] = -resistance / per_newton
    lateral = [s for s in layout.states if s not in ("X", "Y", "psi1", "u")]
    inputs = tractor + [name for group in steers for name in group]
    system = linearise(model, x0, u0, states=lateral, input_names=inputs)
    a_x, b_x = np.asarray(system.A), np.asarray(system.B)
    nx, ns = len(lateral), len(units)
    n = nx + 1 + ns
    a = np.zeros((n, n))
    a[:nx, :nx] = a_x
    a[:nx, nx] = b_x[:, : len(tractor)].sum(axis=1)
    column = len(tractor)
    for k, group in enumerate(steers):
        a[:nx, nx + 1 + k] = b_x[:, column : column + len(group)].sum(axis=1)
        column += len(group)
    a[nx, nx] = -w.disturbance_bandwidth
    a[nx + 1 :, nx + 1 :] = -np.eye(ns) / w.actuator_lag
    b_w = np.zeros(n)
    b_w[nx] = w.disturbance_bandwidth
    b_c = np.zeros((n, ns))
    b_c[nx + 1 :, :] = np.eye(ns) / w.actuator_lag
    measured = measured_signals(params)
    c_y = np.zeros((len(measured), n))
    for row, name in enumerate(measured):
        c_y[row, lateral.index(name)] = 1.0
    rates = [lateral.index(f"r{k}") for k in range(1, params.n_units + 1)]
    arms = _lever_arms(params)
    rearmost = params.n_units - 1
    terms = [(k, INNER_ACCELERATION_WEIGHT) for k in units if k != rearmost] + [(rearmost, 1.0)]
    c_acceleration = np.array([q * arms[k] @ a[rates] for k, q in terms])  # Σ_j λ_kj ṙ_j (module docstring)
    c_articulation_rate = np.zeros((params.n_units - 1, n))
    for j in range(params.n_units - 1):  # Γ̇_j = r_j − r_{j+1}
        c_articulation_rate[j, rates[j]], c_articulation_rate[j, rates[j + 1]] = 1.0, -1.0
    c_steer = np.zeros((ns, n))
    c_steer[:, nx + 1 :] = np.eye(ns)
    steady = -np.linalg.solve(a_x, a[:nx, nx])  # the lateral states per radian of the tractor's steer, held
    yaw_rate = abs(float(steady[lateral.index("r1")]))
    least = min(MIN_DAMPING, OPEN_LOOP_DAMPING_SHARE * _damping(a))
    return ChainPlant(a, b_w, b_c, c_y, c_acceleration, c_articulation_rate, c_steer, speed * yaw_rate, yaw_rate, least)


def chain_h2_cost(gain: np.ndarray, plant: ChainPlant, weights: StabilityWeights | None = None) -> float:
    """The closed loop's squared H2 norm from the tractor's steer disturbance to the weighted outputs.

    Parameters
    ----------
    gain
        ``K``, ``(n_steered, n_measured)`` on :func:`measured_signals` (or flattened row by row): ``δ_c = −K y``.
    plant
        :func:`chain_plant`.
    weights
        The cost's weights.

    Returns
    -------
    float
        ``tr(C_z P C_zᵀ)`` with ``A_cl P + P A_clᵀ + b_w b_wᵀ = 0`` (module docstring);
        :data:`~controller.high_speed.UNSTABLE_COST` when a closed-loop pole has a decay rate below
        :data:`~controller.high_speed.STABILITY_MARGIN`.
    """
    w = StabilityWeights() if weights is None else weights
    k = np.asarray(gain, dtype=float).reshape(plant.b_c.shape[1], plant.c_y.shape[0])
    feedback = -k @ plant.c_y  # δ_c = feedback · x
    a_cl = plant.a + plant.b_c @ feedback
    if not np.all(np.isfinite(a_cl)):
        return UNSTABLE_COST
    poles = np.linalg.eigvals(a_cl)
    if np.max(poles.real) > -STABILITY_MARGIN or np.min(-poles.real / np.abs(poles)) < plant.min_damping:
        return UNSTABLE_COST
    relative = plant.c_acceleration / plant.reference_acceleration
    rate, reference = plant.c_articulation_rate, plant.reference_yaw_rate
    return weighted_h2(a_cl, plant.b_w, w, relative, rate, reference, feedback, plant.c_steer)


def design_chain_gain(params: VehicleParams, speed: float, weights: StabilityWeights | None = None) -> np.ndarray:
    """The static output-feedback gain ``K`` ``(n_steered, n_measured)`` that minimises :func:`chain_h2_cost` at
    ``speed`` [m/s].

    Found from ``K = 0`` (module docstring); ``K = 0`` (every unit unsteered) when the search ends on a cost no lower
    than it. Raises :class:`~vehicle_model.errors.InputError` when the unsteered combination is itself unstable at
    that speed (no stable start).
    """
    plant = chain_plant(params, speed, weights)
    shape = (plant.b_c.shape[1], plant.c_y.shape[0])
    start = np.zeros(shape[0] * shape[1])
    open_loop = chain_h2_cost(start, plant, weights)
    if open_loop >= UNSTABLE_COST:
        raise InputError(f"the unsteered combination is unstable at {speed:.1f} m/s: no stability steer designed")
    found = scipy.optimize.minimize(chain_h2_cost, start, args=(plant, weights), method="BFGS")
    if not found.fun < open_loop:
        return start.reshape(shape)
    return np.asarray(found.x, dtype=float).reshape(shape)


def _designed_schedule(
    params: VehicleParams, crossover_start: float, weights: StabilityWeights
) -> tuple[np.ndarray, np.ndarray]:
    """The design speeds and their gains (module docstring, *Design*)."""
    speeds = design_speeds(crossover_start)
    gains = np.array([design_chain_gain(params, float(u), weights) for u in speeds])
    plants = [chain_plant(params, float(u), weights) for u in speeds]
    unsteered = np.array([chain_h2_cost(np.zeros_like(gains[0]), plant, weights) for plant in plants])
    designed = np.array([chain_h2_cost(gain, plant, weights) for gain, plant in zip(gains, plants, strict=True)])
    if np.any(designed > STALL_SHARE * unsteered):  # the search from K = 0 stalled: the continued design
        continued = continued_schedule(plants, chain_h2_cost, weights)
        if schedule_admissible(speeds, continued, lambda u: chain_plant(params, u, weights)):
            gains = continued
    return speeds, gains


DESIGN_SOURCES: Final[tuple[Path, ...]] = (
    *sorted(Path(__file__).resolve().parent.glob("*.py")),
    *sorted(Path(vehicle_model.__file__).resolve().parent.glob("*.py")),
)
"""The sources whose contents enter a schedule's cache key: every module of the ``controller`` and ``vehicle_model``
packages (the design, its search, the model it linearises; an edit anywhere there designs the schedules again)."""


def schedule_key(params: VehicleParams, crossover_start: float, weights: StabilityWeights) -> str:
    """The SHA-256 (hex) of everything that decides a schedule (:mod:`vehicle_model.disk_cache`): the combination,
    the crossover's start, the weights, :data:`DESIGN_SOURCES`, and the numerical libraries' versions and code paths
    (numpy's SIMD paths, scipy, casadi, the machine)."""
    return key_of(
        (
            f"params={exact_text(params)}",
            f"crossover_start={exact_text(float(crossover_start))}",
            f"weights={exact_text(weights)}",
            f"sources={sources_digest(DESIGN_SOURCES)}",
            f"numpy={numpy_runtime()}",
            f"scipy={scipy.__version__}",
            f"casadi={casadi.__version__}",
            f"machine={platform.machine()}",
        )
    )


@functools.lru_cache(maxsize=8)
def _scheduled_gains(
    params: VehicleParams, crossover_start: float, weights: StabilityWeights
) -> tuple[np.ndarray, np.ndarray]:
    """The design speeds and their gains, designed once per combination, crossover and weights (every steered unit's
    controller shares them) and kept on disk in the cache's ``stability`` folder (:func:`schedule_key`); an entry
    whose speeds are not the design speeds or whose gains are not finite of the right shape is designed again."""
    key = schedule_key(params, crossover_start, weights)
    path = entry_path("stability", key)
    stored = None if path is None else read_entry(path, key, ("speeds", "gains"))
    speeds = design_speeds(crossover_start)
    shape = (len(speeds), len(steered_units(params)), len(measured_signals(params)))
    if (
        stored is not None
        and np.array_equal(stored["speeds"], speeds)
        and stored["gains"].shape == shape
        and np.all(np.isfinite(stored["gains"]))
    ):
        gains = stored["gains"].astype(float)
    else:
        speeds, gains = _designed_schedule(params, crossover_start, weights)
        if path is not None:
            write_entry(path, key, {"speeds": speeds, "gains": gains})
    speeds.flags.writeable = False
    gains.flags.writeable = False
    return speeds, gains


class ChainStabilitySteer:
    """The gain-scheduled stability steer of every steered unit of a combination (module docstring).

    Parameters
    ----------
    params
        A combination with at least one steerable towed axle.
    crossover_start
        The crossover's lower speed [m/s], the lowest design speed (below it the command is not used).
    weights
        The cost's weights (:class:`~controller.high_speed.StabilityWeights`).

    Attributes
    ----------
    units : tuple of int
        The steered units (:func:`steered_units`), the rows of the gains.
    speeds : numpy.ndarray
        Design speeds [m/s].
    gains : numpy.ndarray
        ``(len(speeds), len(units), n_measured)`` gains on :func:`measured_signals` [rad/(rad/s), rad/rad].
    """

    def __init__(self, params: VehicleParams, crossover_start: float, weights: StabilityWeights | None = None) -> None:
        self.units = _check_chain(params)
        self.weights = StabilityWeights() if weights is None else weights
        self.speeds, self.gains = _scheduled_gains(params, float(crossover_start), self.weights)

    def gain(self, speed: float) -> np.ndarray:
        """``K(u)``: the designed gains interpolated linearly in speed, held outside the grid."""
        flat = self.gains.reshape(len(self.speeds), -1)
        return np.array([np.interp(speed, self.speeds, column) for column in flat.T]).reshape(self.gains.shape[1:])

    def __call__(self, speed: float, yaw_rates: Sequence[float], articulations: Sequence[float]) -> np.ndarray:
        """The stability steer ``−K(u)·y`` [rad] of each steered unit (rows of :attr:`units`), before its fade.

        Parameters
        ----------
        speed
            Forward speed ``u`` [m/s].
        yaw_rates
            Every unit's gyro ``r1, r2, …`` [rad/s], front to rear.
        articulations
            Every articulation ``Γ1, Γ2, …`` [rad], front to rear.
        """
        return -(self.gain(speed) @ np.array([*yaw_rates, *articulations], dtype=float))
