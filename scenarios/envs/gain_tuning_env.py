"""``offtrack/GainTuning-v0``: choose the path-following PID gains, one decision per episode."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from controller.path_following import TrailerSteeringController
from controller.path_following_config import PathFollowingGains
from vehicle_model.errors import InputError
from vehicle_model.geometry import follow_point_from_kingpin

from ..loop.cosimulation import CoSimulation
from ..loop.ends import ENVIRONMENT_LIMITS, Limits, RunStatus, StopReason
from ..loop.schema import FIRST_TOWED_UNIT, estimate_columns
from ..loop.trailer_steer import PathFollowingSteer, trailer_axles
from ..registry import TRUTH
from ..run.drive import run_loop
from ..run.metrics import after_warmup, max_abs, rms
from ..setup.build import ScenarioSetup
from ..setup.models import rebuild_setup
from ..unit_feedback import steered_units
from .env_config import configure, scenario_defaults
from .plan_view import check_render_mode, draw_plan_view
from .scenario import ScenarioChoice
from .units import check_episode_units, check_units
from .validation import check_choice

__all__ = [
    "GAIN_RANGES",
    "GainTuningEnv",
    "action_to_gains",
    "action_to_unit_gains",
    "configured_unit_gains",
    "gains_to_action",
    "unit_figures",
]

GAIN_RANGES: dict[str, tuple[float, float]] = {"kp": (0.01, 3.0), "ki": (0.001, 1.0), "kd": (0.001, 3.0)}
"""Ranges of the gains the action spans (log-scaled): ``kp`` [rad/m], ``ki`` [rad/m²], ``kd`` [rad], per metre
travelled (:class:`~controller.path_following_config.PathFollowingGains`). The designed defaults of the ``lst``
(``kp`` 0.286, ``ki`` 0.0745, ``kd`` 0) lie inside, ``kd`` at the lower end."""

CONTEXT_NAMES: tuple[str, ...] = ("mu", "camber_signed_percent", "speed", "laden")
"""Observation of :class:`GainTuningEnv`: friction [-], camber [%] (positive outward/adverse, negative
inward), cornering speed [m/s], 1 for a laden trailer (0 for an ``-unladen`` preset)."""


def action_to_gains(action: np.ndarray, ranges: Mapping[str, tuple[float, float]] = GAIN_RANGES) -> PathFollowingGains:
    """Normalised action ``a ∈ [-1, 1]³`` → gains ``g = lo·(hi/lo)^((a + 1)/2)`` (log-scaled, clipped)."""
    a = np.clip(np.asarray(action, dtype=float).reshape(-1), -1.0, 1.0)
    if a.size != 3 or not np.all(np.isfinite(a)):
        raise InputError(f"action = {action!r} must be three finite numbers (kp, ki, kd) in [-1, 1]")
    values = {
        name: float(lo * (hi / lo) ** (0.5 * (x + 1.0))) for (name, (lo, hi)), x in zip(ranges.items(), a, strict=True)
    }
    return PathFollowingGains(**values)


def action_to_unit_gains(
    action: np.ndarray, n: int, ranges: Mapping[str, tuple[float, float]] = GAIN_RANGES
) -> tuple[PathFollowingGains, ...]:
    """Normalised action ``a ∈ [-1, 1]^(3n)`` → one gain set per steered unit, front to rear: entries ``3i … 3i + 2``
    are unit ``i``'s ``(kp, ki, kd)``, each as :func:`action_to_gains`."""
    a = np.asarray(action, dtype=float).reshape(-1)
    if n == 1:
        return (action_to_gains(a, ranges),)
    if a.size != 3 * n:
        raise InputError(
            f"action = {action!r} must be {3 * n} finite numbers in [-1, 1]: (kp, ki, kd) of each of the {n} steered "
            "units, front to rear"
        )
    return tuple(action_to_gains(a[3 * i : 3 * i + 3], ranges) for i in range(n))


def gains_to_action(gains: PathFollowingGains, ranges: Mapping[str, tuple[float, float]] = GAIN_RANGES) -> np.ndarray:
    """Gains → normalised action (inverse of :func:`action_to_gains`; gains outside the ranges are clipped)."""
    out = []
    for name, (lo, hi) in ranges.items():
        value = max(getattr(gains, name), lo)
        out.append(2.0 * math.log(value / lo) / math.log(hi / lo) - 1.0)
    return np.clip(np.array(out, dtype=np.float32), -1.0, 1.0)


def configured_unit_gains(setup: ScenarioSetup) -> tuple[PathFollowingGains, ...]:
    """The gains each steered towed unit of ``setup`` runs with (front to rear), exactly as ``offtrack run`` sets
    them: the ``controller`` section's ``unit_gains`` or ``kp``/``ki``/``kd`` when given, else each unit's own pole
    placement for its geometry (the designed gains, ``kd = 0``;
    :func:`~controller.path_following_config.kinematic_pole_placement`)."""
    cfg = setup.config
    units = steered_units(setup.params, cfg.feedback, cfg.rear_feedback)
    settings = cfg.controller.unit_settings(cfg.rates.control_hz, len(units))
    return tuple(
        TrailerSteeringController(setup.params, s, unit).gains for (unit, _), s in zip(units, settings, strict=True)
    )


def unit_figures(columns: dict[str, np.ndarray], settled: np.ndarray, unit: int) -> dict[str, float]:
    """RMS and largest true off-tracking [m] and RMS feedback steer [rad] of unit ``unit`` of the combination (3 or
    4: behind the first towed one), over the first towed unit's settled samples on which the unit's own
    off-tracking exists (0.0 when none; the feedback steer 0.0 when the unit is not steered)."""
    truth_column = estimate_columns(columns).get((TRUTH, unit))
    truth = np.asarray(columns[truth_column.name] if truth_column else np.full(settled.size, np.nan), dtype=float)
    after = settled & np.isfinite(truth)
    feedback = np.asarray(columns.get(f"unit{unit}_feedback_steer", np.zeros(settled.size)), dtype=float)

    def finite(x: float) -> float:
        return x if math.isfinite(x) else 0.0

    return {
        "rms_offtracking": finite(rms(truth[after])),
        "max_offtracking": finite(max_abs(truth[after])),
        "rms_feedback_steer": finite(rms(feedback[after])),
    }


def episode_figures(columns: dict[str, np.ndarray], follow_point_offset: float) -> dict[str, float]:
    """RMS and largest true off-tracking after warm-up [m], RMS feedback steer [rad], saturated fraction.

    Warm-up (:func:`scenarios.run.metrics.after_warmup`): until one trailer length after the truth exists. Missing
    figures are 0.0 (no settled sample: the run ended during warm-up).
    """
    settled = after_warmup(columns, follow_point_offset)
    sat_cols = [v for k, v in columns.items() if k.startswith("saturated_")]
    saturated = np.any(np.vstack(sat_cols) > 0.5, axis=0) if sat_cols else np.zeros_like(settled)
    feedback = columns.get("trailer_feedback_steer", np.zeros(settled.size))

    truth = columns[estimate_columns(columns)[TRUTH, FIRST_TOWED_UNIT].name]

    def finite(x: float) -> float:
        return x if math.isfinite(x) else 0.0

    return {
        "rms_offtracking": finite(rms(truth[settled])),
        "max_offtracking": finite(max_abs(truth[settled])),
        "rms_feedback_steer": finite(rms(feedback[settled])),
        "saturated_fraction": float(np.mean(saturated[settled])) if settled.any() else 0.0,
        "settled_samples": float(settled.sum()),
        "simulated_s": float(columns["time"][-1]) if columns["time"].size else 0.0,
    }


class GainTuningEnv(gym.Env[np.ndarray, np.ndarray]):
    """Pick the trailer path-following PID gains for a (randomised) scenario; the reward is the run's cost.

    ## Description

    A one-step (contextual bandit) environment for tuning
    :class:`~controller.path_following.TrailerSteeringController`: ``reset`` draws a scenario (friction,
    camber, speed, trailer load, …) and shows its settings; ``step(action)`` runs the whole scenario in the
    co-simulation with the controller at the chosen gains (curvature feed-forward, saturation, rate limit
    and speed schedule as configured) and returns minus its cost. Default scenario: a quarter of a 50 m
    roundabout at 15 km/h with the ``lst`` trailer, about 0.5 s of computing per step with ``truth`` feedback.
    Calling ``step`` again before ``reset`` evaluates other gains on the same draw (same seed).

    Any combination can be tuned (docs/vehicles.md): every steered towed unit — the first on ``feedback`` when it
    has a steerable axle, each unit behind it on its ``rear_feedback`` (:func:`scenarios.unit_feedback.steered_units`)
    — runs its own PID, and the action holds one gain set per steered unit. One set per unit, not one shared, is
    the design: each unit's loop has its own geometry (virtual axle, follow point; the designed gains are placed
    per unit) and its own estimate, and a shared set is the special case of equal entries. A tractor–semi-trailer
    has ``n = 1``: everything below then reads as for one trailer.

    ## Action Space

    ``Box(-1, 1, (3n,), float32)`` for ``n`` steered towed units (``Box(-1, 1, (3,))`` for a tractor–semi-trailer):
    ``(kp, ki, kd)`` of each steered unit, front to rear, normalised on a log scale over :data:`GAIN_RANGES`,
    ``g = lo·(hi/lo)^((a + 1)/2)``: ``kp`` 0.01–3 rad/m, ``ki`` 0.001–1 rad/m², ``kd`` 0.001–3 rad (per metre
    travelled). :func:`action_to_gains`, :func:`action_to_unit_gains` and :func:`gains_to_action` convert.

    ## Observation Space

    ``Box(float32)`` of the episode's settings (:data:`CONTEXT_NAMES`): ``mu`` 0–1.5, ``camber_signed_percent``
    ±10 (positive: outward/adverse), ``speed`` 0–25 m/s, ``laden`` 0/1.

    ## Rewards

    ``reward = −cost`` with::

        cost = mean_k RMS(e_k after warm-up) [m] + w_effort·mean_k RMS(δ_fb,k) [rad] + w_sat·(saturated fraction)
               + failure_cost·(run terminated)

    the means over the ``n`` steered units (for ``n = 1`` the single trailer's ``RMS(e_tr)`` and ``RMS(δ_fb)``):
    ``e_k`` the **true** off-tracking of unit ``k`` against its own coupling's path, warm-up one trailer length
    after the first towed unit's first exists (:func:`scenarios.run.metrics.after_warmup`), ``δ_fb,k`` the part
    of unit ``k``'s virtual-axle steer its PID's feedback makes, the saturated fraction the share of settled ticks
    on which any axle hit ±δ_max. Defaults ``w_effort = 0.1 m/rad``, ``w_sat = 0.5 m``, ``failure_cost = 5 m``.
    The parts and the run's figures are in ``info`` (``cost_*``, ``rms_offtracking``, ``max_offtracking``,
    ``rms_feedback_steer`` — the first towed unit's —, ``saturated_fraction``, ``status``, the gains ``kp``,
    ``ki``, ``kd`` of the first steered unit and ``unit<k>_kp``, … of each further steered unit ``k``; for a
    longer combination ``units``: :func:`unit_figures` of each unit behind the first towed one, by its number).
    The run is :func:`scenarios.run.drive.run_loop` on the co-simulation of ``offtrack run``; a run ends early
    when any towed unit breaks a limit (:meth:`~scenarios.loop.ends.Limits.check_units`).

    ## Starting State

    As ``offtrack/TrailerSteering-v0``: the scenario's start; the settings are drawn at every ``reset`` from
    the ``randomise`` ranges with ``np_random``, which also seeds the run.

    ## Episode End

    Every step ends the episode (``terminated=True``). The run inside ends at the scenario's end, or early on a
    jackknife, divergence or leaving the road (:class:`~scenarios.loop.ends.Limits`, then ``failure_cost`` is added).

    ## Arguments

    ``GainTuningEnv(config=None, render_mode=None, **settings)``, its :attr:`config` :meth:`default_config` updated
    by ``config`` and then by the keywords, as ``offtrack/TrailerSteering-v0``'s. The settings are the scenario
    settings of ``offtrack/TrailerSteering-v0`` (``scenario``, ``overrides``, ``feedback``, ``rear_feedback``,
    ``vehicle``, ``mu``, ``camber_percent``, ``camber_direction``, ``speed_kmh``, ``direction``, ``randomise``,
    ``sensors``, the limits, all validated at construction), and ``effort_weight``, ``saturation_weight``,
    ``failure_cost``, ``render_size``; ``render_mode="rgb_array"`` gives a plan view of the whole
    path with the last run's kingpin and follow-point tracks (``"human"`` is refused). ``reset(options=...)``
    takes the scenario arguments for one episode. The spec has no ``max_episode_steps``: every episode is one
    step, ended by ``terminated=True`` (a one-step time limit would also mark it truncated). As there, the vehicles
    of ``randomise["vehicle"]`` and of ``reset`` options must steer the same towed units.

    Attributes
    ----------
    config : dict
        Every setting the environment was made with (:meth:`default_config`'s keys).
    units : EnvUnits
        The combination's number of units and its steered towed units (:class:`~scenarios.envs.units.EnvUnits`).
    n_steered : int
        Steered towed units: the action holds ``3·n_steered`` entries.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 1}

    @classmethod
    def default_config(cls) -> dict[str, Any]:
        """Every setting of the environment and its default (the keys its ``config`` and keywords take).

        The scenario settings (:func:`~scenarios.envs.env_config.scenario_defaults`), then the cost's
        ``effort_weight``, ``saturation_weight`` and ``failure_cost``, the limits ``max_articulation_deg``,
        ``max_lateral_error``, ``max_offtracking``, and the picture's ``render_size``.
        """
        return {
            **scenario_defaults(),
            "effort_weight": 0.1,
            "saturation_weight": 0.5,
            "failure_cost": 5.0,
            "max_articulation_deg": ENVIRONMENT_LIMITS.max_articulation_deg,
            "max_lateral_error": ENVIRONMENT_LIMITS.max_lateral_error,
            "max_offtracking": ENVIRONMENT_LIMITS.max_offtracking,
            "render_size": (400, 400),
        }

    def __init__(
        self,
        config: Mapping[str, Any] | ScenarioChoice | None = None,
        render_mode: str | None = None,
        **settings: Any,
    ) -> None:
        """Make the environment.

        Parameters
        ----------
        config
            Settings over :meth:`default_config` (the keys of the "Arguments" above), or a
            :class:`~scenarios.envs.scenario.ScenarioChoice` for the scenario settings.
        render_mode
            ``None`` or ``"rgb_array"``.
        **settings
            Any key of :meth:`default_config`, applied over ``config`` (how ``gymnasium.make`` passes them).

        Raises
        ------
        InputError
            A key that is not a setting (naming it and the allowed keys), or a setting out of its range.
        """
        self.config, self.choice, self.units = configure(type(self).__name__, self.default_config(), config, settings)
        cfg = self.config
        self.n_steered = self.units.n_steered
        for name in ("effort_weight", "saturation_weight", "failure_cost"):
            value = cfg[name]
            if not (value >= 0 and math.isfinite(value)):
                raise InputError(f"{name} = {value!r} must be a finite number ≥ 0")
        self.effort_weight = float(cfg["effort_weight"])
        self.saturation_weight = float(cfg["saturation_weight"])
        self.failure_cost = float(cfg["failure_cost"])
        self.limits = Limits(
            cfg["max_articulation_deg"], cfg["max_lateral_error"], cfg["max_offtracking"], every_unit=True
        )
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.render_size = (int(cfg["render_size"][0]), int(cfg["render_size"][1]))
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3 * self.n_steered,), dtype=np.float32)
        self.observation_space = spaces.Box(
            np.array([0.0, -10.0, 0.0, 0.0], dtype=np.float32),
            np.array([1.5, 10.0, 25.0, 1.0], dtype=np.float32),
            dtype=np.float32,
        )
        self._setup: ScenarioSetup | None = None
        self._last: tuple[str, dict[str, np.ndarray], CoSimulation] | None = None
        self.episode_settings: dict[str, Any] = {}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        """Draw the episode's scenario; ``options`` override the environment's settings for this episode."""
        super().reset(seed=seed)
        choice = self.choice.with_options(options)
        if options:
            check_choice(choice)
            episode = check_units(choice)
            if not episode.same_shape(self.units):
                raise InputError(
                    f"reset options: {episode.describe()}; this environment's action needs {self.units.describe()} "
                    "(make a new environment for it)"
                )
        config, settings = choice.resolve(self.np_random)
        check_episode_units(self.units, config)
        self._setup = rebuild_setup(config)
        self._last = None
        self.episode_settings = settings
        return self._context(), dict(settings)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Run the episode's scenario with the gains of ``action`` (one ``(kp, ki, kd)`` per steered unit)."""
        if self._setup is None:
            raise gym.error.ResetNeeded("call reset() before step()")
        gains = action_to_unit_gains(action, self.n_steered)
        cost, info = self.evaluate(gains[0] if self.n_steered == 1 else gains)
        return self._context(), -cost, True, False, info

    def evaluate(self, gains: PathFollowingGains | Sequence[PathFollowingGains]) -> tuple[float, dict[str, Any]]:
        """Cost and figures of the episode's scenario steered with ``gains`` (any gains, e.g. ``kd = 0``).

        Parameters
        ----------
        gains
            One gain set per steered unit, front to rear, or one set for every steered unit.

        Returns
        -------
        cost : float
            As in the class docstring (the reward is its negative).
        info : dict
            The cost parts, the run's figures, the gains and the episode's settings.
        """
        setup = self._setup
        if setup is None:
            raise gym.error.ResetNeeded("call reset() before evaluate()")
        sets = (gains,) * self.n_steered if isinstance(gains, PathFollowingGains) else tuple(gains)
        if len(sets) != self.n_steered or not all(isinstance(g, PathFollowingGains) for g in sets):
            raise InputError(
                f"gains = {gains!r}: one PathFollowingGains per steered unit ({self.n_steered}) or one for every unit"
            )
        cosim = CoSimulation(setup, self._source(setup, sets), limits=self.limits)
        outcome, columns = run_loop(lambda: cosim, catch_stops=False)
        if outcome.status == RunStatus.LOST_CONTROL and cosim.breach is not None:
            status = str(cosim.breach.reason)
        elif outcome.status == RunStatus.DIVERGED:
            status = str(StopReason.DIVERGED)
        else:
            status = str(outcome.status)
        self._last = (status, columns, cosim)
        figures = episode_figures(columns, setup.params.follow_point_offset)
        settled = after_warmup(columns, setup.params.follow_point_offset)
        further = {str(unit): unit_figures(columns, settled, unit) for unit in self.units.further}
        steered = [figures if unit == 1 else further[str(unit + 1)] for unit in self.units.units]
        parts = {
            "cost_offtracking": sum(f["rms_offtracking"] for f in steered) / len(steered),
            "cost_effort": self.effort_weight * (sum(f["rms_feedback_steer"] for f in steered) / len(steered)),
            "cost_saturation": self.saturation_weight * figures["saturated_fraction"],
            "cost_failure": self.failure_cost if status != RunStatus.COMPLETED else 0.0,
        }
        cost = float(sum(parts.values()))
        info = {
            **self.episode_settings,
            "kp": sets[0].kp,
            "ki": sets[0].ki,
            "kd": sets[0].kd,
        }
        for unit, unit_gains in zip(self.units.units[1:], sets[1:], strict=True):
            info.update({f"unit{unit + 1}_{k}": getattr(unit_gains, k) for k in ("kp", "ki", "kd")})
        info.update({"status": status, **figures, **parts, "cost": cost})
        if further:
            info["units"] = further
        return cost, info

    def render(self) -> np.ndarray | None:
        """Plan view of the whole path with the last run's tracks, as uint8 ``H×W×3``."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; create the env with render_mode='rgb_array'")
            return None
        if self._setup is None:
            raise gym.error.ResetNeeded("call reset() before render()")
        setup = self._setup
        points = setup.path.points
        lo, hi = points.min(axis=0), points.max(axis=0)
        span = float(max(hi[0] - lo[0], (hi[1] - lo[1]) * self.render_size[1] / self.render_size[0]) + 30.0)
        if self._last is None:
            state, kingpin, follow, text = setup.initial_state, None, None, ("no run yet",)
        else:
            status, cols, cosim = self._last
            kingpin = np.column_stack([cols["kingpin_x"], cols["kingpin_y"]])
            l_fp = setup.params.follow_point_offset
            follow = follow_point_from_kingpin(kingpin, cols["psi2"], l_fp)
            state = cosim.tick.state
            figures = episode_figures(cols, l_fp)
            text = (f"{status}: RMS e_tr {figures['rms_offtracking'] * 1e3:.1f} mm",)
        return draw_plan_view(
            setup.params,
            state,
            points,
            kingpin_track=kingpin,
            follow_track=follow,
            centre=0.5 * (lo + hi),
            span=span,
            size=self.render_size,
            text=text,
        )

    def close(self) -> None:
        """Drop the last run."""
        self._last = None

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_setup"] = None if self._setup is None else self._setup.config  # rebuilt: closures, compiled model
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        config = state["_setup"]
        self.__dict__.update(state)
        self._setup = None if config is None else rebuild_setup(config)

    # ------------------------------------------------------------------ internals

    @staticmethod
    def _source(setup: ScenarioSetup, gains: Sequence[PathFollowingGains]) -> PathFollowingSteer:
        """The scenario's configured controller on every steered unit, each with its own ``gains`` and on its
        configured feedback."""
        cfg = setup.config
        settings = cfg.controller.path_following(cfg.rates.control_hz)
        units = steered_units(setup.params, cfg.feedback, cfg.rear_feedback)
        controllers = tuple(
            (TrailerSteeringController(setup.params, settings.replace(gains=g), unit), key)
            for (unit, key), g in zip(units, gains, strict=True)
        )
        return PathFollowingSteer(*controllers[0], rear=controllers[1:], axles=trailer_axles(setup))

    def _context(self) -> np.ndarray:
        s = self.episode_settings
        sign = 1.0 if s["camber_direction"] == "outward" else -1.0
        obs = np.array(
            [
                s["mu"],
                sign * s["camber_percent"],
                s["speed_kmh"] / 3.6,
                0.0 if str(s["vehicle"]).endswith("-unladen") else 1.0,
            ],
            dtype=np.float32,
        )
        return np.clip(obs, self.observation_space.low, self.observation_space.high)
