"""``offtrack/TrailerSteering-v0``: steer the trailer's axles one control period at a time."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from controller.path_following import TrailerSteeringController
from vehicle_model.errors import InputError, SimulationDivergedError
from vehicle_model.geometry import follow_point_from_kingpin

from ..loop.cosimulation import CoSimulation
from ..loop.ends import ENVIRONMENT_LIMITS, Limits
from ..loop.trailer_steer import AgentSteer
from ..setup.models import rebuild_setup
from .plan_view import camera_strip, check_render_mode, draw_plan_view
from .reward import OFFTRACKING_CLIP, OFFTRACKING_TOLERANCE, REWARD_WEIGHTS, SteeringReward, episode_summary
from .scenario import DEFAULT_OVERRIDES, DEFAULT_SCENARIO, DomainRandomisation, FeedbackSource, ScenarioChoice
from .sensors import SensorMode
from .validation import check_choice

__all__ = ["MAX_EPISODE_STEPS", "OBSERVATION_NAMES", "REWARD_WEIGHTS", "TrailerSteeringEnv"]

MAX_EPISODE_STEPS = 5000
"""``max_episode_steps`` of the registered spec: 100 s simulated (the default episode is about 1700 steps)."""

PREVIEW_DISTANCES: tuple[float, ...] = (0.0, 10.0, 20.0, 30.0)
"""Default path-curvature preview distances ahead of the driver's control point [m]."""

_BASE_OBSERVATION: tuple[tuple[str, float], ...] = (
    ("offtracking_estimate", 5.0),
    ("estimate_valid", 1.0),
    ("articulation", math.pi),
    ("wheel_speed", 30.0),
    ("tractor_yaw_rate", 6.0),
    ("trailer_yaw_rate", 6.0),
    ("previous_virtual_steer", math.pi / 2),
    ("previous_action", 1.0),
    ("pid_virtual_steer", math.pi / 2),
)
_CURVATURE_BOUND = 0.25  # [1/m]: the configuration's smallest path radius is 5 m

OBSERVATION_NAMES: tuple[str, ...] = tuple(name for name, _ in _BASE_OBSERVATION)
"""Names of the leading observation entries; ``curvature_ahead_<d>m`` entries follow, one per preview distance."""


class TrailerSteeringEnv(gym.Env[np.ndarray, np.ndarray]):
    """Steer the trailer of a tractor–semi-trailer so that its rear follows the tractor's kingpin path.

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

    ## Action Space

    ``Box(-1, 1, (1,), float32)``, normalised:

    * ``action_mode="direct"``: the virtual-axle steer ``δ_v = a·δ_max`` (``δ_max`` = ``controller.max_steer_deg``,
      25° by default);
    * ``action_mode="residual"``: a correction added to the PID's virtual-axle steer
      (:class:`~controller.path_following.TrailerSteeringController` fed by ``feedback``),
      ``δ_v = δ_PID + a·residual_scale_deg``; ``a = 0`` reproduces the PID exactly.

    ## Observation Space

    ``Box(float32)`` of ``9 + len(preview_distances)`` entries, what the vehicle can know (measured signals,
    the chosen estimate, the map), clipped to finite bounds:

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
    | 9… | ``curvature_ahead_<d>m``: path curvature ``d`` metres ahead of the driver's control point | 1/m | ±0.25 |

    ## Rewards

    From the **true** off-tracking ``e`` after the step and the applied axle commands ``δ_j``, per step::

        r = −w_e·min(|e|/e_tol, c_max) − w_u·mean_j (δ_j/δ_max)² − w_du·mean_j (Δδ_j/(δ̇_max·Δt))²

    ``e_tol = 0.10 m`` (the off-tracking target), ``c_max = 10``, weights :data:`REWARD_WEIGHTS` (``w_e = 1``,
    ``w_u = w_du = 0.01``): the off-tracking term is about 99 % of the designed PID's return. On termination
    the worst per-step cost for every step left, plus ``termination_penalty``, is charged as well
    (:mod:`scenarios.envs.reward`). The parts are in ``info`` as ``reward_offtracking``, ``reward_effort``,
    ``reward_rate``, ``reward_termination``; the final step's ``info["episode_summary"]`` holds the episode in
    the figures of ``metrics.json`` (true off-tracking RMS and largest after warm-up, saturated fraction,
    termination reason, the return and its parts) and ``info["config"]`` the configuration it ran.

    ## Starting State

    The scenario's: the driver's control point at the start of the path, straight, at the profile's speed,
    trailer axles straight. Domain randomisation (``randomise``) draws friction, camber, speed, trailer
    load (``lst`` / ``lst-unladen``) and turn direction at every reset from ``np_random``, which also draws
    the sensor biases and seeds the run (signal noise, camera noise and scenery): by default the on-board
    signals carry data-sheet noise and a per-episode bias (:mod:`scenarios.envs.sensors`), so every seed
    gives a different episode.

    ## Episode End

    *Terminated*: jackknife (``|Γ| > max_articulation_deg``, or the model diverges), the driver's control
    point more than ``max_lateral_error`` from its path, or ``|e| > max_offtracking`` (the trailer leaves
    the road); ``info["termination_reason"]`` says which. *Truncated*: the driver reaches the end of the path
    (or the scenario's duration is up): about 1700 steps by default. The registered spec also truncates at
    ``max_episode_steps`` = :data:`MAX_EPISODE_STEPS` (100 s simulated): for a longer scenario pass a larger
    ``max_episode_steps`` to ``gymnasium.make`` (an episode cut by the time limit has no ``episode_summary``).

    ## Arguments

    ```python
    gymnasium.make("offtrack/TrailerSteering-v0", scenario="roundabout-3", overrides={"path.turns": 0.25},
                   feedback="truth", vehicle="lst", action_mode="direct",
                   randomise={"mu": (0.1, 0.8), "camber_percent": (0, 5), "vehicle": ("lst", "lst-unladen")})
    ```

    * ``scenario``, ``overrides``: catalogue scenario and dotted configuration fields (``offtrack run --set``).
    * ``feedback``: ``truth``, ``zero_slip`` (Cheng, blind to slip), ``viso_ot`` (renders the trailer's
      stereo camera and runs visual odometry: about 10× slower) or ``viso_ot_fused`` (the same camera fused
      with the trailer's gyro and wheel speed in a Kalman filter, an estimate every control tick).
    * ``vehicle``, ``mu``, ``camber_percent``, ``camber_direction``, ``speed_kmh``, ``direction``: fixed settings
      (``None``: the scenario's).
    * ``randomise``: :class:`~scenarios.envs.scenario.DomainRandomisation` ranges.
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
    ``reset(options=...)`` (:data:`~scenarios.envs.scenario.OPTION_KEYS`).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 50}

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
        action_mode: Literal["direct", "residual"] = "direct",
        residual_scale_deg: float = 5.0,
        preview_distances: Sequence[float] = PREVIEW_DISTANCES,
        reward_weights: Mapping[str, float] | None = None,
        offtracking_tolerance: float = OFFTRACKING_TOLERANCE,
        offtracking_clip: float = OFFTRACKING_CLIP,
        termination_penalty: float = 10.0,
        max_articulation_deg: float = ENVIRONMENT_LIMITS.max_articulation_deg,
        max_lateral_error: float = ENVIRONMENT_LIMITS.max_lateral_error,
        max_offtracking: float | None = ENVIRONMENT_LIMITS.max_offtracking,
        render_mode: str | None = None,
        render_size: tuple[int, int] = (400, 400),
        render_span: float = 50.0,
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
        if action_mode not in ("direct", "residual"):
            raise InputError(f"action_mode = {action_mode!r} must be 'direct' or 'residual'")
        self.action_mode = action_mode
        if not (residual_scale_deg > 0 and math.isfinite(residual_scale_deg)):
            raise InputError(f"residual_scale_deg = {residual_scale_deg!r} must be a finite number > 0")
        self.residual_scale = math.radians(residual_scale_deg)
        self.preview_distances = np.asarray(preview_distances, dtype=float)
        if self.preview_distances.ndim != 1 or not np.all(np.isfinite(self.preview_distances)):
            raise InputError(f"preview_distances = {preview_distances!r} must be a sequence of distances [m]")
        self.reward = SteeringReward(
            dict(reward_weights or {}), offtracking_tolerance, offtracking_clip, termination_penalty
        )
        self.reward_weights = dict(self.reward.weights)
        self.limits = Limits(max_articulation_deg, max_lateral_error, max_offtracking)
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.render_size = (int(render_size[0]), int(render_size[1]))
        self.render_span = float(render_span)

        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        bounds = [b for _, b in _BASE_OBSERVATION] + [_CURVATURE_BOUND] * len(self.preview_distances)
        high = np.array(bounds, dtype=np.float32)
        low = -high
        low[1] = 0.0
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.observation_names = OBSERVATION_NAMES + tuple(f"curvature_ahead_{d:g}m" for d in self.preview_distances)

        self._cosim: CoSimulation | None = None
        self._controller: TrailerSteeringController | None = None
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
        config, settings = choice.resolve(self.np_random)
        setup = rebuild_setup(config)
        settings_si = config.controller.path_following(config.rates.control_hz)
        agent = AgentSteer(setup.params, settings_si)
        self._cosim = CoSimulation(setup, agent, limits=self.limits)
        self._controller = (
            TrailerSteeringController(setup.params, settings_si) if self.action_mode == "residual" else None
        )
        self._max_steer = settings_si.max_steer
        self._max_rate = settings_si.max_steer_rate
        self._previous_action = 0.0
        self._pid_virtual = 0.0
        self._done = False
        self.episode_settings = settings
        self._tracks = ([], [])
        self._returns = {}
        self._steps = 0
        self._after_tick()
        return self._observation(), dict(settings)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Steer for one control period."""
        cosim, agent = self._cosim, self._agent
        if cosim is None or agent is None:
            raise gym.error.ResetNeeded("call reset() before step()")
        if self._done:
            raise gym.error.ResetNeeded("the episode has ended; call reset()")
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.size != 1 or not np.isfinite(a[0]):
            raise InputError(f"action = {action!r} must be one finite number in [-1, 1]")
        a_value = float(np.clip(a[0], -1.0, 1.0))
        tick = cosim.tick
        if self.action_mode == "residual":
            virtual = self._pid_virtual + a_value * self.residual_scale
        else:
            virtual = a_value * self._max_steer
        previous = agent.commands.copy()
        agent.request(virtual)
        reason = ""
        try:
            tick = cosim.step()
        except SimulationDivergedError:
            reason = "diverged"
        if not reason and cosim.breach is not None:
            reason = cosim.breach.reason
        commands = agent.commands.copy()
        terminated = bool(reason)
        truncated = not terminated and cosim.finished
        self._done = terminated or truncated
        self._previous_action = a_value

        parts = self.reward.parts(cosim, commands, previous, self._max_steer, self._max_rate, reason)
        reward = float(sum(parts.values()))
        if not terminated:
            self._after_tick()
        truth = tick.estimates["truth"]
        estimate = tick.estimates.get(self.choice.feedback)
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
        self._controller = None

    # ------------------------------------------------------------------ internals

    @property
    def _agent(self) -> AgentSteer | None:
        """The episode's trailer-steer source: the agent's actions through the controller's output stage."""
        return None if self._cosim is None else self._cosim.trailer_steer  # type: ignore[return-value]

    def _after_tick(self) -> None:
        """What the agent sees with a new tick: the PID's proposal (residual mode) and the render tracks."""
        cosim = self._cosim
        assert cosim is not None
        tick = cosim.tick
        if self._controller is not None:
            self._controller(tick.state, tick.estimates.get(self.choice.feedback))
            self._pid_virtual = self._controller.virtual_steer
        if self.render_mode is not None:
            self._tracks[0].append(tick.kingpin)
            self._tracks[1].append(
                follow_point_from_kingpin(tick.kingpin, tick.state.psi2, cosim.setup.params.follow_point_offset)
            )

    def _observation(self) -> np.ndarray:
        cosim, agent = self._cosim, self._agent
        assert cosim is not None and agent is not None
        tick = cosim.tick
        m = tick.measured
        estimate = tick.estimates.get(self.choice.feedback)
        valid = estimate is not None and estimate.available
        path = cosim.setup.path
        ahead = np.clip(cosim.driver.progress + self.preview_distances, 0.0, path.length)
        curvature = np.interp(ahead, path.s, path.curvature)
        obs = np.concatenate(
            [
                [
                    estimate.value if valid else 0.0,  # type: ignore[union-attr]
                    1.0 if valid else 0.0,
                    m["articulation"][0],
                    m["wheel_speed"][0],
                    m["tractor_yaw_rate"][0],
                    m["trailer_yaw_rate"][0],
                    agent.virtual_steer,
                    self._previous_action,
                    self._pid_virtual,
                ],
                curvature,
            ]
        ).astype(np.float32)
        return np.clip(obs, self.observation_space.low, self.observation_space.high)
