"""Path-following trailer steering: a PID on the off-tracking error with curvature feed-forward.

The law (docs/vehicle_dynamics.md §6.2, §7.3; Cheng 2009, Jujnovich & Cebon 2013; Miao & Cebon 2014 feed the same
law an independent off-tracking measurement, here the caller picks the estimate by name)::

    δ_v = δ_ff(κ5) + f_hs(u)·[k_p·e + k_i·∫e ds + k_d·de/ds]          (virtual-axle steer)
    tan δ_j = tan δ_v + (L_v − L_j)·κ_c,   κ_c = (tan β_k − tan δ_v)/L_v   (common instantaneous centre)
    δ_j ← f(u) · δ_j,  then per-axle saturation ±δ_max, then rate limit ±δ̇_max

This module holds the per-tick controller (:class:`TrailerSteeringController`: hold, feed-forward, PID,
anti-windup). The kingpin's dead-reckoned path that the chord law reads is in :mod:`controller.kingpin_path`. Its
settings, gains, kinematic pole placement and speed schedule are in :mod:`controller.path_following_config`; the
virtual-axle distribution, the steady-turn steer and the per-axle limits are in
:mod:`controller.axle_steer_distribution`.

Sign convention (docs/design.md §6)
-----------------------------------
``e = e_tr`` is the off-tracking: the y coordinate (left positive), in the current trailer frame, of the
kingpin's past path at the follow-point station. An unsteered trailer in a left turn cuts in, so ``e < 0``:
the follow point lies left of (inside) the kingpin path and the trailer's rear must move **right**, which
a **negative** (rightward) steer of the rear axles does. Linearised on a straight path with the trailer
heading ψ2 relative to the kingpin path, ``e ≈ L_fp·ψ2`` and the virtual axle gives
``ψ̇2 = −(u/L_v)(ψ2 + δ_v)``, so

    de/ds = −e/L_v − (L_fp/L_v)·δ_v                                  (docs/vehicle_dynamics.md §7.3)

The path-following literature writes the same equation for the follow point's left-positive deviation
``e_f = −e_tr`` (docs/vehicle_dynamics.md §7.3); its law ``δ_v = δ_ff − PID(e_f)`` therefore reads
``δ_v = δ_ff + PID(e_tr)`` here, with **positive** gains.
A left turn with ``e_tr < 0`` gives a rightward (negative) correction; the mirrored right turn gives the
mirrored command.

Virtual axle and distribution: see :mod:`controller.axle_steer_distribution`.

Feed-forward
------------
*Steady law* (``feedforward = "steady"``). In a steady turn of kingpin radius ``R5 = 1/|κ5|`` the follow
point runs on the kingpin's circle when the trailer turns about the centre abreast of the midpoint between
kingpin and follow point (docs/vehicle_dynamics.md §6.2)::

    y_c = sign(κ5)·sqrt(R5² − L_fp²/4),   tan δ_ff = (L_fp/2 − L_v)/y_c
        = κ5·(L_fp/2 − L_v) / sqrt(1 − κ5²L_fp²/4)        (→ atan(κ5·(L_fp/2 − L_v)) for R5 ≫ L_fp)

The exact form is used: at the roundabout test's R5 ≈ 10 m the small-curvature form is 2° short. On the
current ``κ5`` this law is right only once the kingpin has driven one trailer length on the same curvature;
at the entry to and exit from a turn it steers too early (1.5 m of transient off-tracking on the roundabout
test without feedback).

*Chord law* (``feedforward = "path"``, default). The controller dead-reckons the kingpin path of the last
trailer length from the tractor's signals (heading from the yaw rate, kingpin velocity as below). The trailer
that tracks perfectly lies on the chord from the path point ``L_fp`` behind the kingpin (straight-line
distance) to the kingpin, heading ``ψ2*``; its kingpin moves along the path direction ``θ_k`` and its follow
point along the path direction ``θ_f`` at the chord's end. The rigid trailer's yaw rate is then
``r2 = v_k2x·(tan β_k* − tan φ_f*)/L_fp`` (velocity of the point ``(−L_fp, 0)``), and the virtual axle's
zero-slip angle (docs/vehicle_dynamics.md §2.3)::

    tan δ_ff = tan β_k* − (L_v/L_fp)·(tan β_k* − tan φ_f*),    β_k* = θ_k − ψ2*,  φ_f* = θ_f − ψ2*

It depends on the kingpin path only (not on the trailer's actual state, so the open loop keeps the trailer's
own decay ``1/L_v``), and in a steady turn (``β_k* = −φ_f* = asin(L_fp/2R5)``) it equals the steady law.
Before one trailer length has been recorded the path is taken as straight behind its oldest point.

Kinematics source: ``κ5``, the path direction and ``β_k`` come from the tractor's on-board quantities by
zero-slip kinematics (``kinematics = "signals"``: wheel speed ``u``, tractor yaw rate ``r1`` and articulation
``Γ``; the kingpin moves at ``(u, −e5·r1)`` in tractor axes with ``e5`` its offset behind the tractor's rear
point, docs/vehicle_dynamics.md §2.3, §7.2), read noise-free from the state the co-simulation passes; or from the true
state (``kinematics = "truth"``: kingpin velocity ``(u, v1 − h1·r1)``). ``κ5 = r1/|v_k|``. Either way the
feed-forward is blind to the trailer's own tyre slip; the feedback removes what it misses.

Gains and speed
---------------
Gains are per unit distance travelled: ``k_p`` [rad/m], ``k_i`` [rad/m²] on ``∫e ds``, ``k_d`` [rad] on
``de/ds``, so the kinematic closed loop has the same poles in distance at every speed. In time they are
``k_p``, ``u·k_i``, ``k_d/u``, and the loop's bandwidth in time grows with ``u``. With the camera's hold and
latency and the trailer's yaw mode (≈ 2.5 rad/s, ζ ≈ 0.5 at 80 km/h) the loop would lose its margins above
about 25 km/h and go unstable by 30–50 km/h (``docs/controller_design.md`` §5.2), so above ``bandwidth_speed``
(15 km/h) the feedback is scaled by ``f_hs = (bandwidth_speed/u)²``. That holds the natural frequency of the kinematic
loop in time, ``u·sqrt(f_hs·k_i·L_fp/L_v)``, at its value at ``bandwidth_speed`` (the loop becomes integral
dominated); phase margin ≥ 41° and gain margin ≥ 8.5 dB from 15 to 90 km/h with a 0.16 s dead time. The whole
command is faded in with speed, ``f(u) = clip((u − u0)/(u1 − u0), 0, 1)``, default zero below 0.3 m/s and
full above 1 m/s (and zero when reversing). The integral is over distance, so it stops by itself at
standstill. No high-speed fade-out is needed with the schedule.

Speed and objective
-------------------
Path following is a low-speed objective: at highway speed the off-tracking of any trailer is small, and what
matters is how the rear unit amplifies the tractor's lateral acceleration (rearward amplification) and how its sway
decays (yaw damping). A trailer that tracks the tractor's path through a lane change is asked to move its rear
sideways as fast as the tractor moves its front, and the feedback adds phase lag to the trailer's yaw mode, so
path following raises rearward amplification and lowers yaw damping at speed. The literature changes objective
with speed (Kural et al. 2017 schedule one controller from low-speed path following to high-speed rearward
amplification; Cheng et al. 2011 and Jujnovich & Cebon 2013 in full were not available here). This controller's
high-speed mode is the unsteered trailer: between the two speeds of ``high_speed_crossover`` the whole command
(feed-forward and feedback) fades linearly to zero, and above it the axles stay straight, so at speed the trailer
is never worse than unsteered; the integrator stops with the fade. The crossover's default and the measurements
behind it are in docs/controller_design.md (*Speed: the crossover*). With ``high_speed_mode = "stability"`` (opt-in)
a stability steer of the gyros and the articulations fades in on the same schedule, added to every axle's target
before the limits (:mod:`controller.high_speed`; on a longer combination :mod:`controller.high_speed_chain`).

Measurement timing: HOLD
------------------------
The controller runs every control period; an estimate may arrive less often (the camera rate) and late.
The controller holds the last estimate (zero-order hold). A new sample is recognised by a change of value
(or the first value after none); the derivative ``de/ds`` is computed from consecutive samples, over the
distance driven between them, only when a new sample arrives, and held in between. The hold and the latency
are treated as a dead time in the gain design (latency + half a camera period + half a control period), not
predicted away. A missing estimate (``None``: not yet one trailer length driven, or the estimator lost track) sets the
feedback to zero and freezes the integrator: the trailer is steered by the feed-forward alone until
estimates return.

Reach
-----
Where the chord law itself needs an axle past its lock, no feedback can hold the follow point on the kingpin's
path: the trailer cuts in by whatever the lock leaves. The controller flags those ticks, and the ticks after them
while every axle stays at its lock removing the error they left (``beyond_reach``, recorded as
``<prefix>beyond_reach``); the run reports their share of the path. Off-tracking there measures the manoeuvre,
not the controller.

Where the path is beyond reach an outswing (``e·κ5 > 0``) is not integrated while the command with it still holds
an axle past its lock, so that its push cannot reach the output, nor once the kingpin's curvature has fallen below
:data:`EXIT_CURVATURE_SHARE` of its peak since the path went beyond reach: the turn is ending, and an outswing
integrated there would unwind as a cut-in after it (``reach_freeze``, ``reach_freeze_at = "exit"``, the default;
``"lock"`` without the exit's hold; ``"feedforward"`` wherever the path is beyond reach), and ``max_outswing`` (off
by default) bounds it: :mod:`controller.reach_rules`.

Anti-windup
-----------
Conditional integration: the integral is not advanced when that would push the command further into a
limit that every steerable axle has reached (magnitude saturation or rate limit, in the direction of the
push; the distribution is monotone in ``δ_v``, so one direction serves all axles), nor while the virtual
angle is clamped. Without an integrator (``k_i = 0``) nothing winds up; the output leaves saturation as
soon as the proportional term does, at the rate limit. The slip-angle limit (``max_slip_angle``, 8° by default)
clips each axle to ``β_j ± α_max`` about its velocity's direction, widened to hold straight ahead and the
feed-forward's own steer (:mod:`controller.reach_rules`), before the magnitude limit, and counts as a limit here.
``β_j`` comes from zero-slip kinematics of the tractor's signals, wrong when its tyres slide (docs/controller_design.md
§3.5).
"""

from __future__ import annotations

import math

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.layout import Layout
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import VehicleState

from .axle_steer_distribution import slip_angle_window, steady_turn_tangents, tan_kingpin_direction
from .feedforward_slip import SlipFeedforward
from .friction_hold import (
    WheelSpeedKingpin,
    accelerometer_coupling_velocity,
    asks_for_friction,
    deepens_slip,
    steered_slip_angles,
)
from .high_speed import StabilitySteer
from .high_speed_chain import ChainStabilitySteer
from .kingpin_path import PATH_SPACING, DeadReckonedKingpinPath
from .path_following_config import PathFollowingConfig, bandwidth_schedule, kinematic_pole_placement
from .preview import preview_tangent
from .reach_rules import is_outswing, outswing_scale, window_holding
from .steer_output import OutputStep, TrailerSteerOutput, high_speed_fade, speed_fade

__all__ = ["TrailerSteeringController", "telemetry_prefix"]

EXIT_CURVATURE_SHARE = 0.5
"""Share of the peak kingpin curvature ``|κ5|`` since the path went beyond reach below which the turn counts as
ending (``reach_freeze_at = "exit"``): the outswing's integral belongs to the turn, so it is held from there."""


def telemetry_prefix(unit: int) -> str:
    """The prefix of a steered unit's recorded internals: ``trailer_`` for the first towed unit, ``unit<k>_`` for
    unit ``k`` of the combination behind it (``unit3_`` for the second towed unit)."""
    return "trailer_" if unit == 1 else f"unit{unit + 1}_"


class TrailerSteeringController:
    """Per-tick path-following trailer steering: ``controller(state, estimate) → axle commands``.

    Parameters
    ----------
    params : VehicleParams
        Vehicle; needs at least one steerable axle on the steered unit.
    config : PathFollowingConfig, optional
        Gains, limits, fades; defaults as documented there. Gains given there serve every unit; without them each
        unit's gains are placed for its own geometry (:func:`~.path_following_config.kinematic_pole_placement`).
    unit : int
        The steered towed unit: 1 the first (default), 2 the one it tows, … A unit behind the first follows its
        own coupling's path exactly as the first follows the kingpin's (the multi-trailer form of the law:
        each unit's "tractor" is the unit ahead, whose coupling motion comes down the chain,
        :meth:`~.steer_output.TrailerSteerOutput.coupling_motion`).

    Raises
    ------
    InputError
        When the unit has no steerable axle (the ``reference`` preset), or on a bad argument.

    Attributes
    ----------
    axle_names : tuple of str
        Steerable trailer axles, in the order of the returned commands (the model's layout order).
    gains : PathFollowingGains
        Gains in use.
    output : TrailerSteerOutput
        The output stage (distribution, fade, limits; :mod:`controller.steer_output`).
    virtual_steer : float
        Last virtual-axle angle ``δ_v`` [rad] before the speed fade (feed-forward + feedback, clamped).
    feedforward_steer, feedback_steer : float
        Its two parts [rad].
    commands : numpy.ndarray
        Last per-axle commands [rad] (after fade, saturation and rate limit).
    saturated : numpy.ndarray
        Per axle: the magnitude limit clipped the command on the last tick.
    rate_limited : numpy.ndarray
        Per axle: the rate limit clipped the command on the last tick.
    slip_limited : numpy.ndarray
        Per axle: the slip-angle limit (``config.max_slip_angle``) clipped the command on the last tick.
    integral : float
        ``∫e ds`` [m²].
    stability_steer : float or None
        Last high-speed stability steer [rad] added to every axle's target, faded (``config.high_speed_mode =
        "stability"`` above the crossover's lower speed; ``None`` otherwise).
    fade : float
        Last speed fade factor in [0, 1]: ``f(u)`` times the high-speed crossover's share
        (:func:`~.steer_output.high_speed_fade`).
    estimate : float or None
        The held off-tracking sample in use [m] (``None``: no estimate).
    feedback_weight : float
        Weight ``w`` in (0, 1] the last estimate was multiplied by (``config.uncertain_feedback`` ``"shrink"`` or
        ``"taper"``; 1 when it was used as given or there was none).
    new_sample : bool
        Whether the last tick received a new sample.
    kingpin_curvature : float
        Last ``κ5`` [1/m].
    beyond_reach : bool
        On the last tick the path's own steer (the feed-forward, which holds the follow point on the kingpin's
        path when the tyres do not slip) needed an axle past its lock, or every axle was still at its lock since
        such a tick: the path there is beyond the steering's reach
        (:meth:`~.steer_output.TrailerSteerOutput.beyond_reach`).

    Examples
    --------
    >>> ctrl = TrailerSteeringController(setup.params)  # doctest: +SKIP
    >>> commands = ctrl(tick.state, tick.estimates["truth"])  # doctest: +SKIP
    """

    def __init__(self, params: VehicleParams, config: PathFollowingConfig | None = None, unit: int = 1) -> None:
        self.params = params
        self.config = config if config is not None else PathFollowingConfig()
        if not 1 <= unit < params.n_units:
            raise InputError(f"unit {unit} is not a towed unit of {params.name!r} (1..{params.n_units - 1})")
        self.unit = unit
        self.prefix = telemetry_prefix(unit)
        layout = Layout.for_vehicle(params)
        towed = params.trailers[unit - 1]
        trailer_names = {a.name for a in towed.axles}
        self.axle_names: tuple[str, ...] = tuple(n for n in layout.steerable_axles if n in trailer_names)
        if not self.axle_names:
            raise InputError(
                f"vehicle {params.name!r} has no steerable axle on towed unit {unit}; path-following trailer "
                "steering needs at least one (use the 'lst' preset, or set steerable=True on trailer axles)"
            )
        cfg = self.config
        self.output = TrailerSteerOutput(params, cfg, unit)
        self.distribution = self.output.distribution
        self.follow_point_offset = towed.follow_point_offset
        self.virtual_axle_distance = self.distribution.virtual_axle_distance
        self.gains = (
            cfg.gains
            if cfg.gains is not None
            else kinematic_pole_placement(
                self.virtual_axle_distance, self.follow_point_offset, cfg.natural_frequency, cfg.damping
            )
        )
        self._steered_distances = self.distribution.distances[self.distribution.steerable]
        self.slip_feedforward = (  # the axles' steady slip in the turn (controller.feedforward_slip), opt-in
            SlipFeedforward(params, unit, self.distribution, cfg.max_slip_angle) if cfg.slip_feedforward else None
        )
        self.wheel_speed_kingpin = WheelSpeedKingpin(params, unit)  # the friction hold's, with wheel_speeds
        self.kingpin_path = DeadReckonedKingpinPath(self.follow_point_offset)  # the chord law's
        self.stability: StabilitySteer | ChainStabilitySteer | None = None  # the high-speed stability steer, opt-in
        if cfg.high_speed_mode == "stability" and cfg.high_speed_crossover is not None:
            kind = StabilitySteer if params.n_units == 2 else ChainStabilitySteer  # controller.high_speed(_chain)
            self.stability = kind(params, cfg.high_speed_crossover[0])
        self.reset()

    # ------------------------------------------------------------------ state

    def reset(self) -> None:
        """Straight axles, empty integrator, no held sample."""
        self.output.reset()
        if self.slip_feedforward is not None:
            self.slip_feedforward.reset()
        self.wheel_speed_kingpin.reset()
        self.feedforward_steer = 0.0
        self.feedback_steer = 0.0
        self.integral = 0.0
        self.fade = 0.0
        self.stability_steer: float | None = None
        self.estimate: float | None = None
        self.feedback_weight = 1.0
        self.new_sample = False
        self.kingpin_curvature = 0.0
        self.beyond_reach = False
        self._reach_peak_curvature = 0.0  # largest |κ5| since the path went beyond reach (zero within reach)
        self.distance = 0.0
        self._derivative = 0.0
        self._last_sample: tuple[float, float] | None = None  # (value, distance) of the previous new sample
        self.kingpin_path.reset()

    @property
    def commands(self) -> np.ndarray:
        """Last per-axle commands [rad]."""
        return self.output.commands

    @property
    def virtual_steer(self) -> float:
        """Last virtual-axle angle [rad] (clamped)."""
        return self.output.virtual_steer

    @property
    def saturated(self) -> np.ndarray:
        """Per axle: the magnitude limit clipped the last command."""
        return self.output.saturated

    @property
    def rate_limited(self) -> np.ndarray:
        """Per axle: the rate limit clipped the last command."""
        return self.output.rate_limited

    @property
    def slip_limited(self) -> np.ndarray:
        """Per axle: the slip-angle limit clipped the last command."""
        return self.output.slip_limited

    def telemetry(self) -> dict[str, float]:
        """Last tick's internals as floats, for recording (names prefixed by :func:`telemetry_prefix`; NaN = no
        estimate)."""
        p = self.prefix
        out = {
            f"{p}virtual_steer": self.virtual_steer,
            f"{p}feedforward_steer": self.feedforward_steer,
            f"{p}feedback_steer": self.feedback_steer,
            f"{p}integral": self.integral,
            f"{p}fade": self.fade,
            f"{p}estimate_used": math.nan if self.estimate is None else self.estimate,
            f"{p}beyond_reach": float(self.beyond_reach),
        }
        for name, sat, rate, slip in zip(
            self.axle_names, self.saturated, self.rate_limited, self.slip_limited, strict=True
        ):
            out[f"saturated_{name}"] = float(sat)
            out[f"rate_limited_{name}"] = float(rate)
            out[f"slip_limited_{name}"] = float(slip)
        return out

    # ------------------------------------------------------------------ the law

    def __call__(
        self,
        state: VehicleState,
        estimate: OfftrackingEstimate | None,
        lateral_acceleration: float = math.nan,
        wheel_speeds: tuple[float, float] = (math.nan, math.nan),
    ) -> np.ndarray:
        """Steer of every steerable trailer axle [rad] for the next control period.

        Parameters
        ----------
        state
            Current (true) state.
        estimate
            The off-tracking estimate fed back (``None``, or one without a value: feed-forward only, integrator
            frozen). An estimate whose standard deviation exceeds ``config.feedback_max_std`` is not used, or with
            ``config.uncertain_feedback = "shrink"`` is shrunk toward zero and the integrator frozen, or with
            ``"taper"`` weighted by ``(σ_max/σ)²``, the integrator advancing on the weighted error.
        lateral_acceleration
            The tractor's lateral specific force [m/s²] (signal ``tractor_lateral_acceleration``); read only by the
            friction hold with ``config.friction_hold_kingpin = "lateral_acceleration"``, which refuses a NaN (and
            with ``"wheel_speeds"``, which judges the slip only where it asks for the tyres' friction).
        wheel_speeds
            The tractor's and the first towed unit's wheel speeds [m/s] (signals ``wheel_speed``,
            ``trailer_wheel_speed``); read only by the friction hold with ``config.friction_hold_kingpin =
            "wheel_speeds"``, which refuses a NaN.

        Returns
        -------
        numpy.ndarray
            One angle per steerable trailer axle, in :attr:`axle_names` (layout) order.
        """
        cfg = self.config
        dt = self.output.period(state.time)

        # Kingpin motion: curvature κ5 and direction β_k in the trailer frame (docs/vehicle_dynamics.md).
        motion = self.output.coupling_motion(state)
        vx, vy = motion.vx, motion.vy
        speed = math.hypot(vx, vy)
        forward = state.u > 0.0
        self.kingpin_curvature = motion.tow_yaw_rate / speed if speed > 1e-6 else 0.0
        gamma, rate = motion.articulation, motion.yaw_rate
        slip_window = slip_angle_window(  # β_j ± α_max, from the same kinematics and the trailer's gyro
            self._steered_distances, gamma, vx, vy, rate, cfg.max_slip_angle, cfg.fade_speeds[1]
        )
        tan_kingpin = tan_kingpin_direction(gamma, vx, vy)
        ds = speed * dt if forward else 0.0
        self.distance += ds
        low_speed = speed_fade(state.u, cfg.fade_speeds)
        path_share = high_speed_fade(state.u, cfg.high_speed_crossover)
        self.fade = low_speed * path_share
        self.stability_steer = None
        if self.stability is not None and state.u > cfg.high_speed_crossover[0]:  # fades in as path following out
            share = low_speed * (1.0 - path_share)
            self.stability_steer = share * self._stability_command(state, motion.tow_yaw_rate, rate, gamma)

        # Feed-forward (the steady law in its exact form, or the chord law).
        self.kingpin_path.record(motion.tow_yaw_rate, vx, vy, dt, forward)
        if cfg.feedforward == "steady":
            tan_ff, _ = steady_turn_tangents(
                self.kingpin_curvature, self.follow_point_offset, self.virtual_axle_distance
            )
            self.feedforward_steer = math.atan(tan_ff)
        elif cfg.feedforward == "path":
            self.feedforward_steer = (
                math.atan(self.kingpin_path.chord_tangent(self.virtual_axle_distance)) if self.kingpin_path else 0.0
            )
        else:
            self.feedforward_steer = 0.0
        path_beyond_reach = self.fade > 0 and self.output.beyond_reach(self.feedforward_steer, tan_kingpin)
        if cfg.preview_distance is not None and self.kingpin_path:  # the chord law a preview distance ahead
            self.feedforward_steer = math.atan(
                preview_tangent(
                    self.kingpin_path.points,
                    self.kingpin_path.kingpin,
                    self.kingpin_curvature,
                    cfg.preview_distance,
                    self.follow_point_offset,
                    self.virtual_axle_distance,
                    PATH_SPACING,
                )
            )
        if self.slip_feedforward is not None and forward:  # plus the slip that carries the trailer's lateral force
            self.slip_feedforward.record(self.distance, self.kingpin_curvature)
            tan_ff = math.tan(self.feedforward_steer)
            tan_ff += self.slip_feedforward(self.distance, speed, tan_ff, tan_kingpin)
            self.feedforward_steer = math.atan(tan_ff)
        if slip_window is not None and cfg.slip_window_holds_feedforward:  # the path's own steer is never clipped
            virtual = min(max(self.feedforward_steer, -cfg.max_virtual_steer), cfg.max_virtual_steer)
            slip_window = window_holding(slip_window, self.fade * self.distribution(math.tan(virtual), tan_kingpin))

        wheel_kingpin = (vx, vy)  # the friction hold's kingpin from the wheel speeds, low-passed every tick
        if cfg.friction_hold_slip is not None and cfg.friction_hold_kingpin == "wheel_speeds":
            wheel_kingpin = self.wheel_speed_kingpin.update(state, wheel_speeds, lateral_acceleration, dt)

        # Feedback on the held sample.
        error = self._sample(estimate)
        ki = self.gains.ki
        schedule = bandwidth_schedule(state.u, cfg.bandwidth_speed)
        integral_new = self.integral
        reach_freeze = cfg.reach_freeze and path_beyond_reach and is_outswing(error, self.kingpin_curvature)
        curvature = abs(self.kingpin_curvature)
        self._reach_peak_curvature = max(self._reach_peak_curvature, curvature) if path_beyond_reach else 0.0
        turn_ending = curvature < EXIT_CURVATURE_SHARE * self._reach_peak_curvature
        frozen = reach_freeze and (
            cfg.reach_freeze_at == "feedforward" or (cfg.reach_freeze_at == "exit" and turn_ending)
        )
        # A shrunk (uncertain) estimate does not wind the integrator; a tapered one winds it by its weighted error.
        frozen = frozen or (self.feedback_weight < 1.0 and cfg.uncertain_feedback == "shrink")
        if error is not None and ki > 0 and self.fade > 0 and not frozen:
            integral_new = self.integral + error * ds

        feedback, step = self._command(integral_new, error, schedule, tan_kingpin, dt, slip_window)
        push = ki * (integral_new - self.integral)
        blocked = (push > 0 and step.blocked_up) or (push < 0 and step.blocked_down)
        if blocked or (reach_freeze and self.output.held_at_lock(step, push)):
            integral_new = self.integral  # conditional integration: do not wind up, nor gather behind the lock
            feedback, step = self._command(integral_new, error, schedule, tan_kingpin, dt, slip_window)
        elif cfg.friction_hold_slip is not None and not np.any(self.output.saturated):  # nor push an axle at its
            # friction further into its slip (at the lock the slip is the lock's geometry's, not the friction's)
            hold_vx, hold_vy, judged = vx, vy, True
            if cfg.friction_hold_kingpin == "lateral_acceleration":  # the kingpin velocity that sees the crab
                hold_vx, hold_vy = accelerometer_coupling_velocity(self.params, self.unit, state, lateral_acceleration)
            elif cfg.friction_hold_kingpin == "wheel_speeds":  # the crab the wheel speeds measure, where a slide
                hold_vx, hold_vy = wheel_kingpin  # at the friction is asked for
                judged = asks_for_friction(lateral_acceleration)
            slips = steered_slip_angles(
                self._steered_distances, self.output.commands, gamma, hold_vx, hold_vy, rate, cfg.fade_speeds[1]
            )
            slips = slips if judged else None
            if deepens_slip(slips, cfg.friction_hold_slip, push):
                integral_new = self.integral
                feedback, step = self._command(integral_new, error, schedule, tan_kingpin, dt, slip_window)
        self.integral = integral_new
        self.feedback_steer = feedback
        commands = self.output.commit(step)
        # Beyond reach: the path needs more than the lock, or the axles are still at their lock recovering from it.
        self.beyond_reach = path_beyond_reach or (self.beyond_reach and bool(np.all(self.output.saturated)))
        return commands

    def _stability_command(self, state: VehicleState, tow_yaw_rate: float, rate: float, gamma: float) -> float:
        """The unfaded stability steer [rad] of this unit: the semi-trailer's from its gyros ``r1`` (``tow_yaw_rate``),
        ``r2`` (``rate``) and ``Γ`` (``gamma``); a longer combination's, its row of every unit's gyro and
        articulation."""
        if isinstance(self.stability, StabilitySteer):
            return self.stability(state.u, tow_yaw_rate, rate, gamma)
        chain = self.stability
        steers = chain(state.u, [state.r1, *state.towed_yaw_rates], state.articulations)
        return float(steers[chain.units.index(self.unit)])

    def _command(
        self,
        integral: float,
        error: float | None,
        schedule: float,
        tan_kingpin: float,
        dt: float,
        slip_window: tuple[np.ndarray, np.ndarray] | None,
    ) -> tuple[float, OutputStep]:
        """The feedback term and the output stage's step for a given integral."""
        gains = self.gains
        fb = 0.0 if error is None else schedule * (gains.kp * error + gains.ki * integral + gains.kd * self._derivative)
        virtual = outswing_scale(self.feedforward_steer + fb, error, self.kingpin_curvature, self.config.max_outswing)
        return fb, self.output.propose(virtual, tan_kingpin, self.fade, dt, slip_window, self.stability_steer)

    def _sample(self, estimate: OfftrackingEstimate | None) -> float | None:
        """Zero-order hold of the estimate; derivative on new samples only. ``None`` if missing.

        An estimate whose std ``σ`` exceeds ``σ_max = config.feedback_max_std`` is dropped (``uncertain_feedback =
        "drop"``), shrunk (``"shrink"``) to the posterior mean ``w·e``, ``w = σ_max²/(σ_max² + σ²)``, of the
        product of the estimate's Gaussian (mean ``e``, std ``σ``) and a prior of zero off-tracking with std
        ``σ_max``, or tapered (``"taper"``) to ``w·e``, ``w = σ_max²/σ²``
        (:class:`~.path_following_config.PathFollowingConfig`); the hold and the derivative see ``w·e``.
        """
        self.new_sample = False
        self.feedback_weight = 1.0
        value: float | None = None if estimate is None else estimate.value
        std = math.nan if estimate is None else estimate.std
        max_std = self.config.feedback_max_std
        if math.isfinite(std) and std > max_std:
            if self.config.uncertain_feedback == "shrink":
                self.feedback_weight = max_std**2 / (max_std**2 + std**2)
            elif self.config.uncertain_feedback == "taper":
                self.feedback_weight = max_std**2 / std**2  # inverse-variance weight (PathFollowingConfig)
            else:
                value = None  # too uncertain (PathFollowingConfig.feedback_max_std): feed-forward only
        if value is None or not math.isfinite(value):
            self.feedback_weight = 1.0
            # Missing: feedback off, integrator frozen, derivative restarts when samples return.
            self.estimate = None
            self._last_sample = None
            self._derivative = 0.0
            return None
        value = float(value) if self.feedback_weight == 1.0 else self.feedback_weight * float(value)
        if self.estimate is None or value != self.estimate:
            self.new_sample = True
            if self._last_sample is not None:
                prev_value, prev_distance = self._last_sample
                travelled = self.distance - prev_distance
                if travelled > self.config.derivative_min_distance:
                    self._derivative = (value - prev_value) / travelled
                    self._last_sample = (value, self.distance)
            else:
                self._last_sample = (value, self.distance)
            self.estimate = value
        return self.estimate
