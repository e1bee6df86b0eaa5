"""``offtrack/GainTuning-v0``: choose the path-following PID gains, one decision per episode."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from controller.path_following import TrailerSteeringController
from controller.path_following_config import PathFollowingGains
from vehicle_model.errors import InputError
from vehicle_model.geometry import follow_point_from_kingpin

from ..loop.cosimulation import CoSimulation
from ..loop.ends import ENVIRONMENT_LIMITS, Limits, RunStatus
from ..loop.trailer_steer import PathFollowingSteer
from ..run.drive import run_loop
from ..run.metrics import after_warmup, max_abs, rms
from ..setup.build import ScenarioSetup
from ..setup.models import rebuild_setup
from .plan_view import check_render_mode, draw_plan_view
from .scenario import DEFAULT_OVERRIDES, DEFAULT_SCENARIO, DomainRandomisation, FeedbackSource, ScenarioChoice
from .sensors import SensorMode
from .validation import check_choice

__all__ = ["GAIN_RANGES", "GainTuningEnv", "action_to_gains", "gains_to_action"]

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


def gains_to_action(gains: PathFollowingGains, ranges: Mapping[str, tuple[float, float]] = GAIN_RANGES) -> np.ndarray:
    """Gains → normalised action (inverse of :func:`action_to_gains`; gains outside the ranges are clipped)."""
    out = []
    for name, (lo, hi) in ranges.items():
        value = max(getattr(gains, name), lo)
        out.append(2.0 * math.log(value / lo) / math.log(hi / lo) - 1.0)
    return np.clip(np.array(out, dtype=np.float32), -1.0, 1.0)


def episode_figures(columns: dict[str, np.ndarray], follow_point_offset: float) -> dict[str, float]:
    """RMS and largest true off-tracking after warm-up [m], RMS feedback steer [rad], saturated fraction.

    Warm-up (:func:`scenarios.run.metrics.after_warmup`): until one trailer length after the truth exists. Missing
    figures are 0.0 (no settled sample: the run ended during warm-up).
    """
    settled = after_warmup(columns, follow_point_offset)
    sat_cols = [v for k, v in columns.items() if k.startswith("saturated_")]
    saturated = np.any(np.vstack(sat_cols) > 0.5, axis=0) if sat_cols else np.zeros_like(settled)
    feedback = columns.get("trailer_feedback_steer", np.zeros(settled.size))

    def finite(x: float) -> float:
        return x if math.isfinite(x) else 0.0

    return {
        "rms_offtracking": finite(rms(columns["offtracking_truth"][settled])),
        "max_offtracking": finite(max_abs(columns["offtracking_truth"][settled])),
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

    ## Action Space

    ``Box(-1, 1, (3,), float32)``: ``(kp, ki, kd)`` normalised on a log scale over :data:`GAIN_RANGES`,
    ``g = lo·(hi/lo)^((a + 1)/2)``: ``kp`` 0.01–3 rad/m, ``ki`` 0.001–1 rad/m², ``kd`` 0.001–3 rad (per metre
    travelled). :func:`action_to_gains` and :func:`gains_to_action` convert.

    ## Observation Space

    ``Box(float32)`` of the episode's settings (:data:`CONTEXT_NAMES`): ``mu`` 0–1.5, ``camber_signed_percent``
    ±10 (positive: outward/adverse), ``speed`` 0–25 m/s, ``laden`` 0/1.

    ## Rewards

    ``reward = −cost`` with::

        cost = RMS(e_tr after warm-up) [m] + w_effort·RMS(δ_fb) [rad] + w_sat·(saturated fraction)
               + failure_cost·(run terminated)

    ``e_tr`` the **true** off-tracking, warm-up one trailer length after it first exists
    (:func:`scenarios.run.metrics.after_warmup`), ``δ_fb`` the PID's part of the virtual-axle steer, the
    saturated fraction the share of settled ticks on which an axle hit ±δ_max. Defaults
    ``w_effort = 0.1 m/rad``, ``w_sat = 0.5 m``, ``failure_cost = 5 m``. The parts and the run's figures are in
    ``info`` (``cost_*``, ``rms_offtracking``, ``max_offtracking``, ``saturated_fraction``, ``status``, the gains).
    The run is :func:`scenarios.run.drive.run_loop` on the co-simulation of ``offtrack run``.

    ## Starting State

    As ``offtrack/TrailerSteering-v0``: the scenario's start; the settings are drawn at every ``reset`` from
    the ``randomise`` ranges with ``np_random``, which also seeds the run.

    ## Episode End

    Every step ends the episode (``terminated=True``). The run inside ends at the scenario's end, or early on a
    jackknife, divergence or leaving the road (:class:`~scenarios.loop.ends.Limits`, then ``failure_cost`` is added).

    ## Arguments

    The scenario arguments of ``offtrack/TrailerSteering-v0`` (``scenario``, ``overrides``, ``feedback``, ``vehicle``,
    ``mu``, ``camber_percent``, ``camber_direction``, ``speed_kmh``, ``direction``, ``randomise``, ``sensors``, the
    limits, all validated at construction), and
    ``effort_weight``, ``saturation_weight``, ``failure_cost``, ``render_mode="rgb_array"`` (plan view of the whole
    path with the last run's kingpin and follow-point tracks; ``"human"`` is refused). ``reset(options=...)``
    takes the scenario arguments for one episode. The spec has no ``max_episode_steps``: every episode is one
    step, ended by ``terminated=True`` (a one-step time limit would also mark it truncated).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 1}

    def __init__(
        self,
        scenario: str = DEFAULT_SCENARIO,
        overrides: Mapping[str, Any] | None = None,
        feedback: FeedbackSource = "truth",
        vehicle: str | None = "lst",
        mu: float | None = None,
        camber_percent: float | None = None,
        camber_direction: Literal["outward", "inward"] | None = None,
        speed_kmh: float | None = None,
        direction: Literal["left", "right"] | None = None,
        randomise: DomainRandomisation | Mapping[str, Any] | None = None,
        sensors: SensorMode = "datasheet",
        effort_weight: float = 0.1,
        saturation_weight: float = 0.5,
        failure_cost: float = 5.0,
        max_articulation_deg: float = ENVIRONMENT_LIMITS.max_articulation_deg,
        max_lateral_error: float = ENVIRONMENT_LIMITS.max_lateral_error,
        max_offtracking: float | None = ENVIRONMENT_LIMITS.max_offtracking,
        render_mode: str | None = None,
        render_size: tuple[int, int] = (400, 400),
    ) -> None:
        self.choice = ScenarioChoice(
            scenario=scenario,
            overrides=dict(DEFAULT_OVERRIDES) if overrides is None else dict(overrides),
            feedback=feedback,
            vehicle=vehicle,
            mu=mu,
            camber_percent=camber_percent,
            camber_direction=camber_direction,
            speed_kmh=speed_kmh,
            direction=direction,
            randomise=DomainRandomisation.coerce(randomise),
            sensors=sensors,
        )
        check_choice(self.choice)
        for name, value in (("effort_weight", effort_weight), ("saturation_weight", saturation_weight)):
            if not (value >= 0 and math.isfinite(value)):
                raise InputError(f"{name} = {value!r} must be a finite number ≥ 0")
        if not (failure_cost >= 0 and math.isfinite(failure_cost)):
            raise InputError(f"failure_cost = {failure_cost!r} must be a finite number ≥ 0")
        self.effort_weight = float(effort_weight)
        self.saturation_weight = float(saturation_weight)
        self.failure_cost = float(failure_cost)
        self.limits = Limits(max_articulation_deg, max_lateral_error, max_offtracking)
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.render_size = (int(render_size[0]), int(render_size[1]))
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
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
        config, settings = choice.resolve(self.np_random)
        self._setup = rebuild_setup(config)
        self._last = None
        self.episode_settings = settings
        return self._context(), dict(settings)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Run the episode's scenario with the gains of ``action``."""
        if self._setup is None:
            raise gym.error.ResetNeeded("call reset() before step()")
        cost, info = self.evaluate(action_to_gains(action))
        return self._context(), -cost, True, False, info

    def evaluate(self, gains: PathFollowingGains) -> tuple[float, dict[str, Any]]:
        """Cost and figures of the episode's scenario steered with ``gains`` (any gains, e.g. ``kd = 0``).

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
        cosim = CoSimulation(setup, self._source(setup, gains), limits=self.limits)
        outcome, columns = run_loop(lambda: cosim, catch_stops=False)
        if outcome.status == RunStatus.LOST_CONTROL and cosim.breach is not None:
            status = str(cosim.breach.reason)
        elif outcome.status == RunStatus.DIVERGED:
            status = "diverged"
        else:
            status = str(outcome.status)
        self._last = (status, columns, cosim)
        figures = episode_figures(columns, setup.params.follow_point_offset)
        parts = {
            "cost_offtracking": figures["rms_offtracking"],
            "cost_effort": self.effort_weight * figures["rms_feedback_steer"],
            "cost_saturation": self.saturation_weight * figures["saturated_fraction"],
            "cost_failure": self.failure_cost if status != RunStatus.COMPLETED else 0.0,
        }
        cost = float(sum(parts.values()))
        info = {
            **self.episode_settings,
            "kp": gains.kp,
            "ki": gains.ki,
            "kd": gains.kd,
            "status": status,
            **figures,
            **parts,
            "cost": cost,
        }
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
    def _source(setup: ScenarioSetup, gains: PathFollowingGains) -> PathFollowingSteer:
        """The scenario's configured controller with ``gains``, on the configured feedback."""
        cfg = setup.config
        settings = cfg.controller.path_following(cfg.rates.control_hz).replace(gains=gains)
        return PathFollowingSteer(TrailerSteeringController(setup.params, settings), cfg.feedback)

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
