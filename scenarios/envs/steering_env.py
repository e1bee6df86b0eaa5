"""``offtrack/TrailerSteering-v0``: steer the trailer's axles one control period at a time."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from controller.path_following import TrailerSteeringController
from vehicle_model.errors import InputError, SimulationDivergedError
from vehicle_model.geometry import follow_point_from_kingpin
from vehicle_model.offtracking import OfftrackingEstimate

from ..loop.cosimulation import CoSimulation
from ..loop.ends import ENVIRONMENT_LIMITS, Limits, StopReason
from ..loop.trailer_steer import AgentSteer, hold_signals, trailer_axles
from ..setup.models import rebuild_setup
from ..unit_feedback import estimate_key
from .env_config import configure, scenario_defaults
from .plan_view import camera_strip, check_render_mode, draw_plan_view
from .reward import OFFTRACKING_CLIP, OFFTRACKING_TOLERANCE, REWARD_WEIGHTS, SteeringReward, episode_summary
from .scenario import ScenarioChoice
from .steering_observation import observation_layout
from .units import check_episode_units, check_units
from .validation import check_choice

__all__ = [
    "MAX_EPISODE_STEPS",
    "REWARD_WEIGHTS",
    "TrailerSteeringEnv",
]

MAX_EPISODE_STEPS = 5000
"""``max_episode_steps`` of the registered spec: 100 s simulated (the default episode is about 1700 steps)."""

PREVIEW_DISTANCES: tuple[float, ...] = (0.0, 10.0, 20.0, 30.0)
"""Default path-curvature preview distances ahead of the driver's control point [m]."""


class TrailerSteeringEnv(gym.Env[np.ndarray, np.ndarray]):
    """Steer the towed units of a combination so that each one's rear follows its own coupling's path.

    ## Description

    A tractor drives a scenario of the offtrack catalogue (default: a quarter of a 50 m roundabout at
    15 km/h with the ``lst`` longer semi-trailer, entry and exit straights included) under its own driver
    and speed controller. Every step is one control period (20 ms) of the co-simulation
    (:class:`~scenarios.loop.cosimulation.CoSimulation`, the loop of ``offtrack run``, with the agent as its
    trailer-steer source, :class:`~scenarios.loop.trailer_steer.AgentSteer`): the agent steers the
    trailer's *virtual axle* and the controller's distribution points every steerable trailer axle at the
    same instantaneous centre, with the speed fade, ±25° saturation and 20°/s rate limit of the
    path-following controller. The goal is zero off-tracking ``e_tr``: the follow point at the trailer's
    rear on the kingpin's past path (docs/usage.md, "Off-tracking and the estimators").

    Any combination of the catalogue (docs/vehicles.md) can be steered: a B-double, an A-double, a truck and dolly
    with steerable axles on more than one towed unit. Every towed unit that is steered — one with a steerable axle,
    the first on ``feedback`` and each unit behind it on its ``rear_feedback``
    (:func:`scenarios.unit_feedback.steered_units`) — has its own entry in the action, its own virtual axle and
    output stage (:class:`~controller.steer_output.TrailerSteerOutput` with ``unit``), and its own off-tracking
    ``e_k`` against its own coupling's path (the closed loop of ``offtrack run`` with the PID on every steered unit,
    :class:`~scenarios.loop.trailer_steer.PathFollowingSteer`). A tractor–semi-trailer has ``n = 1``: everything
    below then reads as for one trailer.

    ## Action Space

    ``Box(-1, 1, (n,), float32)``, normalised, one entry ``a_k`` per steered towed unit, front to rear
    (``n`` = :attr:`n_steered`; ``Box(-1, 1, (1,))`` for a tractor–semi-trailer):

    * ``action_mode="direct"``: unit ``k``'s virtual-axle steer ``δ_v,k = a_k·δ_max`` (``δ_max`` =
      ``controller.max_steer_deg``, 25° by default);
    * ``action_mode="residual"``: a correction added to unit ``k``'s own PID's virtual-axle steer
      (:class:`~controller.path_following.TrailerSteeringController` with ``unit``, fed by that unit's estimate),
      ``δ_v,k = δ_PID,k + a_k·residual_scale_deg``; ``a = 0`` reproduces the closed loop of ``offtrack run`` with
      the same feedbacks exactly, as long as the controller's slip-angle limit (``controller.max_slip_angle_deg``,
      which only the PID applies) clips nothing.

    A unit's virtual-axle angle is distributed over its own steerable axles; a steerable axle of a unit that is
    not steered (``rear_feedback`` ``none``) is held straight.

    ## Observation Space

    ``Box(float32)`` of ``9 + 7·(N − 2) + len(preview_distances)`` entries for a combination of ``N`` units
    (``9 + len(preview_distances)`` for a tractor–semi-trailer), what the vehicle can know (measured signals,
    the chosen estimates, the map), clipped to finite bounds; :attr:`observation_names` names them:

    | # | name | unit | bound |
    |---|---|---|---|
    | 0 | ``offtracking_estimate`` (``feedback`` source, held between camera frames; 0 when invalid) | m | ±5 |
    | 1 | ``estimate_valid`` (1: the estimate exists) | - | 0..1 |
    | 2 | ``articulation`` Γ (fifth-wheel sensor) | rad | ±π |
    | 3 | ``wheel_speed`` | m/s | ±30 |
    | 4 | ``tractor_yaw_rate`` | rad/s | ±6 |
    | 5 | ``trailer_yaw_rate`` | rad/s | ±6 |
    | 6 | ``previous_virtual_steer`` (applied, after the clamp) | rad | ±π/2 |
    | 7 | ``previous_action`` | - | ±1 |
    | 8 | ``pid_virtual_steer`` (residual mode; 0 in direct mode) | rad | ±π/2 |
    | 9… | ``unit<k>_…``: 7 entries for each unit ``k = 3 … N`` behind the first towed one (below) | | |
    | … | ``curvature_ahead_<d>m``: path curvature ``d`` metres ahead of the driver's control point | 1/m | ±0.25 |

    Entries 0, 1 and 6–8 are the first towed unit's (6–8 are 0 when it is not steered). Each unit ``k`` behind
    it (:func:`~.steering_observation.unit_observation_names`; ``k`` numbers the combination's units from the
    tractor, as the recorded columns do) adds:

    | name | unit | bound |
    |---|---|---|
    | ``unit<k>_offtracking_estimate``: the estimate it is steered on (``truth<k>``, ``zero_slip<k>`` or its own
      camera's ``viso_ot<k>`` / ``viso_ot_fused<k>``, its ``rear_feedback``; 0 when invalid or the unit is not
      steered) | m | ±5 |
    | ``unit<k>_estimate_valid`` | - | 0..1 |
    | ``unit<k>_articulation`` against the unit ahead (its coupling's sensor, ``rear_articulation``) | rad | ±π |
    | ``unit<k>_yaw_rate`` (true: the signals have no gyro on the units behind the first towed one) | rad/s | ±6 |
    | ``unit<k>_previous_virtual_steer``, ``unit<k>_previous_action``, ``unit<k>_pid_virtual_steer`` (as 6–8; 0
      when the unit is not steered) | rad, -, rad | ±π/2, ±1, ±π/2 |

    ## Rewards

    From the **true** off-tracking ``e_k`` of every steered unit after the step and the applied commands ``δ_j``
    of every steered axle, per step::

        r = −w_e·mean_k min(|e_k|/e_tol, c_max) − w_u·mean_j (δ_j/δ_max)² − w_du·mean_j (Δδ_j/(δ̇_max·Δt))²

    (the mean over the ``n`` steered units of each one's clipped, normalised off-tracking against its own
    coupling's path, 0 for a unit whose ``e_k`` does not exist yet; for ``n = 1`` the single trailer's term).

    ``e_tol = 0.10 m`` (the off-tracking target), ``c_max = 10``, weights :data:`REWARD_WEIGHTS` (``w_e = 1``,
    ``w_u = w_du = 0.01``): the off-tracking term is about 99 % of the designed PID's return. On termination
    the worst per-step cost for every step left, plus ``termination_penalty``, is charged as well
    (:mod:`scenarios.envs.reward`). The parts are in ``info`` as ``reward_offtracking``, ``reward_effort``,
    ``reward_rate``, ``reward_termination``; the final step's ``info["episode_summary"]`` holds the episode in
    the figures of ``metrics.json`` (true off-tracking RMS and largest after warm-up, saturated fraction,
    termination reason, the return and its parts; for a longer combination ``units``, the same RMS and largest
    of every unit behind the first towed one, by its number) and ``info["config"]`` the configuration it ran.
    For a longer combination ``info`` also holds ``virtual_steers`` (every steered unit's, front to rear) and
    ``offtracking_true_units`` (each further unit's true off-tracking, by its number).

    ## Starting State

    The scenario's: the driver's control point at the start of the path, straight, at the profile's speed,
    trailer axles straight. Domain randomisation (``randomise``) draws friction, camber, speed, trailer
    load (``lst`` / ``lst-unladen``) and turn direction at every reset from ``np_random``, which also draws
    the sensor biases and seeds the run (signal noise, camera noise and scenery): by default the on-board
    signals carry data-sheet noise and a per-episode bias (:mod:`scenarios.envs.sensors`), so every seed
    gives a different episode.

    ## Episode End

    *Terminated*: jackknife (any towed unit's articulation against the unit ahead beyond
    ``max_articulation_deg``, or the model diverges), the driver's control point more than ``max_lateral_error``
    from its path, or any towed unit's ``|e_k| > max_offtracking`` (it leaves the road);
    ``info["termination_reason"]`` says which (:meth:`~scenarios.loop.ends.Limits.check_units`).
    *Truncated*: the driver reaches the end of the path
    (or the scenario's duration is up): about 1700 steps by default. The registered spec also truncates at
    ``max_episode_steps`` = :data:`MAX_EPISODE_STEPS` (100 s simulated): for a longer scenario pass a larger
    ``max_episode_steps`` to ``gymnasium.make`` (an episode cut by the time limit has no ``episode_summary``).

    ## Arguments

    ``TrailerSteeringEnv(config=None, render_mode=None, **settings)``: the environment's :attr:`config` is
    :meth:`default_config` updated by ``config`` (a mapping of the settings below, or a
    :class:`~scenarios.envs.scenario.ScenarioChoice` for the scenario ones) and then by the keywords, which is how
    ``gymnasium.make`` passes them; a key that is not a setting is refused, naming it and the allowed keys::

        gymnasium.make("offtrack/TrailerSteering-v0", scenario="roundabout-3", overrides={"path.turns": 0.25},
                       feedback="truth", vehicle="lst", action_mode="direct",
                       randomise={"mu": (0.1, 0.8), "camber_percent": (0, 5), "vehicle": ("lst", "lst-unladen")})
        TrailerSteeringEnv({"feedback": "zero_slip", "action_mode": "residual"})

    * ``scenario``, ``overrides``: catalogue scenario and dotted configuration fields (``offtrack run --set``).
    * ``feedback``: the first towed unit's estimate: ``truth``, ``zero_slip`` (Cheng, blind to slip), ``viso_ot``
      (renders the trailer's stereo camera and runs visual odometry: much slower, docs/environments.md) or
      ``viso_ot_fused`` (the same camera fused with the trailer's gyro and wheel speed in a Kalman filter, an estimate
      every control tick). On a longer combination each towed unit with a camera rig (``camera.rigs``; by default
      every one) has its own camera estimates.
    * ``rear_feedback``: the estimate of each towed unit behind the first, one per unit: ``none`` (not steered:
      its axles held straight, no action entry), ``truth``, ``zero_slip``, ``viso_ot`` or ``viso_ot_fused`` (of
      that unit, on its own camera); ``None`` (default):
      each one with a steerable axle on the kind of ``feedback``. The configuration's ``rear_feedback``
      (:mod:`scenarios.unit_feedback`), validated with its messages.
    * ``vehicle``, ``mu``, ``camber_percent``, ``camber_direction``, ``speed_kmh``, ``direction``: fixed settings
      (``None``: the scenario's).
    * ``randomise``: :class:`~scenarios.envs.scenario.DomainRandomisation` ranges. The vehicles of
      ``randomise["vehicle"]`` must have the same number of units and steer the same towed units (the spaces'
      shapes are fixed), or the environment is refused (:func:`~scenarios.envs.units.check_units`).
    * ``sensors``: ``datasheet`` (default: noise and bias of production sensors) or ``scenario`` (its own signals).
    * ``action_mode``, ``residual_scale_deg``, ``preview_distances``.
    * ``reward_weights`` (keys ``offtracking``, ``effort``, ``rate``), ``offtracking_tolerance`` [m],
      ``offtracking_clip``, ``termination_penalty``.
    * ``max_articulation_deg``, ``max_lateral_error`` [m], ``max_offtracking`` [m or None].
    * ``render_mode``: ``"rgb_array"``: a plan view around the trailer (``render_size`` pixels, ``render_span``
      metres wide, with a scale bar), with the trailer camera's left image beneath it when ``viso_ot`` renders.
      ``"human"`` is refused (a headless co-simulation has no window: show the ``rgb_array`` frames yourself).

    Every argument is validated at construction (``gymnasium.make``) with the configuration schema's messages
    (:func:`~scenarios.envs.validation.check_choice`; :class:`~vehicle_model.errors.InputError` or
    :class:`~scenarios.config.ConfigError` naming the argument), randomisation ranges at both ends.

    Every setting except the reward and action settings can also be given for one episode in
    ``reset(options=...)`` (:data:`~scenarios.envs.scenario.OPTION_KEYS`); one that would change the units (a
    vehicle with other units steered) is refused.

    Attributes
    ----------
    config : dict
        Every setting the environment was made with (:meth:`default_config`'s keys).
    choice : ScenarioChoice
        Its scenario settings.
    units : EnvUnits
        The combination's number of units and its steered towed units with their estimates
        (:class:`~scenarios.envs.units.EnvUnits`).
    n_steered : int
        Steered towed units: the action's length.
    observation_names : tuple of str
        The name of every observation entry.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 50}

    @classmethod
    def default_config(cls) -> dict[str, Any]:
        """Every setting of the environment and its default (the keys its ``config`` and keywords take).

        The scenario settings (:func:`~scenarios.envs.env_config.scenario_defaults`), then ``action_mode``,
        ``residual_scale_deg``, ``preview_distances``, ``reward_weights`` (``None``: :data:`REWARD_WEIGHTS`),
        ``offtracking_tolerance``, ``offtracking_clip``, ``termination_penalty``, the limits ``max_articulation_deg``,
        ``max_lateral_error``, ``max_offtracking``, and the picture's ``render_size`` and ``render_span``.
        """
        return {
            **scenario_defaults(),
            "action_mode": "direct",
            "residual_scale_deg": 5.0,
            "preview_distances": PREVIEW_DISTANCES,
            "reward_weights": None,
            "offtracking_tolerance": OFFTRACKING_TOLERANCE,
            "offtracking_clip": OFFTRACKING_CLIP,
            "termination_penalty": 10.0,
            "max_articulation_deg": ENVIRONMENT_LIMITS.max_articulation_deg,
            "max_lateral_error": ENVIRONMENT_LIMITS.max_lateral_error,
            "max_offtracking": ENVIRONMENT_LIMITS.max_offtracking,
            "render_size": (400, 400),
            "render_span": 50.0,
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
        action_mode, residual_scale_deg = cfg["action_mode"], cfg["residual_scale_deg"]
        if action_mode not in ("direct", "residual"):
            raise InputError(f"action_mode = {action_mode!r} must be 'direct' or 'residual'")
        self.action_mode = action_mode
        if not (residual_scale_deg > 0 and math.isfinite(residual_scale_deg)):
            raise InputError(f"residual_scale_deg = {residual_scale_deg!r} must be a finite number > 0")
        self.residual_scale = math.radians(residual_scale_deg)
        preview_distances = cfg["preview_distances"]
        self.preview_distances = np.asarray(preview_distances, dtype=float)
        if self.preview_distances.ndim != 1 or not np.all(np.isfinite(self.preview_distances)):
            raise InputError(f"preview_distances = {preview_distances!r} must be a sequence of distances [m]")
        self.reward = SteeringReward(
            dict(cfg["reward_weights"] or {}),
            cfg["offtracking_tolerance"],
            cfg["offtracking_clip"],
            cfg["termination_penalty"],
        )
        self.reward_weights = dict(self.reward.weights)
        self.limits = Limits(
            cfg["max_articulation_deg"], cfg["max_lateral_error"], cfg["max_offtracking"], every_unit=True
        )
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.render_size = (int(cfg["render_size"][0]), int(cfg["render_size"][1]))
        self.render_span = float(cfg["render_span"])

        self.action_space = spaces.Box(-1.0, 1.0, shape=(self.n_steered,), dtype=np.float32)
        self.observation_space, self.observation_names = observation_layout(self.units.further, self.preview_distances)

        self._cosim: CoSimulation | None = None
        self._controllers: tuple[TrailerSteeringController, ...] = ()
        self._episode_units = self.units
        self._feedback = self.choice.feedback
        self._done = False
        self._tracks: tuple[list[np.ndarray], list[np.ndarray]] = ([], [])
        self._returns: dict[str, float] = {}
        self._steps = 0
        self.episode_settings: dict[str, Any] = {}

    # ------------------------------------------------------------------ Gymnasium API

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        """Start an episode; ``options`` override the environment's scenario settings for this episode."""
        super().reset(seed=seed)
        choice = self.choice.with_options(options)
        if options:
            check_choice(choice)
            episode = check_units(choice)
            if not episode.same_shape(self.units):
                raise InputError(
                    f"reset options: {episode.describe()}; this environment's spaces need {self.units.describe()} "
                    "(make a new environment for it)"
                )
        config, settings = choice.resolve(self.np_random)
        units = check_episode_units(self.units, config)
        setup = rebuild_setup(config)
        settings_si = config.controller.path_following(config.rates.control_hz)
        agent = AgentSteer(setup.params, settings_si, units.units, trailer_axles(setup))
        self._cosim = CoSimulation(setup, agent, limits=self.limits)
        self._episode_units = units
        self._feedback = config.feedback
        self._controllers = (
            tuple(
                TrailerSteeringController(setup.params, unit_settings, unit)
                for unit, unit_settings in zip(
                    units.units, config.controller.unit_settings(config.rates.control_hz, len(units.units)), strict=True
                )
            )
            if self.action_mode == "residual"
            else ()
        )
        self._max_steer = settings_si.max_steer
        self._max_rate = settings_si.max_steer_rate
        self._previous_action = np.zeros(self.n_steered)
        self._pid_virtual = np.zeros(self.n_steered)
        self._done = False
        self.episode_settings = settings
        self._tracks = ([], [])
        self._returns = {}
        self._steps = 0
        self._after_tick()
        return self._observation(), dict(settings)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Steer for one control period: ``action`` holds one entry per steered towed unit, front to rear."""
        cosim, agent = self._cosim, self._agent
        if cosim is None or agent is None:
            raise gym.error.ResetNeeded("call reset() before step()")
        if self._done:
            raise gym.error.ResetNeeded("the episode has ended; call reset()")
        n = self.n_steered
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.size != n or not np.all(np.isfinite(a)):
            wanted = "one finite number" if n == 1 else f"{n} finite numbers (one per steered towed unit)"
            raise InputError(f"action = {action!r} must be {wanted} in [-1, 1]")
        a_values = np.clip(a, -1.0, 1.0)
        if self.action_mode == "residual":
            virtual = self._pid_virtual + a_values * self.residual_scale
        else:
            virtual = a_values * self._max_steer
        previous = agent.steered_commands
        agent.request(virtual)
        tick = cosim.tick
        reason = ""
        try:
            tick = cosim.step()
        except SimulationDivergedError:
            reason = StopReason.DIVERGED
        if not reason and cosim.breach is not None:
            reason = cosim.breach.reason
        commands = agent.commands.copy()
        terminated = bool(reason)
        truncated = not terminated and cosim.finished
        self._done = terminated or truncated
        self._previous_action = a_values

        units = self._episode_units
        truth_keys = tuple(estimate_key("truth", unit) for unit in units.units)
        parts = self.reward.parts(
            cosim, agent.steered_commands, previous, self._max_steer, self._max_rate, reason, truth_keys
        )
        reward = float(sum(parts.values()))
        if not terminated:
            self._after_tick()
        truth = tick.estimates["truth"]
        estimate = tick.estimates.get(self._feedback)
        info: dict[str, Any] = {
            "time": float(tick.time),
            "offtracking_true": truth.value if truth.available else None,
            "offtracking_estimate": estimate.value if estimate is not None and estimate.available else None,
            "virtual_steer": agent.virtual_steer,
            "trailer_steer": commands,
            "path_progress": float(cosim.driver.progress),
            "lateral_error": float(cosim.driver.lateral_error),
            "termination_reason": str(reason),
            **parts,
        }
        if units.n_units > 2:
            info["virtual_steers"] = agent.virtual_steers
            info["offtracking_true_units"] = {
                str(unit): _value(tick.estimates.get(estimate_key("truth", unit - 1))) for unit in units.further
            }
        for key, value in parts.items():
            self._returns[key] = self._returns.get(key, 0.0) + float(value)
        self._steps += 1
        if self._done:
            cosim.finish()
            info["episode_summary"] = episode_summary(cosim, str(reason), self._returns, self._steps)
            info["config"] = cosim.setup.config.model_dump(mode="json")
        return self._observation(), reward, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """The plan view (and the trailer camera's view when ``viso_ot`` renders) as uint8 ``H×W×3``."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; create the env with render_mode='rgb_array'")
            return None
        cosim = self._cosim
        if cosim is None:
            raise gym.error.ResetNeeded("call reset() before render()")
        setup, tick = cosim.setup, cosim.tick
        truth = tick.estimates["truth"]
        kingpins, follows = self._tracks
        agent = self._agent
        image = draw_plan_view(
            setup.params,
            tick.state,
            setup.path.points,
            kingpin_track=np.array(kingpins),
            follow_track=np.array(follows),
            trailer_steer=agent.commands if agent is not None else (),
            trailer_axles=cosim.trailer_axles,
            span=self.render_span,
            size=self.render_size,
            text=(
                f"t {tick.time:5.1f} s  u {tick.state.u * 3.6:4.1f} km/h",
                "e_tr " + (f"{truth.value:+.3f} m" if truth.available else "  n/a"),
                f"steer {math.degrees(agent.virtual_steer if agent is not None else 0.0):+.1f} deg",
            ),
        )
        camera = cosim.camera
        if camera is not None:
            image = np.vstack([image, camera_strip(camera.view_image(tick.state.pose), image.shape[1])])
        return image

    def close(self) -> None:
        """Drop the run (and its camera pipeline, if any)."""
        if self._cosim is not None:
            self._cosim.close()
        self._cosim = None
        self._controllers = ()

    # ------------------------------------------------------------------ internals

    @property
    def _agent(self) -> AgentSteer | None:
        """The episode's trailer-steer source: the agent's actions through the controller's output stages."""
        return None if self._cosim is None else self._cosim.trailer_steer  # type: ignore[return-value]

    def _after_tick(self) -> None:
        """What the agent sees with a new tick: the PIDs' proposals (residual mode) and the render tracks."""
        cosim = self._cosim
        assert cosim is not None
        tick = cosim.tick
        lateral, wheel = hold_signals(tick.measured)  # as the run's PathFollowingSteer passes them
        for i, (ctrl, (_, key)) in enumerate(zip(self._controllers, self._episode_units.steered, strict=False)):
            ctrl(tick.state, tick.estimates.get(key), lateral, wheel)
            self._pid_virtual[i] = ctrl.virtual_steer
        if self.render_mode is not None:
            self._tracks[0].append(tick.kingpin)
            self._tracks[1].append(
                follow_point_from_kingpin(tick.kingpin, tick.state.psi2, cosim.setup.params.follow_point_offset)
            )

    def _steer_entries(self, agent: AgentSteer, towed: int) -> list[float]:
        """Previous virtual steer, previous action and PID virtual steer of towed unit ``towed`` (0 if not steered)."""
        units = self._episode_units.units
        if towed not in units:
            return [0.0, 0.0, 0.0]
        i = units.index(towed)
        return [agent.outputs[i].virtual_steer, float(self._previous_action[i]), float(self._pid_virtual[i])]

    def _observation(self) -> np.ndarray:
        cosim, agent = self._cosim, self._agent
        assert cosim is not None and agent is not None
        tick = cosim.tick
        m = tick.measured
        estimate = tick.estimates.get(self._feedback)
        valid = estimate is not None and estimate.available
        path = cosim.setup.path
        ahead = np.clip(cosim.driver.progress + self.preview_distances, 0.0, path.length)
        curvature = np.interp(ahead, path.s, path.curvature)
        further: list[float] = []
        units = self._episode_units
        keys = dict(units.steered)
        rates = tick.state.towed_yaw_rates
        for unit in units.further:
            key = keys.get(unit - 1)
            unit_estimate = tick.estimates.get(key) if key is not None else None
            unit_valid = unit_estimate is not None and unit_estimate.available
            further += [
                unit_estimate.value if unit_valid else 0.0,  # type: ignore[union-attr]
                1.0 if unit_valid else 0.0,
                m["rear_articulation"][unit - 3],
                rates[unit - 2],
                *self._steer_entries(agent, unit - 1),
            ]
        obs = np.concatenate(
            [
                [
                    estimate.value if valid else 0.0,  # type: ignore[union-attr]
                    1.0 if valid else 0.0,
                    m["articulation"][0],
                    m["wheel_speed"][0],
                    m["tractor_yaw_rate"][0],
                    m["trailer_yaw_rate"][0],
                    *self._steer_entries(agent, 1),
                ],
                further,
                curvature,
            ]
        ).astype(np.float32)
        return np.clip(obs, self.observation_space.low, self.observation_space.high)


def _value(estimate: OfftrackingEstimate | None) -> float | None:
    """An estimate's value, or ``None`` when it has none."""
    return estimate.value if estimate is not None and estimate.available else None
