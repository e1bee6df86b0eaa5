"""The steering environment's reward, and the episode summary that matches ``metrics.json`` of the same run.

Reward, per step, from the **true** off-tracking ``e_k`` of every steered towed unit after the step (each against
its own coupling's path) and the applied commands ``δ_j`` of every steered axle::

    r = −w_e·mean_k min(|e_k|/e_tol, c_max) − w_u·mean_j (δ_j/δ_max)² − w_du·mean_j (Δδ_j/(δ̇_max·Δt))²

For one steered unit (a tractor–semi-trailer) the first term is ``−w_e·min(|e|/e_tol, c_max)`` of its trailer.

``e_tol`` is a tolerance, by default the 0.10 m off-tracking RMS target of the closed loop, so the
first term is the off-tracking in units of that target; it is linear (an absolute error) so that it still
pulls at the millimetre errors a good controller reaches, where a squared error would vanish under the effort
terms. ``c_max`` (default 10, i.e. 1 m) bounds it; a unit's term is 0 during its first trailer length, before
``e_k`` exists, and every unit's is ``c_max`` when the model diverges. With the default weights
(:data:`REWARD_WEIGHTS`) and the designed PID on the default scenario (about 1.3 mm mean ``|e|``, 4.7° largest
steer) the off-tracking term is about 99 % of the return; a policy whose steer chatters at the full rate limit
pays 0.01 per step, what 1 mm of off-tracking costs.

On termination the agent is also charged the worst per-step cost ``w_e·c_max + w_u + w_du`` for every control
period left to the end of the path at the target speed, plus ``termination_penalty``, so ending an episode
early never pays.

The summary (:func:`episode_summary`) is computed by :func:`scenarios.run.metrics.compute_metrics` from the
episode's recorded rows (the co-simulation records every tick as ``offtrack run`` does), the function that writes
``metrics.json``, so its figures equal that file's for the same run (``offtrack run`` of the configuration in
``info["config"]``, steered the same way).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from vehicle_model.errors import InputError

from ..loop.cosimulation import CoSimulation
from ..loop.ends import StopReason
from ..run.metrics import compute_metrics

__all__ = ["OFFTRACKING_TOLERANCE", "REWARD_WEIGHTS", "SteeringReward", "episode_summary"]

REWARD_WEIGHTS: dict[str, float] = {"offtracking": 1.0, "effort": 0.01, "rate": 0.01}
"""Default weights ``w_e``, ``w_u``, ``w_du`` of the per-step cost terms."""

OFFTRACKING_TOLERANCE = 0.10
"""Default ``e_tol`` [m]: the closed loop's off-tracking RMS target."""

OFFTRACKING_CLIP = 10.0
"""Default ``c_max``: the off-tracking term saturates at ``c_max·e_tol`` (1 m by default)."""


@dataclass(frozen=True)
class SteeringReward:
    """Weights and scales of the reward (module docstring).

    Parameters
    ----------
    weights : mapping
        ``offtracking``, ``effort``, ``rate`` (missing keys: :data:`REWARD_WEIGHTS`).
    tolerance : float
        ``e_tol`` [m].
    clip : float
        ``c_max`` [-].
    termination_penalty : float
        Charged once on termination.
    """

    weights: Mapping[str, float] = field(default_factory=lambda: dict(REWARD_WEIGHTS))
    tolerance: float = OFFTRACKING_TOLERANCE
    clip: float = OFFTRACKING_CLIP
    termination_penalty: float = 10.0

    def __post_init__(self) -> None:
        weights = {**REWARD_WEIGHTS, **dict(self.weights or {})}
        if set(weights) != set(REWARD_WEIGHTS) or not all(
            isinstance(w, int | float) and w >= 0 and math.isfinite(w) for w in weights.values()
        ):
            raise InputError(f"reward_weights = {self.weights!r}: non-negative values for {list(REWARD_WEIGHTS)}")
        object.__setattr__(self, "weights", weights)
        if not (self.tolerance > 0 and math.isfinite(self.tolerance)):
            raise InputError(f"offtracking_tolerance = {self.tolerance!r} must be a finite number > 0 [m]")
        if not (self.clip > 0 and math.isfinite(self.clip)):
            raise InputError(f"offtracking_clip = {self.clip!r} must be a finite number > 0")
        if not (self.termination_penalty >= 0 and math.isfinite(self.termination_penalty)):
            raise InputError(f"termination_penalty = {self.termination_penalty!r} must be a finite number ≥ 0")

    def parts(
        self,
        cosim: CoSimulation,
        commands: np.ndarray,
        previous: np.ndarray,
        max_steer: float,
        max_rate: float,
        reason: str,
        truths: Sequence[str] = ("truth",),
    ) -> dict[str, float]:
        """The reward's parts for one step (``reward_offtracking``, ``_effort``, ``_rate``, ``_termination``).

        Parameters
        ----------
        cosim
            After the step.
        commands, previous
            Axle commands applied in this step and in the one before [rad].
        max_steer, max_rate
            ``δ_max`` [rad] and ``δ̇_max`` [rad/s].
        reason
            Why the step terminated the episode (``""``: it did not).
        truths
            The keys of the steered units' true off-tracking among the tick's estimates (``truth`` for the first
            towed unit, ``truth3`` for the one behind it, …: :func:`scenarios.unit_feedback.estimate_key`); the
            off-tracking term is the mean of their clipped, normalised magnitudes.
        """
        w = self.weights
        tick = cosim.tick
        if reason == StopReason.DIVERGED:
            offtracking = self.clip
        else:
            terms = []
            for key in truths:
                truth = tick.estimates[key]
                terms.append(min(abs(truth.value) / self.tolerance, self.clip) if truth.available else 0.0)
            offtracking = sum(terms) / len(terms)
        effort = float(np.mean((commands / max_steer) ** 2))
        rate = float(np.mean(((commands - previous) / (max_rate * cosim.period)) ** 2))
        termination = 0.0
        if reason:
            remaining = max(cosim.setup.path.length - cosim.driver.progress, 0.0)
            steps_left = remaining / max(tick.speed_target, 0.5) / cosim.period
            worst = w["offtracking"] * self.clip + w["effort"] + w["rate"]
            termination = -(worst * steps_left + self.termination_penalty)
        return {
            "reward_offtracking": -w["offtracking"] * offtracking,
            "reward_effort": -w["effort"] * effort,
            "reward_rate": -w["rate"] * rate,
            "reward_termination": termination,
        }


def episode_summary(
    cosim: CoSimulation, termination_reason: str, returns: Mapping[str, float], steps: int
) -> dict[str, Any]:
    """An ended episode in figures, as ``metrics.json`` gives them (module docstring).

    Parameters
    ----------
    cosim
        The episode's co-simulation after :meth:`~scenarios.loop.cosimulation.CoSimulation.finish`.
    termination_reason
        Why it terminated (``""``: it reached its end).
    returns
        The sum of every reward part over the episode (``reward_offtracking``, …).
    steps
        Steps taken.

    Returns
    -------
    dict
        ``rms_offtracking`` and ``max_offtracking`` (true, after warm-up [m]: ``offtracking.truth_after_warmup``
        of ``metrics.json``; NaN when the episode ended during warm-up), ``rms_offtracking_all`` and
        ``max_offtracking_all`` (``offtracking.truth``), ``saturated_fraction`` (largest of the axles'
        ``trailer_steering.<axle>.saturated_fraction``) and ``trailer_steering`` (per axle),
        ``termination_reason`` (``""``: the episode reached its end), ``steps``, ``simulated_s``, ``return`` and
        the sum of every reward part (``return_offtracking``, …). The off-tracking figures are the first towed
        unit's; for a longer combination ``units`` holds, by the number of each unit behind it (``"3"``, ``"4"``),
        its own ``rms_offtracking``, ``max_offtracking`` (after the first towed unit's warm-up, once the unit's own
        exists), ``rms_offtracking_all`` and ``max_offtracking_all`` (``offtracking.units`` of ``metrics.json``).
    """
    setup = cosim.setup
    columns = cosim.recorder.arrays()
    metrics = compute_metrics(setup.config.name, setup.config.feedback, setup.params, columns, [], None, (0.0, 0.0))
    truth, settled = metrics["offtracking"]["truth"], metrics["offtracking"]["truth_after_warmup"]
    steering = metrics["trailer_steering"]
    further = metrics["offtracking"].get("units")
    units = (
        {
            "units": {
                unit: {
                    "rms_offtracking": u["rms_after_warmup"],
                    "max_offtracking": u["max_abs_after_warmup"],
                    "rms_offtracking_all": u["rms"],
                    "max_offtracking_all": u["max_abs"],
                }
                for unit, u in further.items()
            }
        }
        if further
        else {}
    )
    return {
        "rms_offtracking": settled["rms"],
        "max_offtracking": settled["max_abs"],
        "rms_offtracking_all": truth["rms"],
        "max_offtracking_all": truth["max_abs"],
        "saturated_fraction": max((a["saturated_fraction"] for a in steering.values()), default=0.0),
        "trailer_steering": steering,
        "termination_reason": termination_reason,
        "steps": steps,
        "simulated_s": float(columns["time"][-1]),
        "return": float(sum(returns.values())),
        **{k.replace("reward_", "return_"): float(v) for k, v in returns.items()},
        **units,
    }
