"""The noise model and tuning of the fused VISO-OT filter (:class:`~sensor.fusion.FusedVisoOt`; the equations each
field enters are stated in :mod:`sensor.fusion_model`, :mod:`sensor.fusion_slip` and :mod:`sensor.fusion_std`)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from vehicle_model.kinematics import RearPoint
from vehicle_model.settings import Settings

from .fusion_linked_rig import LinkedRigFusion

__all__ = [
    "AxialEffect",
    "FollowerLimit",
    "FusionNoise",
    "InnovationRatioFrom",
    "KinematicReference",
    "LinkedRigFusion",
    "PersistingReferenceError",
    "ReferenceTyre",
    "ScrubCouplingStd",
    "SideRigFusion",
]

KinematicReference = Literal[RearPoint, "trailer_lateral_acceleration"]
"""Where (K1)'s lateral velocity comes from: the tractor's signals with its rear point as
:data:`~vehicle_model.kinematics.RearPoint` says, or the unit's own accelerometer (:mod:`sensor.unit_slip_reference`,
which needs :attr:`~sensor.unit_kinematics.ChainSignals.unit_lateral_acceleration`)."""

AxialEffect = Literal["camera", "posterior"]
"""How the axial states' uncertainty enters the off-tracking's std (:mod:`sensor.fusion_axial`)."""
ScrubCouplingStd = Literal["release", "uniform"]
"""How the std's coupling term carries the coupled correction while the tyres scrub (:mod:`sensor.fusion_slip`)."""

InnovationRatioFrom = Literal["all", "lateral", "rear_lateral"]
"""What ``ρ`` of eq (5) (:mod:`sensor.fusion_std`) is the mean of over the window: ``"all"``, each motion's
normalised innovation squared over its three components; ``"lateral"``, three times that of its lateral component
given the other two (:func:`~sensor.fusion_std.lateral_nis`); ``"rear_lateral"``, ``"lateral"`` on a rig that looks
back along its unit and ``"all"`` on every other (:meth:`FusionNoise.for_camera` decides where the filter is built)."""


REFERENCE_SETTINGS: tuple[str, ...] = (
    "coupling_covariance_scale",
    "coupling_follower_limit",
    "coupling_scrub_scale",
    "coupling_axial_scale",
    "coupling_follower_share",
)
"""The side-rig settings the coupling reference takes (:mod:`sensor.fusion_coupling`), not the filter."""
FRICTION = "the lowest road μ the vehicle is specified for, (T3); 0.05 is glare ice, 1.5 a race track; null: none"
"""``reference_friction``'s description (:class:`FusionNoise`, :class:`SideRigFusion`)."""
ROAD_FRICTION = "the road's μ as the run states it, (T4) in the reference's mean; 0.05 is glare ice; null: none"
"""``reference_road_friction``'s description (:class:`FusionNoise`, :class:`SideRigFusion`)."""
ReferenceAxles = Literal["group", "each"]
"""How the ``trailer_lateral_acceleration`` reference's axles share the demand (:mod:`sensor.unit_slip_reference`):
the group at its demand ((T2)/(T4)) or each axle's brush tyre at its own slip angle ((T5))."""
ReferenceTyre = Literal["brush", "stated"]
"""The tyre of that reference's (T5) (:mod:`sensor.unit_slip_reference`): the brush tyre ((T3)) or the vehicle's
declared tyre ((T6), :mod:`sensor.reference_tyre`)."""
REFERENCE_BIAS = "[m/s²] std of the unit's accelerometer bias, (R1)'s floor in place of tractor_slip; null: none"
"""``reference_accelerometer_bias``'s description (:class:`FusionNoise`, :class:`SideRigFusion`)."""
BIAS_STD_SCALE = "factor on the std of eq (5)'s biases' term; 1: as the filter's P_b gives it, toward 0: none of it"
"""``bias_std_scale``'s description (:class:`FusionNoise`, :class:`SideRigFusion`)."""


class PersistingReferenceError(Settings):
    """The part of a following unit's measurement error that persists over frames, as a consider parameter of the
    off-tracking's std (:mod:`sensor.fusion_consider`): a first-order Gauss–Markov lateral error of the reference's
    increment.

    Parameters
    ----------
    share
        Its standard deviation as a share of the reference's own per-frame lateral standard deviation ((C2) of
        :mod:`sensor.fusion_coupling` before ``k_c``).
    correlation_time_s
        Its correlation time [s].
    gain
        Take the reference with the Schmidt–Kalman gain of this error (:mod:`sensor.fusion_schmidt`: less of a
        reference whose error persists); ``False`` (default): the filter's own gain, the error in the std alone.
    """

    share: float = Field(gt=0.0, le=1.0, description="of the per-frame lateral std; above 1 it is no longer a part")
    correlation_time_s: float = Field(
        gt=0.0, le=600.0, description="[s] of the Gauss–Markov error; 600 s is constant over any run"
    )
    gain: bool = False


class FollowerLimit(Settings):
    """What a following unit's measurement becomes while the follower's own tyres scrub (its axles at or near their
    lock), (C3) of :mod:`sensor.fusion_coupling`.

    Parameters
    ----------
    action
        ``inflate``: the follower's own off-tracking variance (its fused filter's std squared) added to the
        reference's lateral variance; ``refuse``: no measurement, the lead takes its own frame alone.
    demand
        The follower's scrub demand ``D`` of (K5) (:mod:`sensor.fusion_slip`) at its frame from which the action is
        taken.
    below
        What a frame below ``demand`` becomes: ``take`` (default: as (C2) gives it) or ``inflate`` (widened by the
        follower's own off-tracking variance as ``inflate`` widens a scrubbing frame; (C3') of
        :mod:`sensor.fusion_coupling`).
    """

    action: Literal["inflate", "refuse"]
    demand: float = Field(
        gt=0.0, le=1.0, description="the follower's scrub demand D from which it acts; 1: an axle at twice the onset"
    )
    below: Literal["take", "inflate"] = "take"


class SideRigFusion(Settings):
    """The settings a camera that looks across its motion (a side rig) takes in place of the section's (``None``: the
    section's own): the odometry's error along its optical axis as states (eq (3') of :mod:`sensor.fusion_model`,
    docs/field_bias.md §7) and the zero-slip kinematics they are found against.

    Parameters
    ----------
    vo_axial_flow, vo_axial_scale, vo_axial_scale_walk, vo_axial_effect, vo_yaw_lever, bias_std_scale
        As :class:`FusionNoise`'s.
    vo_covariance_scale
        As :class:`FusionNoise`'s: the factor on a side rig's motion covariance (``None``: the section's), for a
        side rig whose covariance model (``camera.rigs``' ``vo_covariance_model``) is not the other rigs'.
    kinematic_rear_point, reference_friction, reference_road_friction, reference_axles, reference_tyre,
    reference_accelerometer_bias, kinematic_error_model, coupling_reference, coupling_bias_share,
    coupling_persisting_error
        As :class:`FusionNoise`'s.
    coupling_covariance_scale
        Factor on the covariance of the following unit's measurement, (C2) of :mod:`sensor.fusion_coupling`
        (``None``: 1, the covariance as mapped). The reference takes it, not the filter: it is not among
        :meth:`given`'s settings.
    coupling_follower_limit
        The following unit's measurement widened by the follower's own error or refused while the follower's tyres
        scrub, (C3) of :mod:`sensor.fusion_coupling` (``None``: taken as (C2) gives it). The reference's, like
        ``coupling_covariance_scale``.
    coupling_scrub_scale
        ``k_s`` of (C2') of :mod:`sensor.fusion_coupling`: the following unit's measurement's covariance widened by
        ``1 + k_s·D`` at the follower's scrub demand ``D`` (``None``: 0, off). The reference's, like
        ``coupling_covariance_scale``.
    coupling_axial_scale
        (C0'') of :mod:`sensor.fusion_coupling`: the follower's estimate ``ŝ`` of its odometry's relative error along
        its optical axis (its filter's ``s_z``, eq (3') of :mod:`sensor.fusion_model`) taken out of each following
        frame before (C1), its variance added along the axis (``None``: off). Needs the follower's filter to hold
        ``s_z``: :class:`FusionNoise`'s ``vo_axial_scale`` above 0 (a following camera looks along its unit, so its
        filter takes the section's settings). The reference's, like ``coupling_covariance_scale``.
    coupling_follower_share
        (C4) of :mod:`sensor.fusion_coupling_share`: the following unit's measurement's lateral variance widened by
        the follower's own off-tracking variance in the share ``D`` (its scrub demand) its filter gives its tyres
        (``None``: on, the default; ``False``: off, the reference of (C2) alone). The reference's, like
        ``coupling_covariance_scale``.
    """

    vo_axial_flow: float | None = Field(None, ge=0.0, le=1.0, description="[1/m] start std of s_f; 1 /m: 1 m per m²")
    vo_axial_scale: float | None = Field(None, ge=0.0, le=0.5, description="start std of s_z; 0.5 halves the axis")
    vo_axial_scale_walk: float | None = Field(
        None, ge=0.0, le=0.1, description="[1/√m] their walk; 0.1 forgets in a metre"
    )
    vo_axial_effect: AxialEffect | None = None
    vo_yaw_lever: bool | None = None
    bias_std_scale: float | None = Field(None, gt=0.0, le=1.0, description=BIAS_STD_SCALE)
    vo_covariance_scale: float | None = Field(
        None, ge=1.0, le=1e4, description="on the side rig's VO covariance (a floor); 1e4: no VO"
    )
    kinematic_rear_point: KinematicReference | None = None
    reference_friction: float | None = Field(None, ge=0.05, le=1.5, description=FRICTION)
    reference_road_friction: float | None = Field(None, ge=0.05, le=1.5, description=ROAD_FRICTION)
    reference_axles: ReferenceAxles | None = None
    reference_tyre: ReferenceTyre | None = None
    reference_accelerometer_bias: float | None = Field(None, gt=0.0, le=1.0, description=REFERENCE_BIAS)
    kinematic_error_model: Literal["inflated", "state"] | None = None
    coupling_reference: bool | None = None
    coupling_bias_share: bool | None = None
    coupling_persisting_error: PersistingReferenceError | None = None
    coupling_covariance_scale: float | None = Field(
        None,
        ge=1.0,
        le=100.0,
        description="factor on (C2)'s covariance; below 1 claims a tighter sensor, 100 all but drops it",
    )
    coupling_follower_limit: FollowerLimit | None = None
    coupling_scrub_scale: float | None = Field(
        None, ge=0.0, le=100.0, description="(C2')'s k_s: the covariance × (1 + k_s·D); 100 all but drops it"
    )
    coupling_axial_scale: bool | None = None
    coupling_follower_share: bool | None = None

    @property
    def reference_covariance_scale(self) -> float:
        """The factor the coupling reference applies to (C2)'s covariance: :attr:`coupling_covariance_scale`, 1
        when unset."""
        return 1.0 if self.coupling_covariance_scale is None else self.coupling_covariance_scale

    @property
    def reference_scrub_scale(self) -> float:
        """``k_s`` of (C2') the coupling reference takes: :attr:`coupling_scrub_scale`, 0 (off) when unset."""
        return 0.0 if self.coupling_scrub_scale is None else self.coupling_scrub_scale

    @property
    def reference_axial_scale(self) -> bool:
        """Whether the coupling reference takes the follower's ``ŝ`` out, (C0''): :attr:`coupling_axial_scale`, off
        when unset."""
        return bool(self.coupling_axial_scale)

    @property
    def reference_follower_share(self) -> bool:
        """Whether the coupling reference takes the follower's variance in its scrub's share, (C4):
        :attr:`coupling_follower_share`, on unless set ``False``."""
        return self.coupling_follower_share is not False

    def given(self) -> dict[str, object]:
        """The settings it gives the filter (those not ``None``, less the reference's own)."""
        return {
            name: value
            for name in type(self).model_fields
            if name not in REFERENCE_SETTINGS and (value := getattr(self, name)) is not None
        }


class FusionNoise(Settings):
    """Noise model and tuning of :class:`~sensor.fusion.FusedVisoOt` (SI units); each field's range and its reason
    is declared here.

    Parameters
    ----------
    gyro_noise : float
        White noise of one trailer yaw-rate sample [rad/s].
    wheel_speed_noise : float
        White noise of one trailer wheel-speed sample [m/s].
    slip_velocity_walk : float
        Random walk of the kingpin slip velocity ``v_s`` [m/s/√s]: how fast slip can build up (turn entry on ice).
    gyro_bias_walk, wheel_speed_bias_walk : float
        Random walks of the biases [rad/s/√s, m/s/√s].
    initial_slip_velocity, initial_gyro_bias, initial_wheel_speed_bias : float
        Standard deviations at the start [m/s, rad/s, m/s]; ``initial_gyro_bias`` is that of a gyro that was not
        zeroed (:meth:`~sensor.fusion.FusedVisoOt.zero_gyro`).
    gyro_zeroing_s : float
        The standstill before the run over which a run zeroes the trailer's gyro [s] (0: it does not).
    vo_covariance_scale : float
        Variance factor on the odometry's Gauss–Newton covariance (≥ 1: it is a floor).
    vo_covariance_adaptive : bool
        Grow each camera motion's covariance by the median normalised innovation squared of the motions before it
        over its expectation, ``m`` of eq (V1) of :mod:`sensor.fusion_adaptive`, between ``vo_covariance_scale`` (the
        floor) and ``vo_adaptive_max_factor`` times it (False, the default: ``vo_covariance_scale`` alone).
    vo_adaptive_window : int
        ``N`` of (V1): the camera motions the median is taken over.
    vo_adaptive_max_factor : float
        ``f_max`` of (V1): the ceiling of ``m``.
    vo_translation_floor, vo_rotation_floor : float
        Standard deviations added to every frame's increment [m, rad].
    vo_yaw_bias : float
        Standard deviation at the start of the odometry's systematic yaw error per metre [rad/m].
    vo_yaw_bias_walk : float
        Its random walk per metre travelled [rad/m/√m] (the scenery changes along the road).
    vo_bias_coupling : float
        The odometry's systematic translation error per unit of its yaw error, as a multiple of the regression of
        its random translation error on its yaw error (its covariance; docs/field_bias.md).
    vo_bias_coupling_uncertainty : float
        Relative standard deviation of ``vo_bias_coupling``: the off-tracking's std carries this share of the
        correction the coupling applies for the estimated ``β_ψ`` (eq (5)).
    vo_coupling_learned : bool
        Take the lasting part of eq (3)'s coupling at ``ρ̂·vo_bias_coupling``, the ratio ``ρ̂`` estimated online from
        the frames' lateral against the zero-slip kinematics regressed on their yaw against the gyro, (L1)–(L3) of
        :mod:`sensor.fusion_coupling_ratio` (False, the default: eq (3) as it is).
    vo_coupling_memory : float
        ``D`` of (L2): the distance over which the frames are forgotten [m].
    vo_coupling_prior : float
        ``σ_ρ`` of (L2): the standard deviation of the prior on ``ρ`` about 1 (the default, 0.15, that of
        ``vo_bias_coupling_uncertainty``: the coupling's stated uncertainty).
    vo_axial_scale_uncertainty : float
        Relative standard deviation of the odometry's translation along the camera's optical axis ``u_z`` (the
        depth scale a disparity offset gives: a side camera's drift along its optical axis, docs/field_bias.md §7),
        carried into the off-tracking's std coherently over the path (eq (5); 0: none, the default).
    vo_axial_scale : float
        Standard deviation at the start of the odometry's relative error along the optical axis as a state ``s_z``
        (eq (3'), estimated against the zero-slip kinematics and the trailer's signals; 0: no such state, the
        default). For a camera that looks across its motion (a side camera); docs/field_bias.md §7.4.
    vo_axial_flow : float
        Standard deviation at the start of the odometry's error along the optical axis per square metre of the
        camera's motion across it between two frames, a state ``s_f`` [1/m] (eq (3'): the image's flow between frames
        through the calibration's residual; 0: no such state, the default). docs/field_bias.md §7.4.
    vo_axial_scale_walk : float
        The random walk of ``s_z`` and ``s_f`` per metre travelled [1/√m] (an error that follows the mount's flex).
    vo_axial_effect : str
        How the remaining uncertainty of ``s_z`` and ``s_f`` enters the off-tracking's std (eq (5)): ``camera``
        (default: at the camera's own sensitivity, as if every increment were the camera's motion) or
        ``posterior`` (at the sensitivity of the filter's fused increments, their regression on the states at
        each frame: (A1)–(A2) of :mod:`sensor.fusion_axial`).
    vo_yaw_lever : bool
        Take the translation coupled to the odometry's yaw error along the camera's optical axis as the lever of a
        rotation about the camera, (3'') of :mod:`sensor.fusion_model`, instead of eq (3)'s ``κ·c`` (False, the
        default: eq (3)). For a side rig (``side_rig.vo_yaw_lever``), whose yaw error from its mount moves the
        kingpin's increment through the camera's distance behind it; docs/field_bias.md §7.24.
    kinematics : bool
        Fuse the zero-slip kinematics (K1) when the tractor's signals are given.
    kinematic_rear_point : str
        The tractor's rear point of (K1), :data:`~vehicle_model.kinematics.RearPoint`: ``axle_mean`` (default: the
        rear axles' mean station, fixed, with which the filter's noise model was set and the field-loop grid
        measured), ``equivalent``, ``speed_compensated`` (where a steady turn's lateral acceleration puts it,
        ``L1 − K·u²``) or ``lateral_acceleration`` (moving sideways at the slip the tractor's accelerometer asks
        of its rear tyres; it needs :attr:`~sensor.unit_kinematics.ChainSignals.lateral_acceleration`), or
        ``trailer_lateral_acceleration``: not the tractor's signals but the unit's own axles at the slip its own
        accelerometer asks of them ((T2) of :mod:`sensor.unit_slip_reference`; it needs
        :attr:`~sensor.unit_kinematics.ChainSignals.unit_lateral_acceleration`). docs/field_bias.md §6.3–6.4 say
        what the compensated points change, §7.11.1 what the unit's accelerometer does.
    reference_friction : float or None
        ``μ_min`` of (T3) of :mod:`sensor.unit_slip_reference`: the lowest road friction the vehicle is specified
        for, at which the ``trailer_lateral_acceleration`` reference's linear tyres' residual joins σ_k's floor
        (``None``: no such term, the default; docs/field_bias.md §7.11.2).
    reference_road_friction : float or None
        ``μ_r`` of (T4) of :mod:`sensor.unit_slip_reference`: the road's friction as the run states it, at which
        the ``trailer_lateral_acceleration`` reference's slip is the brush tyre's, not the linear tyre's (``None``:
        the linear tyre's, the default; docs/field_bias.md §7.17).
    reference_axles : str
        How that reference's axles share the demand: ``group`` (default: every axle at the group's demand, (T2)/(T4)
        of :mod:`sensor.unit_slip_reference`) or ``each`` (each axle's brush tyre at its own slip angle, (T5); it
        needs ``reference_road_friction``; docs/field_bias.md §7.34, §7.36).
    reference_tyre : str
        The tyre of ``each``'s axles: ``brush`` (default: (T3)'s brush tyre at the axle's cornering stiffness, static
        load and ``reference_road_friction``) or ``stated`` (the lateral force curve of the tyre the vehicle declares
        on each axle, at its static load and ``reference_road_friction``, (T6) of :mod:`sensor.unit_slip_reference`;
        it needs ``reference_axles: each``; docs/field_bias.md §7.40).
    reference_accelerometer_bias : float or None
        The standard deviation of the unit's accelerometer bias [m/s²] (a data sheet's: a bias uniform within ``±b``
        has ``b/√3``). With the ``trailer_lateral_acceleration`` reference, σ_k's floor takes that bias through the
        reference's own slip, (R1) of :mod:`sensor.fusion_reference`, in place of ``tractor_slip`` (the tractor's
        tyres, which that reference does not carry; ``None``: ``tractor_slip``, the default; docs/field_bias.md
        §7.29).
    tractor_stiffness_uncertainty : float
        ``u_C`` of (K2): the relative uncertainty of the tractor's cornering stiffnesses, so of the rear slip the
        compensated rear points predict.
    kinematic_error_model : str
        How (K1)'s error ``ε_k`` enters: ``inflated`` (default: white, with the variance ``σ_k²·τ_c/dt`` of a
        correlated error; the model of the field-loop grid in docs/field_bias.md) or ``state`` (an eighth state,
        a first-order Gauss–Markov process with correlation time ``τ_c`` and standard deviation ``σ_k``, so that the
        camera learns the kinematics' steady error and the kinematics carry what changes faster: (K3) in the module
        notes).
    kinematic_white_noise : float
        With ``kinematic_error_model: state``, the white noise of one tick's (K1) [m/s]: the tractor's gyro,
        wheel-speed and articulation sensors' noise at the kingpin.
    tractor_slip : float
        ``σ_0`` of (K2): the lateral slip velocity of the tractor's rolling tyres at the kingpin [m/s].
    kinematic_error_time : float
        ``τ_c``: the correlation time of the kinematic errors [s].
    slip_evidence_time : float
        ``τ_a`` of (K2): how fast the kinematics' σ follows the evidence of slip [s].
    slip_evidence_hold : bool
        (K2'): the evidence of slip falls no faster than a stopped slip's would, so a slip that changes sign (a
        change of turn on ice) keeps the kinematics de-weighted through the change (default off, as in the
        field-loop grid of docs/field_bias.md).
    trailer_push_share : float
        ``u_p`` of (K4): the least σ_k of (K2) per unit of the estimated slip velocity ``v_s`` (0: none). A trailer
        whose tyres slip sideways (axles steered towards their lock, scrubbing) carries a lateral force that its
        kingpin passes to the tractor's rear, so the tractor's rear tyres slip in proportion and the zero-slip
        kinematics (K1) err with them, too slowly for the camera's disagreement to show it (docs/fusion.md).
    scrub_slip_angle : float
        ``α_s`` of (K5) [rad]: the tyre slip angle of the unit's most loaded-sideways axle, from its own zero-slip
        kinematics, at which its tyres leave their linear range; the scrub demand rises from 0 there to 1 at twice
        it, and with it the odometry's yaw–translation coupling (eq (3)) gives way to its uncertainty and the slip
        velocity's random walk widens by ``scrub_slip_walk`` (0: no scrub demand).
    scrub_slip_walk : float
        The slip velocity's random walk at full scrub demand [m/s/√s], added to ``slip_velocity_walk`` (K5).
    scrub_bias_release : float
        ``r`` of (K6) in :mod:`sensor.fusion_slip`: the share of the odometry's estimated systematic yaw error
        ``β_ψ`` a frame's motion is no longer taken with at full scrub demand, so that the camera's turn goes to the
        heading while the tyres scrub (0: off).
    scrub_coupling_std : {"release", "uniform"}
        The share of the coupled correction ``β_ψ·G_κ`` the std's coupling term carries while the tyres scrub
        (:mod:`sensor.fusion_slip`): ``uniform`` (K7, the default), the RMS of the share the frames applied less the
        real one, uniform on [0, 1] at full demand, at the demand over the path; ``release``
        ``√((u_κ·(1 − D))² + ((1 − r)·D)²)`` at the last frame's demand.
    scrub_coupling_kept : bool
        Keep the odometry's coupled translation (eq (3)) under a scrub demand: a frame is taken with the share
        ``1 − r·D`` of the coupled correction ``β_ψ·G_κ`` ((K6) alone) instead of ``(1 − r·D)·(1 − D)`` (False, the
        default: (K5) lets the coupling give way as well; :func:`~sensor.fusion_slip.scrub_coupling_yield`).
    gate : float
        Largest normalised innovation squared accepted (χ²₃ at 0.999 is 16.3).
    max_gated : int
        Refused motions in a row after which the next one is accepted (with its covariance inflated).
    max_std : float
        No estimate (``None``) while the off-tracking's standard deviation exceeds this [m].
    offtracking_bias_std : float
        ``σ_b`` of eq (5) [m]: what no state of the filter explains of the odometry's off-tracking error, added in
        quadrature (0: none; a run's ``fusion`` settings add 0.005 m).
    innovation_window : int
        Camera motions over which the mean normalised innovation squared ``ρ`` of eq (5) is taken.
    innovation_ratio_from : {"all", "lateral", "rear_lateral"}
        What ``ρ`` is the mean of: each motion's 3-D normalised innovation squared (``"all"``, the default), or
        three times that of its lateral component given the other two, whose expectation is 1
        (``"lateral"``; :func:`~sensor.fusion_std.window_nis`); ``"rear_lateral"`` takes ``"lateral"`` on a rig
        that looks back along its unit and ``"all"`` on every other (:meth:`for_camera`). Both are capped at
        ``gate`` and floored as :data:`~sensor.fusion_std.MIN_INNOVATION_RATIO` says; docs/fusion.md says when
        the two differ.
    bias_std_scale : float
        ``f_b`` of eq (5): a factor on the standard deviation of the biases' term (``G·P_b·Gᵀ`` with the axial
        states' effects; 1, the default: as the filter's covariance gives it). Below 1 it says the biases' remaining
        uncertainty, as the filter holds it, is wider than the error it leaves in the off-tracking; docs/field_bias.md
        §7.19 sizes it for a side rig.
    coupling_reference : bool
        Take a following unit's camera, carried forward through the couplings with the measured articulations, as a
        measurement of this unit's kingpin increment where the caller gives one (:mod:`sensor.fusion_coupling`;
        off by default, a run's side rigs take it).
    coupling_bias_share : bool
        Carry the biases into the off-tracking's std through only the share of each increment's error that the
        following unit's measurement left in it, ``I − K_Δ`` of eq (4') of :mod:`sensor.fusion_std` (off: through
        the whole increment, as if the camera alone had measured it; the same wherever no reference was taken).
    coupling_persisting_error : PersistingReferenceError or None
        The following unit's measurement error that persists over frames, carried into the off-tracking's std
        through the filter's own gains (a consider parameter, :mod:`sensor.fusion_consider`; ``None``: none, the
        default, the std as without it).
    articulation_noise : float
        White noise of one articulation sample [rad], in the covariance of that measurement ((C2) of
        :mod:`sensor.fusion_coupling`).
    side_rig : SideRigFusion
        What a camera looking across its motion takes instead (:meth:`for_camera`; none by default, a run's
        ``fusion`` settings give the side camera's states).
    linked_rig : LinkedRigFusion
        What a camera looking along its unit takes instead on a unit whose front coupling rides on another towed
        unit (:meth:`for_camera`, :mod:`sensor.fusion_linked_rig`; none by default).
    """

    gyro_noise: float = Field(
        1.2e-3, gt=0.0, le=0.1, description="[rad/s] per sample (sensor/datasheet.py); 0.1 is beyond any gyro"
    )
    wheel_speed_noise: float = Field(0.05, gt=0.0, le=1.0, description="[m/s] per sample; 1 m/s is a broken sensor")
    slip_velocity_walk: float = Field(0.1, gt=0.0, le=5.0, description="[m/s/√s] slip build-up; 5 spins in 1 s")
    gyro_bias_walk: float = Field(
        1e-6, ge=0.0, le=0.1, description="[rad/s/√s] in-run drift (a few °/h); 0.1 is a gyro without a bias"
    )
    wheel_speed_bias_walk: float = Field(2e-3, ge=0.0, le=1.0, description="[m/s/√s]; 1 is a sensor without a bias")
    initial_slip_velocity: float = Field(0.3, ge=0.0, le=10.0, description="[m/s]; 10 m/s of slip is a spin")
    initial_gyro_bias: float = Field(
        1e-3, ge=0.0, le=1.0, description="[rad/s] the offset of a gyro not zeroed (0.06°/s); 1 rad/s is no gyro"
    )
    gyro_zeroing_s: float = Field(
        10.0,
        ge=0.0,
        le=600.0,
        description="[s] the standstill before the run over which the trailer's gyro is zeroed; 0: not zeroed, "
        "600 s is a long stop",
    )
    initial_wheel_speed_bias: float = Field(0.2, ge=0.0, le=10.0, description="[m/s]; 10 m/s is no wheel speed")
    vo_covariance_scale: float = Field(4.0, ge=1.0, le=1e4, description="on the VO covariance (a floor); 1e4: no VO")
    vo_covariance_adaptive: bool = False
    vo_adaptive_window: int = Field(
        100, ge=10, le=10000, description="camera motions in (V1)'s median; below 10 it is no statistic"
    )
    vo_adaptive_max_factor: float = Field(
        4.0, ge=1.0, le=100.0, description="ceiling of (V1)'s factor on the covariance; 1: no growth, 100 drops the VO"
    )
    vo_translation_floor: float = Field(1e-3, ge=0.0, le=1.0, description="[m] per frame; 1 m is no translation")
    vo_rotation_floor: float = Field(1e-4, ge=0.0, le=0.1, description="[rad] per frame; 0.1 rad is no rotation")
    vo_yaw_bias: float = Field(
        1e-3, ge=0.0, le=0.01, description="[rad/m] start std of the VO's yaw error; 0.01 rad/m turns 57° in 100 m"
    )
    vo_yaw_bias_walk: float = Field(2e-5, ge=0.0, le=1e-3, description="[rad/m/√m]; 1e-3 forgets in a metre")
    vo_bias_coupling: float = Field(
        1.15, ge=0.0, le=3.0, description="× the covariance's yaw–translation regression; 0 ties no translation to it"
    )
    vo_bias_coupling_uncertainty: float = Field(
        0.15,
        ge=0.0,
        le=1.0,
        description="relative std of vo_bias_coupling, carried into the off-tracking's std; 1: the coupling unknown",
    )
    vo_coupling_learned: bool = False
    vo_coupling_memory: float = Field(
        100.0, ge=1.0, le=1e5, description="[m] (L2)'s forgetting distance; below 1 m no frame counts"
    )
    vo_coupling_prior: float = Field(0.15, ge=0.01, le=10.0, description="std of (L2)'s prior on the ratio about 1")
    vo_axial_scale_uncertainty: float = Field(
        0.0,
        ge=0.0,
        le=0.5,
        description="relative std of the VO's translation along the optical axis, in the std; 0.5: half of it unknown",
    )
    vo_axial_scale: float = Field(
        0.0, ge=0.0, le=0.5, description="start std of the VO's relative error along the optical axis, a state; 0: none"
    )
    vo_axial_flow: float = Field(
        0.0,
        ge=0.0,
        le=0.5,
        description="[1/m] start std of the VO's axial error per m² of frame motion across it; 0: none",
    )
    vo_axial_scale_walk: float = Field(
        0.0, ge=0.0, le=0.1, description="[1/√m] its random walk per metre; 0.1 forgets a 3 % error in a few cm"
    )
    vo_axial_effect: AxialEffect = "camera"
    vo_yaw_lever: bool = False
    kinematics: bool = True
    kinematic_rear_point: KinematicReference = "axle_mean"
    reference_friction: float | None = Field(None, ge=0.05, le=1.5, description=FRICTION)
    reference_road_friction: float | None = Field(None, ge=0.05, le=1.5, description=ROAD_FRICTION)
    reference_axles: ReferenceAxles = "group"
    reference_tyre: ReferenceTyre = "brush"
    reference_accelerometer_bias: float | None = Field(None, gt=0.0, le=1.0, description=REFERENCE_BIAS)
    tractor_stiffness_uncertainty: float = Field(
        0.2,
        ge=0.0,
        le=1.0,
        description="relative; a tyre's cornering stiffness is known to 10–30 % (load, wear, pressure); 1: unknown",
    )
    kinematic_error_model: Literal["inflated", "state"] = "inflated"
    kinematic_white_noise: float = Field(
        0.005, gt=0.0, le=1.0, description="[m/s] per tick, the tractor's sensor noise at the kingpin; 1 m/s is none"
    )
    tractor_slip: float = Field(
        0.02, gt=0.0, le=1.0, description="[m/s] slip of rolling tractor tyres; 1 m/s is a slide, not a roll"
    )
    kinematic_error_time: float = Field(
        10.0, gt=0.0, le=60.0, description="[s] correlation time of a steady slip; 60 s is a whole manoeuvre"
    )
    slip_evidence_time: float = Field(
        1.0, gt=0.0, le=30.0, description="[s] how fast the kinematics' σ follows the slip; 30 s misses a turn entry"
    )
    slip_evidence_hold: bool = False
    trailer_push_share: float = Field(
        0.0, ge=0.0, le=2.0, description="σ_k per unit of the trailer's slip velocity; 0: none, 2 is a tractor on ice"
    )
    scrub_slip_angle: float = Field(
        0.0, ge=0.0, le=0.5, description="[rad] onset of the scrub demand (K5); 0: none, 0.5 rad is a tyre on its side"
    )
    scrub_slip_walk: float = Field(
        0.0, ge=0.0, le=5.0, description="[m/s/√s] added slip walk at full scrub demand; 5 spins in 1 s"
    )
    scrub_bias_release: float = Field(
        0.0, ge=0.0, le=1.0, description="share of β_ψ released at full scrub demand (K6); 1 takes none of it"
    )
    scrub_coupling_std: ScrubCouplingStd = "uniform"
    scrub_coupling_kept: bool = False
    gate: float = Field(16.3, gt=0.0, le=1e6, description="normalised innovation squared; 1e6 gates nothing")
    max_gated: int = Field(3, ge=0, le=1000, description="refusals in a row before one is accepted")
    max_std: float = Field(0.5, gt=0.0, le=10.0, description="[m] of off-tracking std; 10 m says nothing")
    offtracking_bias_std: float = Field(
        0.0,
        ge=0.0,
        le=0.5,
        description="[m] the VO's error no state explains, added to the filter's std; 0.5 m swamps any estimate",
    )
    innovation_window: int = Field(
        50, ge=1, le=10000, description="camera motions in ρ of eq (5); one is no statistic, 10000 never adapts"
    )
    innovation_ratio_from: InnovationRatioFrom = "all"
    bias_std_scale: float = Field(1.0, gt=0.0, le=1.0, description=BIAS_STD_SCALE)
    coupling_reference: bool = False
    coupling_bias_share: bool = False
    coupling_persisting_error: PersistingReferenceError | None = None
    articulation_noise: float = Field(
        8.7e-4, ge=0.0, le=0.1, description="[rad] per sample (sensor/datasheet.py); 0.1 rad is no articulation sensor"
    )
    side_rig: SideRigFusion = Field(default_factory=SideRigFusion)
    linked_rig: LinkedRigFusion = Field(default_factory=LinkedRigFusion)

    @model_validator(mode="after")
    def _follower_axial_state(self) -> FusionNoise:  # (C0'') takes the follower's s_z: its filter must hold one
        if self.side_rig.coupling_axial_scale and not self.vo_axial_scale > 0.0:
            raise ValueError(
                f"side_rig.coupling_axial_scale = true needs the following camera's filter to hold s_z: "
                f"vo_axial_scale = {self.vo_axial_scale:g}, allowed (0, 0.5] with it (or coupling_axial_scale unset)"
            )
        return self

    def for_camera(self, optical_axis: tuple[float, float], unit: int = 1) -> FusionNoise:
        """The settings of a filter whose camera's optical axis is ``optical_axis`` in the ground plane of towed unit
        ``unit`` (1 the first, on the tractor's coupling; each further one on the coupling of the towed unit ahead).

        A camera that looks across its motion (``|o_y| > |o_x|``, a side rig) takes :attr:`side_rig`'s, any other
        camera on unit 2 or further (a linked rig, :mod:`sensor.fusion_linked_rig`) :attr:`linked_rig`'s, and any
        other these settings unchanged (the same object, as where the section taken gives nothing). With
        :attr:`innovation_ratio_from` ``"rear_lateral"`` a camera that looks back along its unit (``o_x < 0``,
        ``|o_x| ≥ |o_y|``) takes ``"lateral"`` and any other ``"all"``.
        """
        if abs(optical_axis[1]) > abs(optical_axis[0]):
            given = self.side_rig.given()
        else:
            given = self.linked_rig.given() if unit >= 2 else {}
        if self.innovation_ratio_from == "rear_lateral":
            rear = optical_axis[0] < 0.0 and -optical_axis[0] >= abs(optical_axis[1])
            given = {**given, "innovation_ratio_from": "lateral" if rear else "all"}
        return self.replace(**given) if given else self
