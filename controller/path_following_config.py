"""Settings of the path-following trailer steering: PID gains, their pole placement and speed schedule, the config."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from vehicle_model.errors import InputError
from vehicle_model.settings import Settings

__all__ = [
    "FeedForward",
    "HighSpeedMode",
    "HoldKingpin",
    "Kinematics",
    "PathFollowingConfig",
    "PathFollowingGains",
    "UncertainFeedback",
    "bandwidth_schedule",
    "kinematic_pole_placement",
]

Kinematics = Literal["signals", "truth"]
"""Type of :attr:`PathFollowingConfig.kinematics`."""

FeedForward = Literal["path", "steady", "none"]
"""Type of :attr:`PathFollowingConfig.feedforward`."""

HoldKingpin = Literal["zero_slip", "lateral_acceleration", "wheel_speeds"]
"""Type of :attr:`PathFollowingConfig.friction_hold_kingpin`."""

UncertainFeedback = Literal["drop", "shrink", "taper"]
"""Type of :attr:`PathFollowingConfig.uncertain_feedback`."""

HighSpeedMode = Literal["unsteered", "stability"]
"""Type of :attr:`PathFollowingConfig.high_speed_mode`."""

ReachFreezeAt = Literal["feedforward", "lock", "exit"]
"""Type of :attr:`PathFollowingConfig.reach_freeze_at`."""


class PathFollowingGains(Settings):
    """PID gains on the off-tracking error, per unit distance travelled.

    Parameters
    ----------
    kp : float
        Proportional gain [rad/m] (virtual-axle steer per metre of off-tracking).
    ki : float
        Integral gain [rad/m²] on ``∫e_tr ds`` (``s`` the distance travelled); ``u·ki`` in time.
    kd : float
        Derivative gain [rad] on ``de_tr/ds``; ``kd/u`` in time.
    """

    kp: float = Field(ge=0.0)
    ki: float = Field(0.0, ge=0.0)
    kd: float = Field(0.0, ge=0.0)

    def in_time(self, speed: float) -> tuple[float, float, float]:
        """Time-domain equivalents ``(k_p, u·k_i, k_d/u)`` at forward speed ``speed`` [m/s] > 0."""
        if not speed > 0:
            raise InputError(f"speed = {speed!r} must be > 0")
        return self.kp, self.ki * speed, self.kd / speed


def kinematic_pole_placement(
    virtual_axle_distance: float, follow_point_offset: float, natural_frequency: float, damping: float
) -> PathFollowingGains:
    """PI gains placing the poles of the kinematic off-tracking loop in the distance domain.

    With ``de/ds = −e/L_v − (L_fp/L_v)·δ_v`` and ``δ_v = k_p·e + k_i·∫e ds`` the closed loop is
    ``σ² + ((1 + k_p L_fp)/L_v)·σ + k_i L_fp/L_v = 0`` (docs/vehicle_dynamics.md §7.3), so::

        k_p = (2ζω_n L_v − 1)/L_fp,   k_i = ω_n² L_v/L_fp

    ``k_p`` is clipped at zero when the open loop (pole ``1/L_v``) is already faster than asked.

    Parameters
    ----------
    virtual_axle_distance
        ``L_v`` [m].
    follow_point_offset
        ``L_fp`` [m].
    natural_frequency
        ``ω_n`` [1/m] (per metre travelled).
    damping
        ``ζ`` [-].

    Returns
    -------
    PathFollowingGains
        ``kd = 0``.
    """
    lv, lfp, wn, zeta = (float(x) for x in (virtual_axle_distance, follow_point_offset, natural_frequency, damping))
    if not (lv > 0 and lfp > 0 and wn > 0 and zeta > 0):
        raise InputError("kinematic_pole_placement needs L_v, L_fp, natural_frequency and damping all > 0")
    return PathFollowingGains(kp=max((2.0 * zeta * wn * lv - 1.0) / lfp, 0.0), ki=wn**2 * lv / lfp, kd=0.0)


def bandwidth_schedule(speed: float, bandwidth_speed: float | None) -> float:
    """Feedback gain factor ``f_hs = min(1, (u_b/u)²)`` of the high-speed schedule.

    Holds the kinematic loop's natural frequency in time above ``u_b`` (:mod:`controller.path_following`,
    *Gains and speed*).

    Parameters
    ----------
    speed
        Forward speed ``u`` [m/s].
    bandwidth_speed
        ``u_b`` [m/s]; ``None`` disables the schedule.

    Returns
    -------
    float
        ``f_hs`` in (0, 1].
    """
    if bandwidth_speed is None or speed <= bandwidth_speed:
        return 1.0
    return (bandwidth_speed / speed) ** 2


class PathFollowingConfig(Settings):
    """Settings of :class:`~controller.path_following.TrailerSteeringController` (SI units, angles in radians).

    Parameters
    ----------
    gains : PathFollowingGains or None
        PID gains per unit distance; ``None`` places the kinematic poles at ``natural_frequency`` and
        ``damping`` for the vehicle (:func:`kinematic_pole_placement`).
    natural_frequency : float
        ``ω_n`` [1/m] of the default design (docs/vehicle_dynamics.md §7.3 example: 1/3 m⁻¹).
    damping : float
        ``ζ`` of the default design.
    max_steer : float
        Per-axle steer limit [rad] (±25°; the roundabout test needs ±20–25°, docs/vehicle_dynamics.md §5.3).
    max_steer_rate : float
        Per-axle rate limit [rad/s] (20°/s).
    virtual_axle_distance : float or None
        ``L_v`` [m] behind the kingpin; ``None``: the trailer's equivalent wheelbase (all axles).
    fade_speeds : tuple of float
        ``(u0, u1)`` [m/s]: the command is zero below ``u0``, full above ``u1``, linear in between.
    bandwidth_speed : float or None
        Above this speed [m/s] the feedback is scaled by ``(bandwidth_speed/u)²`` (holds the loop's natural
        frequency in time; :mod:`controller.path_following`); ``None`` disables the schedule.
    feedforward : {"path", "steady", "none"}
        ``path``: the chord law on the kingpin path of the last trailer length (exact in transients, equal to
        the steady law in a steady turn); ``steady``: the steady law of docs/vehicle_dynamics.md §6.2 on the current
        ``κ5``; ``none``: feedback only.
    kinematics : {"signals", "truth"}
        Where ``κ5`` and the kingpin velocity direction come from (see :mod:`controller.path_following`).
    fixed_axle_compensation : bool
        Offset the steerable axles to cancel the yaw moment of unsteerable ones (:mod:`controller.path_following`).
    max_virtual_steer : float
        Clamp of the virtual-axle angle [rad] (keeps ``tan δ_v`` finite).
    derivative_min_distance : float
        Distance [m] that must separate two samples for a new derivative ``de/ds``.
    control_period : float
        Period [s] assumed on the first call (later ones use the difference of ``state.time``).
    feedback_max_std : float
        Largest standard deviation [m] of the fed-back estimate (the estimates' ``<feedback>_std``, given by the
        fused VISO-OT) at which it is used as given; above it ``uncertain_feedback`` says what is done with it. At
        0.075 m an estimate's 2σ reaches the 0.15 m largest off-tracking of the target (docs/design.md §11): less
        certain than that, it would steer the trailer by as much error as it removes.
    uncertain_feedback : {"taper", "drop", "shrink"}
        What the controller does with an estimate whose std ``σ`` exceeds ``feedback_max_std`` (``σ_max``); ``taper`` by
        default (no step in the command at the limit, so the loop's result does not turn on a rounding of ``σ``:
        docs/controller_design.md §3.3). ``drop``: feed-forward only, integrator frozen. ``shrink``: the estimate ``e``
        is kept as the posterior mean ``w·e``, ``w = σ_max²/(σ_max² + σ²)``, of the product of two Gaussians: the
        estimate (mean ``e``, std ``σ``) and zero off-tracking as a prior with std ``σ_max`` (the trailer on the path,
        as likely off as the largest error the controller trusts). The proportional and derivative terms act on ``w·e``
        and the integrator is frozen while ``w < 1``, so an uncertain error does not wind it up. At and below the limit
        ``w = 1``; just above it ``w`` starts at 1/2. ``taper``: the estimate is kept as ``w·e`` with the
        inverse-variance weight ``w = σ_max²/σ²`` (its weight as a measurement relative to one at the limit;
        docs/studies.md, *The fused-fed loop at the limit of the estimate's std*), and the integrator advances on
        ``w·e``: the command is continuous in ``σ`` across the limit (``w = 1`` there, no step), so an std that crosses
        the limit by a rounding moves the command by as little, and an estimate far off zero keeps steering while its
        std is above the limit. An estimate with no value is dropped in all three.
    high_speed_crossover : tuple of float or None
        ``(u_a, u_b)`` [m/s]: the command is full up to ``u_a`` and fades linearly to zero at ``u_b``, above which
        the trailer runs unsteered (:mod:`controller.path_following`, *Speed and objective*); ``None``: path
        following at every speed. The default, 35 to 55 km/h, starts above the speeds the catalogue's low-speed
        manoeuvres reach and ends where path following has raised rearward amplification well above the
        unsteered trailer's in the single lane change (docs/controller_design.md §3.5, *Speed: the crossover*).
    high_speed_mode : {"unsteered", "stability"}
        What the trailer's steering does above the crossover's lower speed, where path following fades out.
        ``unsteered`` (default): nothing, the axles go straight. ``stability``: a stability steer fades in on the
        same schedule, a gain-scheduled static feedback of the two yaw-rate gyros and the articulation designed
        on the linear tractor–semi-trailer to lower rearward amplification and raise yaw damping
        (:mod:`controller.high_speed`); on a longer combination one steer per steered unit from every unit's gyro and
        every articulation (:mod:`controller.high_speed_chain`). It needs ``high_speed_crossover``.
    max_slip_angle : float or None
        Largest slip angle ``|δ_j − β_j|`` [rad] a steerable axle is commanded to, ``β_j`` the direction of its
        velocity from the same kinematics as the feed-forward (:func:`~controller.axle_steer_distribution.
        axle_velocity_directions`), except that straight ahead is always allowed (the limit never steers an axle
        across it against the command; :func:`~controller.axle_steer_distribution.slip_angle_window`); the
        integrator freezes while every axle is held by it. ``None``: no limit.
        Beyond the Magic Formula's peak more steer gives *less* lateral force (on ice, μ = 0.1, the peak is at
        2.9° of slip; 16 % less force at 10°, 30 % less at 30°), so feedback that keeps pushing reverses its own
        sign and winds the axles to lock. The default, 8°, is a safeguard that does not need μ: on ice it stops
        an estimate a few centimetres off from walking the axles into that range (a fused-fed figure-of-eight on
        ice with camber under field conditions goes to lock and slides off the road without it), while the
        truth- and zero-slip-fed catalogue runs on dry, wet, snow and ice never reach it (the same numbers with
        and without; docs/field_bias.md §6.1). A lower limit binds on the dry roundabout test, where the
        fixed-axle compensation runs trailer2 at about 6° of slip beside trailer3 at lock, and costs off-tracking
        there; the dry tyre's peak is near 21° (docs/vehicle_dynamics.md §3.2), so 8° keeps most of its force.
    slip_window_holds_feedforward : bool
        Widen the slip-angle window to hold each axle's share of the feed-forward: the limit bounds what the
        feedback adds, never the path's own steer (:mod:`controller.reach_rules`). Off: the
        window of ``max_slip_angle`` alone.
    reach_freeze : bool
        Where the feed-forward is beyond the axles' reach, do not integrate an error on the outside of the turn
        (an outswing the lock's transient leaves, which the integral would otherwise carry into the cut-in that
        follows). Off: conditional integration on the limits only.
    reach_freeze_at : {"feedforward", "lock", "exit"}
        When the reach freeze holds an outswing's integral (default ``exit``). ``feedforward``: wherever the
        feed-forward is beyond reach, a guard against an outswing a sliding tractor's entry leaves at the lock.
        ``lock``: only while the command *with* that integral still holds an axle past its lock on the side the
        integral pushes away from, so that the integral's push cannot reach the output and would only gather
        behind the lock; where the feedback has brought the command back inside the lock the outswing is
        integrated, as any error is (docs/controller_design.md §3.5, §3.7). ``exit``: as ``lock``, and also
        wherever the kingpin's curvature has fallen below half its peak since the path went beyond reach (the
        turn's exit): where the axles never reach their lock (ice) ``lock`` integrates the outswing all round the
        turn and it unwinds as a cut-in at the exit; the outswing's integral belongs to the turn.
    max_outswing : float or None
        Bound [m] on the follow point's outswing (off-tracking on the outside of the kingpin's turn): the outward
        part of the virtual-axle command is scaled by ``clip((b − o)/b, 0, 1)`` for an outswing ``o`` of the estimate
        fed back, so the rear is never steered further out at the bound. ``None`` (default): no bound. It trades a
        larger cut-in later in a transient beyond reach for less outswing (docs/controller_design.md §3.5).
    preview_distance : float or None
        Preview ``d`` [m] of the feed-forward: the chord law of the configuration the trailer will have ``d`` metres
        further on, the kingpin extrapolated on its current curvature and the follow point's end of the chord on
        the recorded kingpin path (:mod:`controller.preview`). ``None`` (default): the chord law of the present
        configuration. Needs ``feedforward = "path"``. The reach (``beyond_reach``) stays judged on the present
        chord law: it says what the path needs, not what the preview asks for.
    slip_feedforward : bool
        Add to the feed-forward the steered axles' steady slip that carries the trailer's lateral force in the turn
        (:mod:`controller.feedforward_slip`). Off (default): the kinematic law alone. The reach stays judged on the
        kinematic law.
    friction_hold_slip : float or None
        Do not advance the integral where its push would steer further into its slip a steered axle whose slip
        angle, from the kinematics and the trailer's gyro (the measured yaw rate against the one its steer gives
        without slip), exceeds this [rad]: that axle is judged at its friction (:mod:`controller.friction_hold`).
        Not while a steered axle is at its lock. ``None`` (default): no such hold. A value near the ice tyre's force
        peak (2.8°, the lowest friction the controller is set up for) judges an axle at its friction only past the
        slip beyond which, on ice, more steer gives less force. The slip is off by the tractor's crab where the
        tractor slides (zero-slip kinematics).
    friction_hold_kingpin : {"zero_slip", "lateral_acceleration", "wheel_speeds"}
        The kingpin velocity the hold judges the slip from: ``zero_slip`` (default), the controller's own (as
        ``kinematics``); ``lateral_acceleration``, the tractor's lateral-accelerometer rear point's, which sees the
        tractor's crab (:func:`~controller.friction_hold.accelerometer_coupling_velocity`; it needs the tractor's
        lateral specific force on every call); ``wheel_speeds``, the kingpin's lateral velocity the trailer's wheel
        speed against the tractor's measures through the articulation, which sees the tractor's crab at its friction
        too (:func:`~controller.friction_hold.wheel_speed_coupling_velocity`; it needs both wheel speeds and the
        lateral specific force, below half the ice's ``μ·g`` of which the slip is not judged at friction). Only the
        hold uses it.
    """

    gains: PathFollowingGains | None = None
    natural_frequency: float = Field(1.0 / 3.0, gt=0.0)
    damping: float = Field(0.8, gt=0.0)
    max_steer: float = Field(math.radians(25.0), gt=0.0, le=math.radians(60.0))
    max_steer_rate: float = Field(math.radians(20.0), gt=0.0)
    virtual_axle_distance: float | None = Field(None, gt=0.0, le=50.0)
    fade_speeds: tuple[float, float] = (0.3, 1.0)
    bandwidth_speed: float | None = Field(15.0 / 3.6, gt=0.0)
    feedforward: FeedForward = "path"
    kinematics: Kinematics = "signals"
    fixed_axle_compensation: bool = True
    max_virtual_steer: float = Field(math.radians(45.0), gt=0.0, le=math.radians(80.0))
    derivative_min_distance: float = Field(0.05, ge=0.0)
    control_period: float = Field(0.02, gt=0.0, le=1.0)
    feedback_max_std: float = Field(0.075, gt=0.0)
    uncertain_feedback: UncertainFeedback = "taper"
    max_slip_angle: float | None = Field(math.radians(8.0), gt=0.0, le=math.radians(45.0))
    high_speed_crossover: tuple[float, float] | None = (35.0 / 3.6, 55.0 / 3.6)
    high_speed_mode: HighSpeedMode = "unsteered"
    slip_window_holds_feedforward: bool = True
    reach_freeze: bool = True
    reach_freeze_at: ReachFreezeAt = "exit"
    max_outswing: float | None = Field(None, gt=0.0, le=2.0)
    preview_distance: float | None = Field(None, ge=0.0, le=30.0)
    slip_feedforward: bool = False
    friction_hold_slip: float | None = Field(None, gt=0.0, le=math.radians(45.0))
    friction_hold_kingpin: HoldKingpin = "zero_slip"

    @model_validator(mode="after")
    def _ordered_fade_speeds(self) -> PathFollowingConfig:
        if self.preview_distance is not None and self.feedforward != "path":
            raise ValueError(f"preview_distance needs feedforward = 'path', not {self.feedforward!r}")
        lo, hi = self.fade_speeds
        if not 0 <= lo < hi:
            raise ValueError(f"fade_speeds = {self.fade_speeds!r} must satisfy 0 ≤ u0 < u1")
        if self.high_speed_crossover is not None:
            ua, ub = self.high_speed_crossover
            if not hi <= ua < ub:
                raise ValueError(
                    f"high_speed_crossover = {self.high_speed_crossover!r} must satisfy fade_speeds[1] ≤ u_a < u_b"
                )
        elif self.high_speed_mode != "unsteered":
            raise ValueError(f"high_speed_mode = {self.high_speed_mode!r} needs a high_speed_crossover, not None")
        return self
