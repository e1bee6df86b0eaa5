"""Tune the trailer path-following PID gains through ``offtrack/GainTuning-v0`` with Optuna (``offtrack tune``).

Any combination with steered towed units is tuned, one ``(kp, ki, kd)`` per steered unit. The objective is the
mean cost of the gain-tuning environment over a fixed set of training draws of the domain randomisation (common
random numbers: every trial sees the same draws, so trials compare fairly). Trial 0 is the designed gains, the
ones a run uses when its scenario gives none (each unit's pole placement,
:func:`~scenarios.envs.gain_tuning_env.configured_unit_gains`), evaluated as they are (``kd = 0`` included, which
the log-scaled action cannot express); Optuna's TPE sampler then proposes normalised, log-scaled actions. The
tuned and the designed gains are compared on held-out conditions that the training ranges do not cover, and the
tuned gains are advised only when they are no worse on every one of them (:meth:`TuningResult.advice`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from controller.path_following_config import PathFollowingGains
from vehicle_model.errors import InputError

from ..extras import require
from . import register_envs
from .gain_tuning_env import GAIN_RANGES, GainTuningEnv, action_to_unit_gains, configured_unit_gains, gains_to_action
from .tuning_conditions import (
    HELD_OUT,
    TRAIN_RANDOMISATION,
    held_out_conditions,
    training_randomisation,
    training_vehicles,
)

__all__ = [
    "HELD_OUT",
    "TRAIN_RANDOMISATION",
    "TuningResult",
    "TuningStopped",
    "held_out_conditions",
    "parameter_names",
    "training_randomisation",
    "training_vehicles",
    "tune_gains",
]


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


GAIN_NAMES: tuple[str, ...] = tuple(GAIN_RANGES)


def _gain_sets(gains: PathFollowingGains | Sequence[PathFollowingGains]) -> tuple[PathFollowingGains, ...]:
    return (gains,) if isinstance(gains, PathFollowingGains) else tuple(gains)


@dataclass
class TuningResult:
    """What :func:`tune_gains` found.

    Attributes
    ----------
    designed, tuned : tuple of PathFollowingGains
        Per steered towed unit, front to rear: the designed gains (a run's own when its scenario gives none,
        exactly) and the best gains found (the designed ones when no trial beat them). A single set is taken as
        a one-unit combination's.
    train_cost_designed, train_cost_tuned : float
        Mean training cost of each.
    held_out : list of dict
        One row per held-out condition: ``condition``, and for ``designed`` and ``tuned`` the cost, RMS and
        largest true off-tracking of the first towed unit after warm-up [m] (of each unit ``k`` behind it as
        ``unit<k>_rms_offtracking``, …), saturated fraction and status.
    trials : int
        Trials run (trial 0 is the designed gains).
    trial_rows : list of dict
        One row per trial: ``trial`` (0 is the designed gains), the gains ``kp`` [rad/m], ``ki`` [rad/m²], ``kd``
        [rad] (of more than one steered unit, each unit ``k``'s as ``unit<k>_kp``, …; :func:`parameter_names`),
        ``train_cost`` (mean over the draws; missing for a trial that did not finish) and ``state``.
    evaluations : int
        Scenario runs in all.
    wall_s : float
        Wall-clock time [s].
    units : tuple of int
        The steered towed units, as the combination numbers them (2 the first towed unit).
    vehicle : str
        The vehicle tuned (catalogue name or file).
    """

    designed: tuple[PathFollowingGains, ...]
    tuned: tuple[PathFollowingGains, ...]
    train_cost_designed: float
    train_cost_tuned: float
    held_out: list[dict[str, Any]] = field(default_factory=list)
    trials: int = 0
    trial_rows: list[dict[str, Any]] = field(default_factory=list)
    evaluations: int = 0
    wall_s: float = 0.0
    units: tuple[int, ...] = ()
    vehicle: str = "lst"

    def __post_init__(self) -> None:
        self.designed = _gain_sets(self.designed)
        self.tuned = _gain_sets(self.tuned)
        if len(self.designed) != len(self.tuned):
            raise InputError(f"designed and tuned gains: {len(self.designed)} and {len(self.tuned)} units differ")
        self.units = tuple(self.units) or tuple(range(2, 2 + len(self.designed)))
        if len(self.units) != len(self.designed):
            raise InputError(f"units = {self.units!r}: one per gain set ({len(self.designed)})")

    def table(self) -> str:
        """The gains, the held-out comparison (a Markdown table) and the advice."""
        lines = []
        for unit, designed, tuned in zip(self.units, self.designed, self.tuned, strict=True):
            lines.append(
                f"unit {unit} gains: designed kp {designed.kp!r} rad/m, ki {designed.ki!r} rad/m², kd {designed.kd!r} "
                f"rad → tuned kp {tuned.kp:.4f}, ki {tuned.ki:.4f}, kd {tuned.kd:.4f}"
            )
        lines += [
            f"training cost (mean of the draws): designed {self.train_cost_designed:.5f}, "
            f"tuned {self.train_cost_tuned:.5f}",
            "",
            "| held-out condition | gains | RMS e_tr [mm] | max e_tr [mm] | "
            + "".join(f"RMS e unit {k} [mm] | " for k in self.further_units())
            + "saturated | cost | status |",
            "|---|---|---:|---:|" + "---:|" * len(self.further_units()) + "---:|---:|---|",
        ]
        for row in self.held_out:
            for which in ("designed", "tuned"):
                r = row[which]
                further = "".join(f"{_milli(r.get(f'unit{k}_rms_offtracking'))} | " for k in self.further_units())
                lines.append(
                    f"| {row['condition']} | {which} | {_milli(r['rms_offtracking'])} | "
                    f"{_milli(r['max_offtracking'])} | {further}{_percent(r['saturated_fraction'])} | "
                    f"{_cost(r['cost'])} | {r['status']} |"
                )
        return "\n".join([*lines, "", *self.advice()])

    def further_units(self) -> list[int]:
        """The units behind the first towed one whose held-out figures the rows hold (as the combination numbers
        them)."""
        found = {
            int(key.removeprefix("unit").removesuffix("_rms_offtracking"))
            for row in self.held_out
            for which in ("designed", "tuned")
            for key in row[which]
            if key.startswith("unit") and key.endswith("_rms_offtracking")
        }
        return sorted(found)

    def to_dict(self) -> dict[str, Any]:
        """Everything as plain values (one JSON object)."""
        return {
            "vehicle": self.vehicle,
            "units": list(self.units),
            "designed": [_plain(g) for g in self.designed],
            "tuned": [_plain(g) for g in self.tuned],
            "train_cost_designed": self.train_cost_designed,
            "train_cost_tuned": self.train_cost_tuned,
            "held_out": self.held_out,
            "better": self.verdicts(),
            "apply_tuned": self.apply_tuned(),
            "advice": self.advice()[-1],
            "trials": self.trials,
            "trial_rows": self.trial_rows,
            "evaluations": self.evaluations,
            "wall_s": self.wall_s,
        }

    def verdicts(self) -> dict[str, str]:
        """Per held-out condition, the gains with the lower cost: ``tuned``, ``designed`` or ``equal``.

        A run that did not complete (or has no cost) loses to one that did; two such are ``equal``.
        """

        def cost(figures: Mapping[str, Any]) -> float:
            value = figures.get("cost")
            ok = figures.get("status") == "completed" and isinstance(value, int | float) and math.isfinite(value)
            return float(value) if ok else math.inf

        out = {}
        for row in self.held_out:
            designed, tuned = cost(row["designed"]), cost(row["tuned"])
            out[row["condition"]] = "equal" if tuned == designed else "tuned" if tuned < designed else "designed"
        return out

    def tuned_differs(self) -> bool:
        """Whether the tuning found gains other than the designed ones."""
        return self.tuned != self.designed

    def apply_tuned(self) -> bool:
        """Whether the held-out roads support the tuned gains: they differ from the designed ones and are no worse
        on any held-out condition (with no held-out condition there is no support)."""
        verdicts = self.verdicts()
        return self.tuned_differs() and bool(verdicts) and "designed" not in verdicts.values()

    def advice(self) -> list[str]:
        """What the held-out roads support, in words: a line per condition, then the advice."""
        lines = [f"{condition}: {_VERDICT_WORDS[better]}" for condition, better in self.verdicts().items()]
        if not self.tuned_differs():
            lines.append("advice: keep the designed gains (no trial beat them on the training draws)")
        elif self.apply_tuned():
            lines.append("advice: apply the tuned gains (no worse than the designed ones on every held-out condition)")
        else:
            worse = [c for c, better in self.verdicts().items() if better == "designed"] or ["(none held out)"]
            lines.append(f"advice: keep the designed gains (the tuned ones are worse on {'; '.join(worse)})")
        return lines


_VERDICT_WORDS = {"tuned": "tuned gains better", "designed": "designed gains better", "equal": "equal"}


def _plain(gains: PathFollowingGains) -> dict[str, float]:
    return {name: float(getattr(gains, name)) for name in GAIN_NAMES}


def _number(value: Any) -> float | None:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    return float(value) if ok else None


def _milli(value: Any) -> str:
    x = _number(value)
    return "—" if x is None else f"{1e3 * x:.2f}"


def _percent(value: Any) -> str:
    x = _number(value)
    return "—" if x is None else f"{x:.1%}"


def _cost(value: Any) -> str:
    x = _number(value)
    return "—" if x is None else f"{x:.5f}"


def parameter_names(units: Sequence[int]) -> list[str]:
    """The trial parameters: ``kp``, ``ki``, ``kd`` of a single steered unit; of more, ``unit<k>_kp``, … of each
    steered unit ``k`` (as the combination numbers them: 2 the first towed unit)."""
    if len(units) == 1:
        return list(GAIN_NAMES)
    return [f"unit{unit}_{name}" for unit in units for name in GAIN_NAMES]


def _figures(info: dict[str, Any]) -> dict[str, Any]:
    """A held-out run's figures: the first towed unit's, then ``unit<k>_rms_offtracking`` and
    ``unit<k>_max_offtracking`` [m] of each unit ``k`` behind it."""
    keys = ("cost", "rms_offtracking", "max_offtracking", "saturated_fraction", "status")
    out = {k: info[k] for k in keys}
    for unit, figures in info.get("units", {}).items():
        out.update({f"unit{unit}_{k}": figures[k] for k in ("rms_offtracking", "max_offtracking")})
    return out


def tune_gains(
    n_trials: int = 30,
    train_draws: int = 3,
    seed: int = 0,
    randomise: Mapping[str, Any] | None = None,
    held_out: Mapping[str, Mapping[str, Any]] | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    progress: Callable[[int, int, float], None] | None = None,
    vehicle: str = "lst",
) -> TuningResult:
    """Tune ``(kp, ki, kd)`` of every steered unit on randomised training draws; compare on held-out ones.

    Parameters
    ----------
    n_trials
        Trials: the first evaluates the designed gains as they are, the others Optuna's proposals.
    train_draws
        Domain draws per trial (the same ``train_draws`` draws for every trial).
    seed
        Seeds the draws (``reset(seed=seed + k)``) and the sampler.
    randomise
        Training ranges (default :func:`training_randomisation` of ``vehicle``).
    held_out
        Held-out conditions by label, as ``reset`` options (default :func:`held_out_conditions` of ``vehicle``).
    env_kwargs
        Further ``offtrack/GainTuning-v0`` arguments (scenario, feedback, rear_feedback, weights, …).
    progress
        Called after every trial with ``(trials done, n_trials, best cost so far)``.
    vehicle
        Catalogue name or vehicle file: the combination tuned (with steered towed units).

    Returns
    -------
    TuningResult

    Raises
    ------
    InputError
        Bad budget, Optuna is not installed, or the combination steers no towed unit.
    TuningStopped
        Ctrl-C or SIGTERM: the trials finished so far, raised from the stop.
    """
    if n_trials < 1 or train_draws < 1:
        raise InputError("tune_gains needs n_trials ≥ 1 and train_draws ≥ 1")
    optuna = require("optuna", "tune", "tuning the gains")
    register_envs()
    t0 = time.perf_counter()
    ranges = training_randomisation(vehicle) if randomise is None else dict(randomise)
    kwargs = {"vehicle": vehicle, "randomise": ranges, **(env_kwargs or {})}
    env = gym.make("offtrack/GainTuning-v0", **kwargs)
    tuning_env: GainTuningEnv = env.unwrapped  # type: ignore[assignment]
    if tuning_env.n_steered < 1:
        env.close()
        raise InputError(f"vehicle {vehicle!r}: steers no towed unit ({tuning_env.units.describe()}); nothing to tune")
    n = tuning_env.n_steered
    units = tuple(unit + 1 for unit in tuning_env.units.units)
    names = parameter_names(units)
    evaluations = 0

    def train_cost(gains: tuple[PathFollowingGains, ...]) -> float:
        nonlocal evaluations
        costs = []
        for k in range(train_draws):
            env.reset(seed=seed + k)
            costs.append(tuning_env.evaluate(gains)[0])
            evaluations += 1
        return float(np.mean(costs))

    env.reset(seed=seed)
    setup = tuning_env._setup
    assert setup is not None
    designed = configured_unit_gains(setup)

    def designed_action() -> dict[str, float]:
        action = np.concatenate([gains_to_action(g) for g in designed])
        return dict(zip(names, map(float, action), strict=True))

    stops: list[KeyboardInterrupt] = []

    def objective(trial: optuna.Trial) -> float:
        action = np.array([trial.suggest_float(name, -1.0, 1.0) for name in names], dtype=np.float32)
        try:
            return train_cost(action_to_unit_gains(action, n))
        except KeyboardInterrupt as stop:  # Optuna would log it with a traceback: end the study quietly instead
            stops.append(stop)
            trial.study.stop()
            raise optuna.TrialPruned() from None

    def trial_gains(trial: optuna.trial.FrozenTrial) -> tuple[PathFollowingGains, ...]:
        if trial.number == 0:  # the designed gains, evaluated as they are (not through the action)
            return designed
        return action_to_unit_gains(np.array([trial.params[n] for n in names], dtype=np.float32), n)

    def finished_rows(study: optuna.Study | None) -> list[dict[str, Any]]:
        rows = []
        for trial in [] if study is None else study.trials:
            row: dict[str, Any] = {"trial": trial.number}
            for name, value in zip(names, (v for g in trial_gains(trial) for v in _plain(g).values()), strict=True):
                row[name] = value
            row["train_cost"] = None if trial.value is None else float(trial.value)
            rows.append({**row, "state": trial.state.name.lower()})
        return [row for row in rows if row["state"] == "complete"] if stops else rows

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    try:
        designed_cost = train_cost(designed)
    except KeyboardInterrupt as stop:
        env.close()
        raise TuningStopped([]) from stop
    study = optuna.create_study(direction="minimize", sampler=optuna.samplers.TPESampler(seed=seed))
    distributions = {name: optuna.distributions.FloatDistribution(-1.0, 1.0) for name in names}
    study.add_trial(
        optuna.trial.create_trial(params=designed_action(), distributions=distributions, value=designed_cost)
    )
    if progress is not None:
        progress(1, n_trials, designed_cost)
    callbacks = []
    if progress is not None:
        callbacks.append(lambda s, t: progress(len(s.trials), n_trials, float(s.best_value)))
    try:
        if n_trials > 1:
            study.optimize(objective, n_trials=n_trials - 1, callbacks=callbacks)
    except KeyboardInterrupt as stop:  # between trials (the sampler, a callback)
        stops.append(stop)
    if stops:
        env.close()
        raise TuningStopped(finished_rows(study)) from stops[0]
    best = study.best_trial
    tuned = trial_gains(best)

    try:
        result = TuningResult(
            designed,
            tuned,
            designed_cost,
            float(best.value),
            trials=len(study.trials),
            units=units,
            vehicle=vehicle,
        )
        result.trial_rows.extend(finished_rows(study))
        for label, options in (held_out_conditions(vehicle) if held_out is None else held_out).items():
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
