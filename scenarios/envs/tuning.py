"""Tune the trailer path-following PID gains through ``offtrack/GainTuning-v0`` with Optuna (``offtrack tune``).

The objective is the mean cost of the gain-tuning environment over a fixed set of training draws of the
domain randomisation (common random numbers: every trial sees the same draws, so trials compare fairly);
Optuna's TPE sampler proposes the normalised, log-scaled actions and starts from the designed gains
(:func:`controller.gain_design.design_gains`, the controller's defaults). The tuned and the designed gains are
then compared on held-out conditions that the training ranges do not cover.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from controller.gain_design import design_gains
from controller.path_following_config import PathFollowingGains
from vehicle_model.errors import InputError

from ..extras import require
from . import register_envs
from .gain_tuning_env import GAIN_RANGES, GainTuningEnv, action_to_gains, gains_to_action

__all__ = ["HELD_OUT", "TRAIN_RANDOMISATION", "TuningResult", "TuningStopped", "tune_gains"]


class TuningStopped(Exception):
    """Ctrl-C or SIGTERM stopped :func:`tune_gains`; raised from the stop (its ``__cause__``).

    Attributes
    ----------
    trial_rows : list of dict
        The trials finished before the stop, as :attr:`TuningResult.trial_rows`.
    """

    def __init__(self, trial_rows: list[dict[str, Any]]) -> None:
        super().__init__(f"tuning stopped after {len(trial_rows)} finished trial(s)")
        self.trial_rows = trial_rows


TRAIN_RANDOMISATION: dict[str, Any] = {
    "mu": (0.4, 0.8),
    "camber_percent": (0.0, 3.0),
    "camber_direction": ("outward", "inward"),
    "speed_kmh": (12.0, 18.0),
    "vehicle": ("lst", "lst-unladen"),
    "direction": ("left", "right"),
}
"""Training ranges: wet to dry roads, up to 3 % camber either way, 12–18 km/h, laden or unladen."""

HELD_OUT: dict[str, dict[str, Any]] = {
    "snow (μ 0.25), 5 % adverse camber, laden": {
        "mu": 0.25,
        "camber_percent": 5.0,
        "camber_direction": "outward",
        "speed_kmh": 15.0,
        "vehicle": "lst",
        "direction": "left",
    },
    "μ 0.3, 4 % inward camber, unladen, 20 km/h, right": {
        "mu": 0.3,
        "camber_percent": 4.0,
        "camber_direction": "inward",
        "speed_kmh": 20.0,
        "vehicle": "lst-unladen",
        "direction": "right",
    },
    "ice (μ 0.10), 5 % adverse camber, laden": {
        "mu": 0.10,
        "camber_percent": 5.0,
        "camber_direction": "outward",
        "speed_kmh": 15.0,
        "vehicle": "lst",
        "direction": "left",
    },
}
"""Held-out conditions, all outside the training ranges (lower friction, more camber, faster). The last is at
the friction limit (the paper's worst case): there, gains tuned on grippier roads saturate the axles and do
worse than the designed ones — the table shows where the tuning stops being valid."""


@dataclass
class TuningResult:
    """What :func:`tune_gains` found.

    Attributes
    ----------
    designed, tuned : PathFollowingGains
        The designed (default) gains and the best gains found.
    train_cost_designed, train_cost_tuned : float
        Mean training cost of each.
    held_out : list of dict
        One row per held-out condition: ``condition``, and for ``designed`` and ``tuned`` the cost, RMS and
        largest true off-tracking after warm-up [m], saturated fraction and status.
    trials : int
        Optimiser trials run.
    trial_rows : list of dict
        One row per trial: ``trial`` (0 is the designed gains), ``kp`` [rad/m], ``ki`` [rad/m²], ``kd`` [rad],
        ``train_cost`` (mean over the draws; missing for a trial that did not finish) and ``state``.
    evaluations : int
        Scenario runs in all.
    wall_s : float
        Wall-clock time [s].
    """

    designed: PathFollowingGains
    tuned: PathFollowingGains
    train_cost_designed: float
    train_cost_tuned: float
    held_out: list[dict[str, Any]] = field(default_factory=list)
    trials: int = 0
    trial_rows: list[dict[str, Any]] = field(default_factory=list)
    evaluations: int = 0
    wall_s: float = 0.0

    def table(self) -> str:
        """The before/after comparison as a Markdown table."""
        lines = [
            f"gains: designed kp {self.designed.kp:.4f} rad/m, ki {self.designed.ki:.4f} rad/m², "
            f"kd {self.designed.kd:.4f} rad → tuned kp {self.tuned.kp:.4f}, ki {self.tuned.ki:.4f}, "
            f"kd {self.tuned.kd:.4f}",
            f"training cost (mean of the draws): designed {self.train_cost_designed:.5f}, "
            f"tuned {self.train_cost_tuned:.5f}",
            "",
            "| held-out condition | gains | RMS e_tr [mm] | max e_tr [mm] | saturated | cost | status |",
            "|---|---|---:|---:|---:|---:|---|",
        ]
        for row in self.held_out:
            for which in ("designed", "tuned"):
                r = row[which]
                lines.append(
                    f"| {row['condition']} | {which} | {1e3 * r['rms_offtracking']:.2f} | "
                    f"{1e3 * r['max_offtracking']:.2f} | {r['saturated_fraction']:.1%} | {r['cost']:.5f} | "
                    f"{r['status']} |"
                )
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Everything as plain values (one JSON object)."""
        return {
            "designed": {"kp": self.designed.kp, "ki": self.designed.ki, "kd": self.designed.kd},
            "tuned": {"kp": self.tuned.kp, "ki": self.tuned.ki, "kd": self.tuned.kd},
            "train_cost_designed": self.train_cost_designed,
            "train_cost_tuned": self.train_cost_tuned,
            "held_out": self.held_out,
            "tuned_better": self.verdicts(),
            "trials": self.trials,
            "trial_rows": self.trial_rows,
            "evaluations": self.evaluations,
            "wall_s": self.wall_s,
        }

    def verdicts(self) -> dict[str, bool]:
        """Per held-out condition: the tuned gains cost less than the designed ones."""
        return {row["condition"]: row["tuned"]["cost"] < row["designed"]["cost"] for row in self.held_out}


def _figures(info: dict[str, Any]) -> dict[str, Any]:
    keys = ("cost", "rms_offtracking", "max_offtracking", "saturated_fraction", "status")
    return {k: info[k] for k in keys}


def tune_gains(
    n_trials: int = 30,
    train_draws: int = 3,
    seed: int = 0,
    randomise: Mapping[str, Any] | None = None,
    held_out: Mapping[str, Mapping[str, Any]] | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    progress: Callable[[int, int, float], None] | None = None,
) -> TuningResult:
    """Tune ``(kp, ki, kd)`` on randomised training draws and compare with the designed gains on held-out ones.

    Parameters
    ----------
    n_trials
        Optuna trials (the first evaluates the designed gains).
    train_draws
        Domain draws per trial (the same ``train_draws`` draws for every trial).
    seed
        Seeds the draws (``reset(seed=seed + k)``) and the sampler.
    randomise
        Training ranges (default :data:`TRAIN_RANDOMISATION`).
    held_out
        Held-out conditions by label, as ``reset`` options (default :data:`HELD_OUT`).
    env_kwargs
        Further ``offtrack/GainTuning-v0`` arguments (scenario, feedback, weights, …).
    progress
        Called after every trial with ``(trials done, n_trials, best cost so far)``.

    Returns
    -------
    TuningResult

    Raises
    ------
    InputError
        Bad budget, Optuna is not installed, or the combination steers more than one towed unit (the designed
        gains it starts from and compares with are the first towed unit's).
    TuningStopped
        Ctrl-C or SIGTERM: the trials finished so far, raised from the stop.
    """
    if n_trials < 1 or train_draws < 1:
        raise InputError("tune_gains needs n_trials ≥ 1 and train_draws ≥ 1")
    optuna = require("optuna", "tune", "tuning the gains")
    register_envs()
    t0 = time.perf_counter()
    kwargs = {"randomise": TRAIN_RANDOMISATION if randomise is None else dict(randomise), **(env_kwargs or {})}
    env = gym.make("offtrack/GainTuning-v0", **kwargs)
    tuning_env: GainTuningEnv = env.unwrapped  # type: ignore[assignment]
    if tuning_env.n_steered != 1:
        env.close()
        raise InputError(
            f"env_kwargs: tune_gains tunes one steered unit (its designed gains are the first towed unit's); this "
            f"combination steers {tuning_env.n_steered} ({tuning_env.units.describe()}): use offtrack/GainTuning-v0 "
            "with your own optimiser"
        )
    evaluations = 0

    def train_cost(action: np.ndarray) -> float:
        nonlocal evaluations
        costs = []
        for k in range(train_draws):
            env.reset(seed=seed + k)
            _, reward, *_ = env.step(action)
            costs.append(-float(reward))
            evaluations += 1
        return float(np.mean(costs))

    env.reset(seed=seed)
    setup = tuning_env._setup
    assert setup is not None
    designed = design_gains(setup.params, setup.speed_profile.cornering).gains
    names = list(GAIN_RANGES)

    stops: list[KeyboardInterrupt] = []

    def objective(trial: optuna.Trial) -> float:
        action = np.array([trial.suggest_float(name, -1.0, 1.0) for name in names], dtype=np.float32)
        try:
            return train_cost(action)
        except KeyboardInterrupt as stop:  # Optuna would log it with a traceback: end the study quietly instead
            stops.append(stop)
            trial.study.stop()
            raise optuna.TrialPruned() from None

    def finished_rows(study: optuna.Study) -> list[dict[str, Any]]:
        rows = []
        for trial in study.trials:
            gains = action_to_gains(np.array([trial.params[n] for n in names], dtype=np.float32))
            cost = None if trial.value is None else float(trial.value)
            row = {"trial": trial.number, "kp": gains.kp, "ki": gains.ki, "kd": gains.kd, "train_cost": cost}
            rows.append({**row, "state": trial.state.name.lower()})
        return [row for row in rows if row["state"] == "complete"] if stops else rows

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="minimize", sampler=optuna.samplers.TPESampler(seed=seed))
    study.enqueue_trial(dict(zip(names, map(float, gains_to_action(designed)), strict=True)))
    callbacks = []
    if progress is not None:
        callbacks.append(lambda s, t: progress(len(s.trials), n_trials, float(s.best_value)))
    try:
        study.optimize(objective, n_trials=n_trials, callbacks=callbacks)
    except KeyboardInterrupt as stop:  # between trials (the sampler, a callback)
        stops.append(stop)
    if stops:
        env.close()
        raise TuningStopped(finished_rows(study)) from stops[0]
    best_action = np.array([study.best_params[n] for n in names], dtype=np.float32)
    tuned = action_to_gains(best_action)

    def mean_train(gains: PathFollowingGains) -> float:
        nonlocal evaluations
        costs = []
        for k in range(train_draws):
            env.reset(seed=seed + k)
            costs.append(tuning_env.evaluate(gains)[0])
            evaluations += 1
        return float(np.mean(costs))

    try:
        result = TuningResult(designed, tuned, mean_train(designed), mean_train(tuned), trials=len(study.trials))
        result.trial_rows.extend(finished_rows(study))
        for label, options in (HELD_OUT if held_out is None else held_out).items():
            env.reset(seed=seed + 10_000, options={**options, "randomise": None})
            row = {"condition": label}
            for which, gains in (("designed", designed), ("tuned", tuned)):
                row[which] = _figures(tuning_env.evaluate(gains)[1])
                evaluations += 1
            result.held_out.append(row)
    except KeyboardInterrupt as stop:  # in the comparison: every trial is finished
        env.close()
        raise TuningStopped(finished_rows(study)) from stop
    env.close()
    result.evaluations = evaluations
    result.wall_s = time.perf_counter() - t0
    return result
