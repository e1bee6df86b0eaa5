"""The continued search of the multi-unit stability steer's gains, where the search from ``K = 0`` stalls.

:func:`controller.high_speed_chain.design_chain_gain` searches each design speed from ``K = 0`` with the closed
loops outside the admissible pole region costed as unstable. Where the unsteered combination's least damped pole
lies close to the damping floor (the steered A-double at speed; docs/controller_design.md §3.5, *The stability mode on
the A-double*, gives the figures of every part below) every descent direction
leaves the region within a step and that search ends at or near ``K = 0``. :func:`continued_schedule` designs the
whole schedule instead:

* **Continuation over speed.** The design speeds are designed in turn from the crossover upward, each search
  started from the gain of the speed below (halved until its closed loop lies in the region at the new speed;
  ``K = 0`` lies in it), so that neighbouring gains lie on one branch of the cost's minima and the linear
  interpolation between them is a gain of that branch too.
* **A logarithmic barrier** in place of the hard penalty (an interior-point method: Boyd & Vandenberghe, *Convex
  Optimization*, 2004, §11.2): the search minimises ``J(K) − μ·J(0)·Σ log m_i(K)`` with quasi-Newton steps (BFGS,
  numerical gradient) for ``μ`` = :data:`BARRIER_WEIGHTS` in turn, each from the last one's gain, where ``m_i`` are
  the margins of every closed-loop pole from the region's boundary (:func:`pole_margins`). The barrier grows as a
  pole nears the boundary, so the line search can approach the floor instead of falling off a cliff.
* **A gain-norm guard** ``J(0)·‖K‖²/K_g²`` (:data:`GAIN_SCALE`) added to the cost: the H2 cost is nearly flat
  along gain directions the tractor's steer barely excites, and without the guard the search at the lower design
  speeds ends on large gains whose interpolation between design speeds is unstable; at the norms the search from
  ``K = 0`` finds it costs a few per cent of ``J(0)``.
* **The region** (Chilali & Gahinet 1996, IEEE Trans. Automatic Control 41(3): a conic sector intersected with a
  shifted half-plane) holds every pole's damping ratio at least the plant's floor
  (:attr:`~controller.high_speed_chain.ChainPlant.min_damping`) and its decay rate at least
  :data:`MIN_DECAY_RATE`, for the design plant's actuator lag and for an actuator without lag. Without the
  decay floor the H2 optimum has real poles near the origin that the disturbance barely excites (a slow crab of
  the combination, steers held against articulations); without the lag-free loop it has gains that only the
  design's actuator lag stabilises, while the simulated actuator follows its command within a tick.

:func:`schedule_admissible` checks a schedule between its design speeds, where the controller interpolates it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import scipy.optimize

from .high_speed import UNSTABLE_COST

__all__ = [
    "BARRIER_WEIGHTS",
    "GAIN_SCALE",
    "MIN_DECAY_RATE",
    "continued_schedule",
    "pole_margins",
    "schedule_admissible",
]

BARRIER_WEIGHTS = (0.1, 0.01, 0.001)
"""The barrier's weights ``μ`` [share of the unsteered cost], in turn (module docstring)."""

MIN_DECAY_RATE = 0.5
"""Decay rate [1/s] every closed-loop pole of a continued design must reach (a 2 s time constant, slower than the
unsteered combinations' slowest poles over the design speeds, so that ``K = 0`` stays admissible)."""

GAIN_SCALE = 10.0
"""``K_g`` of the gain-norm guard ``J(0)·‖K‖²/K_g²`` [rad per rad/s, rad per rad] added to the continued search's
cost (module docstring)."""

Cost = Callable[[np.ndarray, Any, Any], float]


def _poles(gain: np.ndarray, plant: Any) -> np.ndarray:
    """The poles of the closed loop with the design plant's actuator lag and of the one without it (``δ_s = δ_c``)."""
    k = np.asarray(gain, dtype=float).reshape(plant.b_c.shape[1], plant.c_y.shape[0])
    lagged = np.linalg.eigvals(plant.a + plant.b_c @ (-k @ plant.c_y))
    m = plant.a.shape[0] - plant.b_c.shape[1]  # the lateral states and the tractor's steer
    lag_free = np.linalg.eigvals(plant.a[:m, :m] + plant.a[:m, m:] @ (-k @ plant.c_y[:, :m]))
    return np.concatenate([lagged, lag_free])


def pole_margins(gain: np.ndarray, plant: Any) -> np.ndarray:
    """Every closed-loop pole's margins from the region's boundary (module docstring), each in ``(−∞, 1]``.

    ``(ζ − ζ_min)/(1 − ζ_min)`` of the damping ratio ``ζ`` and ``min(1, (σ − σ_min)/σ_min)`` of the decay rate
    ``σ = −Re λ`` (``σ_min`` = :data:`MIN_DECAY_RATE`), of both closed loops (with and without the actuator lag);
    the gain is admissible when all are positive.

    Parameters
    ----------
    gain
        ``K``, ``(n_steered, n_measured)`` or flattened row by row: ``δ_c = −K y``.
    plant
        The design plant (:class:`~controller.high_speed_chain.ChainPlant`).

    Returns
    -------
    numpy.ndarray
        The damping margins of every pole of both loops, then their decay margins.
    """
    poles = _poles(gain, plant)
    damping = -poles.real / np.maximum(np.abs(poles), 1e-12)
    decay = np.minimum(1.0, (-poles.real - MIN_DECAY_RATE) / MIN_DECAY_RATE)
    return np.concatenate([(damping - plant.min_damping) / (1.0 - plant.min_damping), decay])


def _barrier_cost(gain: np.ndarray, plant: Any, weights: Any, cost: Cost, unsteered: float, mu: float) -> float:
    margins = pole_margins(gain, plant)
    if np.any(margins <= 0.0):
        return UNSTABLE_COST
    value = cost(gain, plant, weights)
    if value >= UNSTABLE_COST:
        return value
    guard = float(np.sum(np.square(gain))) / GAIN_SCALE**2
    return value + unsteered * (guard - mu * float(np.sum(np.log(margins))))


def continued_schedule(plants: Sequence[Any], cost: Cost, weights: Any) -> np.ndarray:
    """The gains of every design speed by continuation from the lowest speed (module docstring).

    Parameters
    ----------
    plants
        The design plants (:class:`~controller.high_speed_chain.ChainPlant`), by rising speed.
    cost
        The design cost ``cost(gain, plant, weights)`` (:func:`~controller.high_speed_chain.chain_h2_cost`).
    weights
        Its weights.

    Returns
    -------
    numpy.ndarray
        ``(len(plants), n_steered, n_measured)``; a speed's gain is ``K = 0`` where the search ends on a cost no
        lower than the unsteered combination's.
    """
    gains = []
    shape = (plants[0].b_c.shape[1], plants[0].c_y.shape[0])
    start = np.zeros(shape[0] * shape[1])
    for plant in plants:
        unsteered = cost(np.zeros_like(start), plant, weights)
        while np.any(pole_margins(start, plant) <= 0.0):  # K = 0 is admissible: the halving ends
            start = 0.5 * start if np.linalg.norm(start) > 1e-3 else np.zeros_like(start)
        for mu in BARRIER_WEIGHTS:
            args = (plant, weights, cost, unsteered, mu)
            start = np.asarray(scipy.optimize.minimize(_barrier_cost, start, args=args, method="BFGS").x)
        if not cost(start, plant, weights) < unsteered:
            start = np.zeros_like(start)
        gains.append(start.reshape(shape))
    return np.array(gains)


def schedule_admissible(speeds: np.ndarray, gains: np.ndarray, plant_at: Callable[[float], Any]) -> bool:
    """Whether the schedule's gain, interpolated linearly in speed, keeps the closed loops in the region (module
    docstring) at every design speed and halfway between neighbouring ones.

    Parameters
    ----------
    speeds
        Design speeds [m/s], rising.
    gains
        ``(len(speeds), n_steered, n_measured)``.
    plant_at
        The design plant at a speed [m/s].
    """
    flat = gains.reshape(len(speeds), -1)
    halfway = 0.5 * (speeds[1:] + speeds[:-1])
    for speed in np.sort(np.concatenate([speeds, halfway])):
        gain = np.array([np.interp(speed, speeds, column) for column in flat.T])
        if np.any(pole_margins(gain, plant_at(float(speed))) <= 0.0):
            return False
    return True
