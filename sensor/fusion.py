"""Fused VISO-OT: a Kalman filter of the trailer's signals, the zero-slip kinematics and the stereo camera's odometry.

VISO-OT (de Saxe & Cebon 2018, §2.2; :mod:`sensor.viso_ot`) gives the off-tracking at the camera rate, a camera
latency late, and has nothing between frames or across failed ones; Cheng's zero-slip kinematics (Cheng 2009;
docs/vehicle_dynamics.md §2.3, §7.2) give the kingpin's motion at every control tick from the tractor's signals,
but are blind to tyre slip. The paper lists a Kalman filter as future work (§5). This one propagates at the control
rate with the trailer's yaw-rate gyro, a wheel-speed sensor on an unsteered trailer axle and the trailer's own steer
angles; takes Cheng's kinematics as a measurement whose noise follows the evidence of slip; and corrects with every
visual-odometry motion, weighted by its Gauss–Newton covariance, with the odometry's own systematic yaw error as a
state. The kingpin increments it produces feed the one path buffer
(:class:`~vehicle_model.offtracking.OfftrackingBuffer`, eqs (3)–(7)). docs/field_bias.md says why each part is
there and what it removes under field conditions.

Any towed unit. Everything below is written for the first towed unit (the semi-trailer behind the tractor), and
holds for any towed unit ``k`` of a longer combination (``unit``): "the trailer" is unit ``k`` with its own gyro,
wheel speed, steerable axles and follow point, "the kingpin" its front coupling (the fifth wheel of unit ``k − 1``,
or a dolly's drawbar eye), and "the tractor's signals" of the zero-slip measurement are carried down the chain of
units ahead of it (:mod:`sensor.unit_kinematics`).

Model (trailer frame ISO 8855, origin at the kingpin; docs/design.md §5–6)
--------------------------------------------------------------------------
State, kept relative to the *anchor* (the time of the last camera frame that was committed)::

    x = [Δx, Δy, Δψ, v_s, b_g, b_w, β_ψ]     (and ε_k of (K3) with ``kinematic_error_model: state``,
                                             then s_z and s_f of (3') when they are on)

``(Δx, Δy, Δψ)`` is the kingpin's displacement and the trailer's heading change since the anchor, in the
anchor's trailer frame; ``v_s`` is the lateral *slip velocity* of the kingpin [m/s] (what the trailer's zero-slip
kinematics does not explain); ``b_g`` the gyro bias [rad/s]; ``b_w`` the wheel-speed bias [m/s]; ``β_ψ`` [rad/m]
the visual odometry's systematic yaw error per metre travelled (calibration and lens: docs/field_bias.md).

Kinematics. The trailer yaw rate is ``r = r_m − b_g``; the kingpin's longitudinal velocity is that of every
point on the centre line, so the axle's wheel speed gives ``u = w_m − b_w`` (free-rolling trailer wheels, no
longitudinal slip). Zero lateral force on the trailer's axles at zero slip (docs/vehicle_dynamics.md §2.3, the
stiffness-weighted form: ``Σ C_j (v_k − r L_j − u tan δ_j) = 0``) gives the kingpin's lateral velocity::

    v_k = r·L_c + u·Σ w_j tan δ_j + v_s,     L_c = Σ C_j L_j / Σ C_j,   w_j = C_j / Σ C_j     (1)

(``L_j`` the axle's distance behind the kingpin, ``δ_j`` its measured steer, zero for a fixed axle). Over one
control period the rates are taken constant at the mean of the two samples and the kingpin moves on the
exact arc::

    δψ = r·dt,   δp = M(δψ)·(u, v_k)·dt,   M(θ) = [[sin θ/θ, −(1−cos θ)/θ], [(1−cos θ)/θ, sin θ/θ]]   (2)
    (Δx, Δy) ← (Δx, Δy) + R(Δψ)·δp,   Δψ ← Δψ + δψ

``v_s``, ``b_g`` and ``b_w`` are random walks in time, ``β_ψ`` in distance travelled. The gyro and wheel-speed
noises enter as white noise on the period's mean rate; the covariance propagates with the Jacobian of (2) (first
order in δψ). The gyro is zeroed at standstill (:meth:`FusedVisoOt.zero_gyro`), as a vehicle's stability control
does at every stop: ``b_g`` starts at the mean reading over the stop with the variance of that mean,
``σ_g²/n`` for ``n`` samples, so that the heading comes from the gyro and the odometry's yaw error is found against
it (docs/field_bias.md); a gyro that was not zeroed starts at zero within ``initial_gyro_bias``, the offset a
data sheet leaves (:mod:`sensor.datasheet`).

Zero-slip measurement (every control tick, when the tractor's signals are given). If no tractor tyre slips
sideways, the kingpin moves at ``(u_1, −e·r_1)`` in tractor axes (:func:`vehicle_model.kinematics.
zero_slip_kingpin_velocity`; Cheng 2009): turned by the articulation Γ into trailer axes its lateral component is
``z_c = sin Γ·u_1 + cos Γ·(−e·r_1)`` (``u_1``, ``r_1`` the tractor's wheel speed and yaw rate). For a unit behind
the first the kingpin's velocity is carried down the chain as rigid-body motion, with the measured articulations
and yaw rates of the units ahead, before it is turned into the unit's axes (:class:`ChainSignals`,
:mod:`sensor.unit_kinematics`): the tractor's slip stays the only error. ``e`` is the
kingpin's distance behind the tractor's rear point, which is not fixed: in a steady turn the rear tyres carry the
tractor's lateral acceleration and the trailer's pull at the fifth wheel, and with linear tyres the point without
lateral velocity lies ``L1' = L1 − K·u_1²`` behind the steer axle (``L1`` the equivalent wheelbase, ``K`` from the
masses and the static cornering stiffnesses: :meth:`~vehicle_model.parameters.VehicleParams.tractor_rear_point`,
docs/vehicle_dynamics.md §2.3, §6.6), so ``e = L_5 − L1'`` with ``kinematic_rear_point`` ``speed_compensated``
(default ``axle_mean``: the rear axles' mean station, fixed). That is the steady part of the tractor's slip,
predicted from its speed. With the tractor's lateral accelerometer (``lateral_acceleration``) the rear point is the
equivalent wheelbase moving sideways at ``−K·u_1·f_y`` (``f_y`` the specific force it reads:
:meth:`~vehicle_model.parameters.VehicleParams.tractor_rear_slip_velocity`), which is the same in a level steady
turn (``f_y = u_1·r_1``) and also covers a cross slope's share of gravity. The rest (saturation, a scrubbing
trailer's push, and for the fixed points the camber) is ``ε_k`` below. With (1) it measures the slip velocity::

    z_c − r_m·L_c − w_m·Σ w_j tan δ_j = v_s + ε_k                                               (K1)

``ε_k`` the slip of the tractor's own tyres. It is a slowly varying error (a steady slip in a steady turn), not
white: with a correlation time ``τ_c`` (``kinematic_error_time``) a measurement at every tick ``dt`` carries the
information of one every ``τ_c``, so it is applied with the variance ``σ_k²·τ_c/dt``. Its standard deviation σ_k
follows the evidence of slip, the disagreement between the camera and the kinematics: each camera frame's lateral
kingpin motion (less the odometry's estimated systematic error) against the kinematics' over the same interval
(Cheng's lateral velocity with the gyro's heading), as a velocity ``δv``. Its exponentially weighted mean over
``τ_a`` (``slip_evidence_time``) and the variance that mean would have from the frames' own noise alone give::

    m_k = m_{k−1} + α·(δv_k − m_{k−1}),   α = Δt_frame/τ_a,
    σ_k² = max(σ_0² + (u_C·v_m)², m_k² − V_k·α/(2 − α))                                          (K2)

(``V_k`` the same weighted mean of the frames' lateral variance over Δt²; ``σ_0`` = ``tractor_slip``: the slip of
rolling tyres; ``v_m`` the rear slip velocity the compensated rear points predict, ``K·u_1²·r_1`` or
``K·u_1·f_y``, uncertain by the cornering stiffnesses' relative ``u_C`` = ``tractor_stiffness_uncertainty``).
A persistent disagreement is slip, noise is not (innovation-based adaptive estimation: Mehra 1972; Mohamed &
Schwarz 1999). A slip that changes sign — a change of turn on ice, where the tractor's tyres slip the other way —
takes ``m_k`` through zero, and (K2) would trust the kinematics just as their error flips; with
``slip_evidence_hold`` the evidence falls no faster than it would had the slip stopped (a mean decaying by
``1 − α`` a frame, its square by ``(1 − α)²``)::

    e_k = max(m_k² − V_k·α/(2 − α), (1 − α)²·e_{k−1}),   σ_k² = max(σ_0² + (u_C·v_m)², e_k)           (K2')

A trailer whose own tyres slip sideways — its axles steered hard towards their lock, scrubbing — carries a lateral
force that the kingpin passes to the tractor's rear, so the tractor's rear tyres slip with it and (K1) errs in
proportion to the trailer's slip ``v_s``; that error may lie below what the disagreement can tell from the camera's
noise. With ``trailer_push_share`` ``u_p`` > 0 the estimated slip itself is that evidence::

    σ_k² = max(σ_0² + (u_C·v_m)², e_k, (u_p·v_s)²)                                                 (K4)

(off by default: ``u_p`` = 0).

On a dry road the disagreement stays within the noise, σ_k stays at σ_0 and the
kinematics share the estimate with the camera; where the camera sees slip — ice, a cambered road — σ_k follows the
slip within ``τ_a`` and the camera carries the estimate. σ_k is recorded (:attr:`FusedVisoOt.kinematic_std`): the
run says which source it trusted.

With ``kinematic_error_model: state`` the correlated error is not inflated white noise but an eighth state, the
shaping filter of a time-correlated measurement error (state augmentation: Bryson & Henrikson 1968): a first-order
Gauss–Markov process with the correlation time ``τ_c`` and the standard deviation σ_k of (K2), and (K1) carries only
the white noise ``σ_w`` (``kinematic_white_noise``) of the tractor's sensors and, as in the inflated model, the
evidence of slip beyond its floor ``σ_f² = σ_0² + (u_C·v_m)²``::

    ε_k ← φ·ε_k + w,   φ = exp(−dt/τ_c),   E[w²] = σ_k²·(1 − φ²)
    (K1) = v_s + ε_k + n,   E[n²] = σ_w² + (σ_k² − σ_f²)·τ_c/dt                                    (K3)

The camera measures the kingpin's motion, so ε_k is observed through the difference: the filter learns the
kinematics' steady error (the sensors' offsets, the linear tyre model's residual, a steady crab) from the camera,
and where the disagreement says nothing slips the kinematics carry what changes faster than that; where it says the
tyres slip, the white part de-weights the kinematics at once, before the state has learned the new error (a
figure-of-eight's change of turn on ice; docs/field_bias.md §6.5).

Camera measurement. Each frame's camera motion becomes a kingpin increment ``z = (dx, dy, dψ)`` over the frame
interval through the camera's pose on the trailer (eqs (1)–(2), :meth:`VisoOtEstimator.kingpin_increment`). Its
covariance ``R`` is the odometry's ``Σ = (JᵀJ)⁻¹σ̂²`` of the 6 motion parameters mapped through that function
(numerical Jacobian), scaled by ``vo_covariance_scale`` (the Gauss–Newton covariance is a floor of the true one,
:mod:`sensor.vo.quality`) plus a floor; so a frame with few or noisy inliers counts for less. The odometry's
systematic error lies along its weakest direction, the yaw–translation ambiguity of a camera looking along its
motion: a yaw error comes with the translation error that keeps the far features in place. So the motion measures::

    z = (Δx, Δy, Δψ) + d·β_ψ·(κ·c_x, κ·c_y, 1),    (c_x, c_y) = R_{xy,ψ} / R_ψψ                   (3)

``d = Δx`` the distance since the anchor, ``(c_x, c_y)`` the frame's regression of translation on yaw error from
``R``, ``κ`` = ``vo_bias_coupling`` (measured, docs/field_bias.md). A motion whose normalised innovation squared
exceeds ``gate`` is refused (``max_gated`` in a row are accepted with the covariance inflated, so the filter cannot
lock itself out).

A camera that looks across its motion (a side camera) has its weakest direction along its optical axis ``o``, the
off-tracking direction, instead. Two optional states, appended after the others, model the odometry's systematic
error along it: ``s_z`` (``vo_axial_scale`` its start std), a relative error of the camera's displacement along the
axis (a disparity offset scaling the depths), and ``s_f`` [1/m] (``vo_axial_flow``), an error that grows with the
square of the camera's displacement across the axis between two frames (the image's flow through a calibration's
residual: features crossing the image change their disparity error with the distance they move, docs/field_bias.md
§7.4). With ``Δ_c`` the camera's displacement over the frame (the kingpin's plus the lever ``(R(Δψ) − I)·p_c`` of the
camera at ``p_c``) and ``t = (o_y, −o_x)``::

    z_xy = (Δx, Δy) + [eq (3)'s term] + (s_z·(o·Δ_c) + s_f·(t·Δ_c)·|t·Δ_c|)·o                    (3')

Both are random walks in distance (``vo_axial_scale_walk``) and are found against the zero-slip kinematics (K1)
where those are trusted (the disagreement of (K2) is taken less their estimated part): a side camera on a straight
road must report no lateral motion. Both are off by default (no such states).

Delayed measurements. A frame taken on tick ``k`` is released ``latency`` ticks later
(:mod:`scenarios.camera.delivery`). The filter keeps the state, covariance, inputs and zero-slip measurements of
every tick since the anchor; :meth:`FusedVisoOt.measure` updates the stored state of tick ``k`` and re-filters to
the present with the stored inputs and measurements (an out-of-sequence update by re-filtering). With zero latency
this is the ordinary update; with any latency it is exactly what the filter would have done had the motion come
on tick ``k``, seen no earlier than its release.

Commit. After each frame (measured or not) the increments from the anchor to the frame are pushed into the
path buffer (the propagated per-tick increments, the last one carrying the correction, so the buffer keeps
control-rate resolution), the frame becomes the anchor, ``(Δx, Δy, Δψ)`` restart from zero and only the
covariance of the other states is carried on (the cross-covariance with the committed increment is dropped:
the usual reset of a delta state). A failed, refused or dropped frame is committed from the prediction alone,
so a gap is bridged with a covariance that grows with its length.

Off-tracking and its standard deviation. Every tick the off-tracking is read from the buffer moved by the
current ``(Δx, Δy, Δψ)`` (eq (7), :func:`~vehicle_model.offtracking.offtracking_from_path`). Its variance has
five parts. The committed increments newer than the follow-point station, and the current one, each contribute
``gᵀ Q g`` with ``Q`` the increment's covariance and ``g`` the first-order effect of its error on ``e_tr``::

    g = (−sin ψ_s, −cos ψ_s, x_e + L_fp)                                                        (4)

(``ψ_s`` the heading of the increment's start frame and ``x_e`` the station of its end, both in the current
trailer frame: a translation error moves the old path rigidly, a heading error turns it about the increment's
end). The remaining uncertainty of the biases ``(b_g, β_ψ)`` is common to every increment, so it enters coherently,
through ``G``, the change of ``e_tr`` per unit bias summed over the increments (a gyro bias turns each by its
duration and, through (1), moves it by ``L_c`` times that; the odometry's error per metre along (3) by its length).
Both parts follow the camera's evidence: ``ρ``, the mean normalised innovation squared of its recent motions, is 3
when they agree with their covariances (Bar-Shalom, Li & Kirubarajan 2001, ch. 5), so ``ρ/3`` scales them up where
the motions are noisier than their covariances say and down (to a quarter at most) where they are quieter. The
coupling ``κ`` of (3) is itself known only to a relative ``u_κ`` (``vo_bias_coupling_uncertainty``: the regression
of the measured errors, docs/field_bias.md), so the translation the filter removes for the estimated ``β_ψ``,
``β_ψ·G_κ`` (``G_κ`` the coupled part of ``G``'s second entry), is uncertain by ``u_κ·β_ψ·G_κ``: a large
estimated odometry error widens the std. A camera that looks across its motion (a side camera) has its weakest
direction along its optical axis ``o`` instead: a disparity offset scales its translation along ``o`` by a relative
error, known to ``u_z`` (``vo_axial_scale_uncertainty``, 0 by default), which enters coherently over the path
through ``A_z = Σ (o·Δ_c)·(g_xy·o)`` (``Δ_c`` each increment's camera displacement) and adds ``(u_z·A_z)²`` to
the coupling term; the states ``s_z`` and ``s_f`` of (3') enter the biases' term with ``A_z`` and
``A_f = Σ (t·Δ_c)·|t·Δ_c|·(g_xy·o)`` beside ``G``. The share of the kinematics' disagreement with the camera that the
estimate carries, ``s_k·m_k`` (K2), enters over the path as a slip velocity would, through ``Λ``, the sum of the
increments' lateral sensitivities times their durations (with (K3) the kinematics' error is a state, its
uncertainty is in the increments' own covariance, and this term is zero; with (K4) ``m_k²`` is at least
``(u_p·v_s)²``). What no state explains — the part of
the odometry's error that changes with the scenery faster than ``β_ψ`` follows — is the constant
``offtracking_bias_std`` ``σ_b``::

    σ_e² = (ρ/3)·(Σ gᵀ Q g + G·P_b·Gᵀ) + (u_κ·β_ψ·G_κ)² + (u_z·A_z)² + (s_k·m_k·Λ)² + σ_b²          (5)

Why this module is long: this docstring states the filter's model in full beside the code that carries it out,
and the propagation, the delayed measurements, the commit and the reading of the off-tracking share one state.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.offtracking import OfftrackingBuffer, offtracking_from_path
from vehicle_model.parameters import VehicleParams
from vehicle_model.rigid import invert_rigid

from .fusion_noise import FusionNoise
from .unit_kinematics import ChainKinematics, ChainSignals, TractorSignals, slip_kinematics
from .viso_ot import VisoOtEstimator
from .vo.motion import params_to_transform, transform_to_params

__all__ = ["STD_PARTS", "ChainSignals", "FusedVisoOt", "FusionNoise", "TractorSignals", "slip_kinematics"]

#: The five terms of the off-tracking's variance, eq (5), in its order: the increments' own covariance, the
#: biases' remaining uncertainty, the bias coupling's (with the optical axis's scale), the kinematics' carried
#: disagreement and the constant ``offtracking_bias_std``.
STD_PARTS: tuple[str, ...] = ("increments", "biases", "coupling", "kinematics", "unexplained")

_STATES = 7
_VS, _BG, _BW, _BPSI, _EK = 3, 4, 5, 6, 7
_BIASES = [_BG, _BPSI]
MIN_INNOVATION_RATIO = 0.25
"""Least ``ρ/3`` of eq (5): a run of well-matched motions may shrink the std by half, not to nothing."""


@dataclass
class _Tick:
    """One control tick since the anchor: its number, the inputs of the step into it, its zero-slip measurements
    ``(H, z, R)`` and the state and covariance after them."""

    tick: int
    inputs: tuple[float, float, float, float]  # dt, mean r_m, mean w_m, mean Σ w_j tan δ_j
    x: np.ndarray
    p: np.ndarray
    kinematic: tuple[tuple[np.ndarray, float, float], ...] = ()
    tractor_lateral: float = math.nan  # the kingpin's lateral velocity if no tractor tyre slips [m/s]
    kinematic_variance: float = 0.0  # σ_k² of (K3) on the step into this tick [m²/s²]


class FusedVisoOt:
    """Kalman filter of trailer signals, zero-slip kinematics and visual odometry feeding the off-tracking path
    buffer (module notes).

    Parameters
    ----------
    params
        Vehicle parameters (the follow point, the unit's axles of eq (1), the tractor's rear point of (K2)).
    camera_in_trailer
        4×4 pose ``T_trailer←camera`` of the left camera in the unit's frame (as
        :class:`~sensor.viso_ot.VisoOtEstimator`).
    noise
        Noise model and tuning (default :class:`FusionNoise`).
    unit
        The towed unit it estimates: 1 the first (default), 2 the one it tows, … Its own gyro, wheel speed and steer
        angles propagate it (:meth:`propagate`), its front coupling is its "kingpin" and its follow point its own;
        the zero-slip measurement takes the tractor's signals carried down the chain (:class:`ChainSignals`,
        :mod:`sensor.unit_kinematics`).

    Attributes
    ----------
    estimate : float or None
        Off-tracking [m] at the last tick (``None``: no estimate yet, or too uncertain).
    std : float
        Its standard deviation [m] (NaN without an estimate).
    frames, updates, rejected : int
        Frames seen, motions used, motions refused by the gate.
    kinematic_std : float
        σ_k of (K2), the zero-slip measurement's standard deviation at the last tick [m/s] (NaN before the first):
        small where the filter trusts the kinematics, large where it has seen slip.
    innovation_ratio : float
        ``ρ/3`` of eq (5): the camera motions' mean normalised innovation squared over its expectation.
    std_parts : dict[str, float]
        The five variance terms of eq (5) at the last tick [m²], keyed by :data:`STD_PARTS` (NaN without an
        estimate); :meth:`std_contributions` gives them as standard deviations.
    """

    def __init__(
        self,
        params: VehicleParams,
        camera_in_trailer: np.ndarray,
        noise: FusionNoise | None = None,
        unit: int = 1,
    ) -> None:
        self.noise = noise if noise is not None else FusionNoise()
        self.params = params
        # eqs (1)–(2): camera motion → kingpin increment (it also checks the unit)
        self.geometry = VisoOtEstimator(params, camera_in_trailer, unit=unit)
        self.unit = self.geometry.unit
        self.follow_point_offset = params.follow_point_offset_of(self.unit)
        self.slip_point, self.steer_weights = slip_kinematics(params, self.unit)
        self._chain = ChainKinematics(params, self.unit, self.noise.kinematic_rear_point)  # (K1)'s z_c
        axis = self.geometry.mount_rotation[:2, 2]  # the optical axis in the unit's ground plane
        self._optical_axis = axis / max(float(np.hypot(*axis)), 1e-12)
        self.buffer = OfftrackingBuffer(self.follow_point_offset)
        n = self.noise
        self._sample_variance = np.array([n.gyro_noise**2, n.wheel_speed_noise**2])
        self._walk_time = np.diag([n.slip_velocity_walk**2, n.gyro_bias_walk**2, n.wheel_speed_bias_walk**2])
        self._walk_distance = n.vo_yaw_bias_walk**2
        self._error_state = n.kinematic_error_model == "state"  # ε_k of (K1) an eighth state, (K3)
        self._axial_state = n.vo_axial_scale > 0.0  # s_z of (3') a state
        self._flow_state = n.vo_axial_flow > 0.0  # s_f of (3') a state
        states = _STATES + int(self._error_state)
        self._sz = states if self._axial_state else None
        self._sf = states + int(self._axial_state) if self._flow_state else None
        self._states = states + int(self._axial_state) + int(self._flow_state)
        self._biases = [*_BIASES, *(i for i in (self._sz, self._sf) if i is not None)]
        self._f = np.eye(self._states)  # work arrays of _step
        self._g = np.zeros((self._states, 2))
        self._gyro_zero: tuple[float, int] | None = None
        self.reset()

    def zero_gyro(self, mean_reading: float, samples: int) -> None:
        """Zero the gyro at standstill: its mean reading over ``samples`` samples at rest is its offset.

        ``b_g`` then starts at ``mean_reading`` with the variance of that mean, ``gyro_noise²/samples`` (a mean of
        white samples), instead of at zero within ``initial_gyro_bias``. Call before the first
        :meth:`propagate`; :meth:`reset` keeps it.

        Raises
        ------
        InputError
            ``mean_reading`` not finite or ``samples`` < 1.
        """
        if not math.isfinite(mean_reading) or samples < 1:
            raise InputError(f"zeroing the gyro needs a finite mean reading and samples ≥ 1: {mean_reading}, {samples}")
        self._gyro_zero = (float(mean_reading), int(samples))
        self.reset()

    def reset(self) -> None:
        """Forget the path, the history and the state."""
        n = self.noise
        self.buffer.reset()
        self.estimate: float | None = None
        self.std = math.nan
        self.std_parts = dict.fromkeys(STD_PARTS, math.nan)
        self.frames = self.updates = self.rejected = 0
        self._gated = 0
        self._history: deque[_Tick] = deque()
        self._previous_input: tuple[float, float, float] | None = None
        x0 = np.zeros(self._states)
        p0 = np.diag(
            [
                *(0.0, 0.0, 0.0),
                *(n.initial_slip_velocity**2, n.initial_gyro_bias**2, n.initial_wheel_speed_bias**2),
                n.vo_yaw_bias**2,
                *((n.tractor_slip**2,) if self._error_state else ()),
                *((n.vo_axial_scale**2,) if self._axial_state else ()),
                *((n.vo_axial_flow**2,) if self._flow_state else ()),
            ]
        )
        if self._gyro_zero is not None:  # zeroed at standstill: the mean reading and its variance
            x0[_BG] = self._gyro_zero[0]
            p0[_BG, _BG] = n.gyro_noise**2 / self._gyro_zero[1]
        self._start = (x0, p0)
        self._innovation_power = math.nan  # m_k and V_k of (K2)
        self._expected_power = math.nan
        self._slip_evidence = 0.0
        self._modelled_slip = 0.0  # v_m of (K2)
        self._chain.reset()
        self._frame_interval = 0.0
        self.kinematic_share = 0.0
        self._coupling = np.zeros(2)  # the last frame's (c_x, c_y)
        self.kinematic_std = math.nan
        self._nis: deque[float] = deque(maxlen=n.innovation_window)
        self.innovation_ratio = 1.0
        # Committed increments still ahead of the follow point: start pose (x, y, ψ), end station x_e and
        # covariance, all in the anchor's frame.
        self._starts = np.zeros((0, 3))
        self._ends = np.zeros((0, 2))
        self._covs = np.zeros((0, 3, 3))
        self._durations = np.zeros(0)

    # ------------------------------------------------------------------ propagation

    def _steer_term(self, steer: np.ndarray | None) -> float:
        if steer is None or self.steer_weights.size == 0:
            return 0.0
        s = np.asarray(steer, dtype=float).reshape(-1)
        if s.size != self.steer_weights.size:
            raise InputError(f"steer needs {self.steer_weights.size} steer angles of unit {self.unit}, got {s.size}")
        return float(np.dot(self.steer_weights, np.tan(s)))

    def propagate(
        self,
        tick: int,
        dt: float,
        yaw_rate: float,
        wheel_speed: float,
        steer: np.ndarray | None = None,
        tractor: TractorSignals | ChainSignals | None = None,
    ) -> None:
        """Advance to control tick ``tick`` with this tick's signals; update :attr:`estimate`.

        Parameters
        ----------
        tick
            Control tick number (increasing).
        dt
            Time since the previous tick [s] (ignored on the first).
        yaw_rate, wheel_speed
            Measured yaw rate [rad/s] and wheel speed [m/s] of the unit (its own gyro, and an unsteered axle's
            wheel-speed sensor).
        steer
            Measured steer of the unit's steerable axles [rad] (layout order; empty or ``None`` for none).
        tractor
            The signals of the zero-slip measurement (K1) (``None``: none this tick): :class:`TractorSignals` for
            the first towed unit, :class:`ChainSignals` for any (:mod:`sensor.unit_kinematics`).
        """
        sample = (float(yaw_rate), float(wheel_speed), self._steer_term(steer))
        if not all(math.isfinite(v) for v in sample):
            raise InputError(f"trailer signals {sample} must be finite")
        # σ_k² of (K3) on this step, kept for re-filtering (the inflated model has no such state)
        if self._error_state:
            kinematic_variance = self._kinematic_variance(self._history[-1].x if self._history else self._start[0])
        else:
            kinematic_variance = 0.0
        if self._previous_input is None:
            x, p = self._start
            x, p = x.copy(), p.copy()
            inputs = (0.0, *sample)
        else:
            prev = self._previous_input
            inputs = (float(dt), *(0.5 * (a + b) for a, b in zip(prev, sample, strict=True)))
            last = self._history[-1]
            x, p = self._step(last.x, last.p, inputs, kinematic_variance)
        kinematic: tuple[tuple[np.ndarray, float, float], ...] = ()
        lateral = math.nan
        if tractor is not None and self.noise.kinematics and self._previous_input is not None:
            lateral = self._chain.lateral(tractor, float(dt))
            self._modelled_slip = self._chain.modelled_slip  # the rear slip the compensated points predict, (K2)
            if math.isfinite(lateral):
                kinematic = self._kinematic_rows(sample, lateral, float(dt), x)
                x, p = _apply_rows(x, p, kinematic)
        elif tractor is not None and self.noise.kinematics:
            self._chain.remember(tractor)
        self._history.append(_Tick(tick, inputs, x, p, kinematic, lateral, kinematic_variance))
        self._previous_input = sample
        self._read()

    def _step(
        self, x: np.ndarray, p: np.ndarray, inputs: tuple[float, ...], kinematic_variance: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """One control period of eqs (1)–(2) and the covariance (and of (K3) with ``σ_k²`` = ``kinematic_variance``)."""
        dt, r_m, w_m, tan_steer = inputs
        r = r_m - x[_BG]
        u = w_m - x[_BW]
        v = r * self.slip_point + u * tan_steer + x[_VS]
        th = r * dt
        if abs(th) > 1e-9:
            a, b = math.sin(th) / th, (1.0 - math.cos(th)) / th
        else:
            a, b = 1.0 - th * th / 6.0, 0.5 * th
        dp = np.array([a * u - b * v, b * u + a * v]) * dt  # eq (2)
        c, s = math.cos(x[2]), math.sin(x[2])
        rot = np.array([[c, -s], [s, c]])
        out = x.copy()
        out[:2] += rot @ dp
        out[2] += th
        # Jacobian (first order in δψ) and noise input of the (gyro, wheel) sample noise.
        ex, ey = rot[:, 0], rot[:, 1]
        lever, along = ey * (self.slip_point * dt), (ex + ey * tan_steer) * dt
        f = self._f
        f[:2, 2] = (-(s * dp[0] + c * dp[1]), c * dp[0] - s * dp[1])  # ∂/∂Δψ of R(Δψ)·δp
        f[:2, _VS] = ey * dt
        f[:2, _BG] = -lever
        f[2, _BG] = -dt
        f[:2, _BW] = -along
        g = self._g
        g[:2, 0] = lever
        g[2, 0] = dt
        g[:2, 1] = along
        q = (g * self._sample_variance) @ g.T
        q[_VS:_BPSI, _VS:_BPSI] += self._walk_time * dt
        q[_BPSI, _BPSI] += self._walk_distance * abs(u) * dt
        if self._error_state:  # (K3): ε_k ← φ·ε_k, its variance relaxing to σ_k² with the correlation time
            phi = math.exp(-dt / self.noise.kinematic_error_time)
            out[_EK] = phi * x[_EK]
            f[_EK, _EK] = phi
            q[_EK, _EK] += kinematic_variance * (1.0 - phi * phi)
        for i in (self._sz, self._sf):  # (3'): s_z and s_f random walks in distance
            if i is not None:
                q[i, i] += self.noise.vo_axial_scale_walk**2 * abs(u) * dt
        return out, f @ p @ f.T + q

    def _kinematic_rows(
        self, sample: tuple[float, float, float], lateral: float, dt: float, x: np.ndarray
    ) -> tuple[tuple[np.ndarray, float, float], ...]:
        """(K1) of this tick as an ``(H, z, R)`` row, with σ from the slip evidence (K2) and the push (K4) of the
        predicted state ``x``."""
        r_m, w_m, tan_steer = sample
        h = np.zeros(self._states)
        h[_VS] = 1.0
        h[_BG] = -self.slip_point  # (K1) is taken with the measured rates: their biases enter it through (1)
        h[_BW] = -tan_steer
        z = lateral - (r_m * self.slip_point + w_m * tan_steer)  # (K1): the slip velocity the tractor implies
        n = self.noise
        variance = self._kinematic_variance(x)
        self.kinematic_std = math.sqrt(variance)
        if self._error_state:  # (K3): ε_k is a state, the tick's own noise white
            h[_EK] = 1.0
            # the evidence of slip beyond the floor also as (K2)'s correlated white error: seen slip de-weights the
            # kinematics at once, while the state learns their steady error
            excess = (variance - self._kinematic_floor()) * n.kinematic_error_time / max(dt, 1e-6)
            return ((h, z, n.kinematic_white_noise**2 + excess),)
        if math.isfinite(self._expected_power) and self._frame_interval > 0.0:  # information per second, eq (5)
            camera = 1.0 / (self._expected_power * self._frame_interval)
            self.kinematic_share = (1.0 / (variance * n.kinematic_error_time)) / (
                1.0 / (variance * n.kinematic_error_time) + camera
            )
        return ((h, z, variance * n.kinematic_error_time / max(dt, 1e-6)),)  # a time-correlated error

    def _kinematic_floor(self) -> float:
        """σ_k²'s floor of (K2), ``σ_0² + (u_C·v_m)²``, with the last tick's modelled rear slip [m²/s²]."""
        n = self.noise
        modelled = n.tractor_stiffness_uncertainty * self._modelled_slip
        return n.tractor_slip**2 + modelled * modelled

    def _kinematic_variance(self, x: np.ndarray) -> float:
        """σ_k² of (K2): the slip evidence so far, at least its floor and (K4)'s push of the state ``x`` [m²/s²]."""
        return max(self._kinematic_floor(), self._slip_evidence, self._push_variance(x))  # (K2), (K4)

    def _push_variance(self, x: np.ndarray) -> float:
        """(K4): ``(u_p·v_s)²``, the tractor's rear slip a trailer slipping at ``v_s`` pushes it into [m²/s²]."""
        push = self.noise.trailer_push_share * float(x[_VS])
        return push * push

    def _kinematic_lateral_step(self, index: int, x: np.ndarray) -> float | None:
        """The kingpin's lateral displacement from the anchor to history ``index`` in the anchor's frame, had no
        tractor tyre slipped: Cheng's lateral velocity with the trailer's speed and the gyro (``None``: no
        tractor signals on some tick)."""
        heading = y = 0.0
        for t in list(self._history)[1 : index + 1]:
            dt, r_m, w_m, _ = t.inputs
            if math.isnan(t.tractor_lateral):
                return None
            mid = heading + 0.5 * (r_m - x[_BG]) * dt
            y += (math.sin(mid) * (w_m - x[_BW]) + math.cos(mid) * t.tractor_lateral) * dt
            heading += (r_m - x[_BG]) * dt
        return y

    def _weigh_slip_evidence(self, disagreement: float, lateral_variance: float, interval: float) -> None:
        """(K2): the camera's lateral kingpin motion against the kinematics' over a frame ``interval`` [s]."""
        if interval <= 0.0:
            return
        self._frame_interval = interval
        alpha = min(1.0, interval / self.noise.slip_evidence_time)
        velocity, expected = disagreement / interval, lateral_variance / interval**2
        if math.isnan(self._innovation_power):
            self._innovation_power, self._expected_power = velocity, expected
        else:
            self._innovation_power += alpha * (velocity - self._innovation_power)
            self._expected_power += alpha * (expected - self._expected_power)
        # the mean's own variance, had the innovations been white: α/(2 − α) of theirs
        evidence = max(0.0, self._innovation_power**2 - self._expected_power * alpha / (2.0 - alpha))
        if self.noise.slip_evidence_hold:  # (K2'): no faster down than a slip that stopped
            evidence = max(evidence, (1.0 - alpha) ** 2 * self._slip_evidence)
        self._slip_evidence = evidence

    # ------------------------------------------------------------------ measurement

    def measurement(self, camera_motion: np.ndarray, covariance: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """Kingpin increment ``(dx, dy, dψ)`` of one camera motion and its 3×3 covariance (module notes).

        ``covariance`` is the odometry's 6×6 covariance of ``(rx, ry, rz, tx, ty, tz)`` of Tr_delta, whose
        inverse is ``camera_motion``; ``None``: the floor alone.
        """
        n = self.noise
        z = np.array(self.geometry.kingpin_increment(camera_motion))
        r = np.diag([n.vo_translation_floor**2, n.vo_translation_floor**2, n.vo_rotation_floor**2])
        if covariance is not None and np.all(np.isfinite(covariance)):
            theta = transform_to_params(invert_rigid(camera_motion))
            jac = np.empty((3, 6))
            h = 1e-7
            for i in range(6):
                d = theta.copy()
                d[i] += h
                jac[:, i] = (np.array(self.geometry.kingpin_increment(invert_rigid(params_to_transform(d)))) - z) / h
            r = r + n.vo_covariance_scale * (jac @ np.asarray(covariance, dtype=float) @ jac.T)
        return z, r

    def measure(self, tick: int, camera_motion: np.ndarray | None, covariance: np.ndarray | None = None) -> bool:
        """The motion of the frame taken on control tick ``tick`` (since the frame before it), released now.

        ``None`` (a failed, refused or dropped frame) commits the prediction to that tick. Ticks at or before
        the anchor are ignored. Returns whether the motion was used. Updates :attr:`estimate`.
        """
        if not self._history or tick <= self._history[0].tick:
            return False
        index = next((i for i, h in enumerate(self._history) if h.tick == tick), None)
        if index is None:
            raise InputError(f"frame of tick {tick} is ahead of the filter (last tick {self._history[-1].tick})")
        self.frames += 1
        entry = self._history[index]
        x, p = entry.x.copy(), entry.p.copy()
        used = False
        if camera_motion is not None and np.all(np.isfinite(camera_motion)):
            z, r = self.measurement(np.asarray(camera_motion, dtype=float), covariance)
            h = np.zeros((3, self._states))
            h[:, :3] = np.eye(3)
            coupling = (
                self.noise.vo_bias_coupling * r[:2, 2] / r[2, 2]
            )  # the yaw–translation ambiguity of this frame (module notes)
            h[:2, _BPSI] = x[0] * coupling  # the odometry's error per metre over the distance since the anchor
            h[2, _BPSI] = x[0]
            if self._sz is not None or self._sf is not None:  # (3'): the camera's displacement, along its axis
                along, across = self._camera_displacement(x[:3])
                if self._sz is not None:
                    h[:2, self._sz] = along * self._optical_axis
                if self._sf is not None:
                    h[:2, self._sf] = across * abs(across) * self._optical_axis
            self._coupling = coupling
            innovation = z - h @ x
            innovation[2] = math.remainder(innovation[2], 2.0 * math.pi)
            ph = p @ h.T
            s = h @ ph + r
            nis = float(innovation @ np.linalg.solve(s, innovation))
            interval = sum(t.inputs[0] for t in list(self._history)[1 : index + 1])
            kinematic_y = self._kinematic_lateral_step(index, x)
            if kinematic_y is not None:  # (K2): the camera's lateral motion against the tractor's kinematics
                camera_y = z[1] - h[1, _BPSI] * x[_BPSI]
                for i in (self._sz, self._sf):  # less the estimated error along the optical axis, (3')
                    if i is not None:
                        camera_y -= h[1, i] * x[i]
                self._weigh_slip_evidence(camera_y - kinematic_y, float(r[1, 1]), interval)
            if nis > self.noise.gate and self._gated < self.noise.max_gated:
                self._gated += 1
                self.rejected += 1
            else:
                if nis > self.noise.gate:
                    s = h @ ph + r * (nis / self.noise.gate)
                self._gated = 0
                k = np.linalg.solve(s, ph.T).T  # P Hᵀ S⁻¹
                x = x + k @ innovation
                p = p - k @ h @ p
                p = 0.5 * (p + p.T)
                used = True
                self.updates += 1
                self._nis.append(min(nis, self.noise.gate))
                self.innovation_ratio = max(MIN_INNOVATION_RATIO, float(np.mean(self._nis)) / 3.0)
        self._commit(index, x, p)
        self._read()
        return used

    def _commit(self, index: int, x: np.ndarray, p: np.ndarray) -> None:
        """Push the increments up to history ``index`` (ending at ``x``) and make that tick the anchor."""
        poses = [h.x[:3] for h in list(self._history)[: index + 1]]
        poses[-1] = x[:3]
        for a, b in itertools.pairwise(poses):
            self.buffer.push(*_relative(a, b))
        end = x[:3].copy()
        # Move the committed increments into the new anchor frame, add this one, drop those behind the follow point.
        starts = np.vstack([self._starts, [[0.0, 0.0, 0.0]]])
        ends = np.vstack([self._ends, end[None, :2]])
        covs = np.concatenate([self._covs, p[None, :3, :3]])
        durations = np.append(self._durations, sum(t.inputs[0] for t in list(self._history)[1 : index + 1]))
        starts = _into(starts, end)
        ends = _into(np.column_stack([ends, np.zeros(len(ends))]), end)[:, :2]
        keep = starts[:, 0] > -self.follow_point_offset - 2.0
        self._starts, self._ends, self._covs = starts[keep], ends[keep], covs[keep]
        self._durations = durations[keep]
        # The new anchor: Δ restarts from zero; the other states keep their covariance.
        anchor_x = x.copy()
        anchor_x[:3] = 0.0
        anchor_p = np.zeros_like(p)
        anchor_p[3:, 3:] = p[3:, 3:]
        rest = list(self._history)[index + 1 :]
        self._history = deque([_Tick(self._history[index].tick, (0.0, 0.0, 0.0, 0.0), anchor_x, anchor_p)])
        for h in rest:  # re-filter to the present with the stored inputs and measurements (delayed measurement)
            last = self._history[-1]
            nx, np_ = self._step(last.x, last.p, h.inputs, h.kinematic_variance)
            nx, np_ = _apply_rows(nx, np_, h.kinematic)
            self._history.append(replace(h, x=nx, p=np_))

    # ------------------------------------------------------------------ estimate

    def _read(self) -> None:
        """Off-tracking and its standard deviation at the newest tick (module notes, eqs (3)–(4))."""
        now = self._history[-1]
        d = now.x[:3]
        lfp = self.follow_point_offset
        points = self.buffer.points
        value = None
        if len(points) >= 2 and self.buffer.distance_travelled + math.hypot(d[0], d[1]) >= lfp:
            value = offtracking_from_path(np.vstack([points, d[None, :2]]), d[:2], float(d[2]), lfp)
        if value is None or not math.isfinite(value) or abs(value) > lfp:
            self.estimate, self.std = None, math.nan
            self.std_parts = dict.fromkeys(STD_PARTS, math.nan)
            return
        # eq (3) over the committed increments ahead of the follow point, in the current frame ...
        c, s = math.cos(d[2]), math.sin(d[2])
        independent = 0.0
        coherent = np.zeros(3)  # G of eq (5): ∂e_tr/∂(b_g, β_ψ), and the coupled part of the second
        lever = 0.0  # ∂e_tr/∂v_s, a slip velocity error held over the window [s]
        cross = 0.0  # ∂e_tr/∂s_f
        axial = 0.0  # ∂e_tr/∂u_z: the change of e_tr per relative error of the translation along the optical axis
        if len(self._covs):
            starts, ends = self._starts, self._ends
            ahead = c * (starts[:, 0] - d[0]) + s * (starts[:, 1] - d[1]) > -lfp
            if ahead.any():
                heading = starts[ahead, 2] - d[2]
                station = c * (ends[ahead, 0] - d[0]) + s * (ends[ahead, 1] - d[1])
                g = np.column_stack([-np.sin(heading), -np.cos(heading), station + lfp])
                independent = float(np.einsum("ni,nij,nj->", g, self._covs[ahead], g))
                length = np.hypot(ends[ahead, 0] - starts[ahead, 0], ends[ahead, 1] - starts[ahead, 1])
                coherent = self._bias_effect(g, length, self._durations[ahead])
                lever += float(np.sum(g[:, 1] * self._durations[ahead]))
                if self.noise.vo_axial_scale_uncertainty > 0.0 or self._axial_state or self._flow_state:
                    turns = np.diff(np.append(starts[:, 2], 0.0))[ahead]  # each increment's Δψ (it ends at the next)
                    axial, cross = self._axial_effect(g, starts[ahead], ends[ahead], turns)
        # ... and the current one, from the anchor (heading −Δψ in the current frame) to the kingpin.
        g_now = np.array([s, -c, lfp])
        independent += float(g_now @ now.p[:3, :3] @ g_now)
        if self.noise.vo_axial_scale_uncertainty > 0.0 or self._axial_state or self._flow_state:
            now_axial, now_cross = self._axial_effect(g_now[None, :], np.zeros((1, 3)), d[None, :2], np.array([d[2]]))
            axial, cross = axial + now_axial, cross + now_cross
        elapsed = sum(t.inputs[0] for t in list(self._history)[1:])
        coherent += self._bias_effect(g_now[None, :], np.array([math.hypot(d[0], d[1])]), np.array([elapsed]))
        self._lateral_lever = lever + g_now[1] * elapsed
        biases = now.p[np.ix_(self._biases, self._biases)]
        effects = np.array(  # (3'): s_z and s_f are coherent over the path too
            [*coherent[:2], *((axial,) if self._axial_state else ()), *((cross,) if self._flow_state else ())]
        )
        # the disagreement the kinematics' share carries into the slip velocity, coherent over the window
        evidence = max(self._slip_evidence, 0.0)
        if self.noise.trailer_push_share > 0.0:  # (K4): the kinematics may err by the push they cannot see
            evidence = max(evidence, self._push_variance(now.x))
        disagreement = self.kinematic_share * math.sqrt(evidence) * self._lateral_lever
        # the coupling is known to vo_bias_coupling_uncertainty: so is the correction it applies for β_ψ
        coupling = self.noise.vo_bias_coupling_uncertainty * now.x[_BPSI] * coherent[2]
        self.std_parts = {
            "increments": self.innovation_ratio * independent,
            "biases": self.innovation_ratio * float(effects @ biases @ effects),
            "coupling": coupling**2 + (self.noise.vo_axial_scale_uncertainty * axial) ** 2,
            "kinematics": disagreement**2,
            "unexplained": self.noise.offtracking_bias_std**2,
        }
        variance = sum(self.std_parts.values())  # eq (5)
        std = math.sqrt(max(variance, 0.0))
        if std > self.noise.max_std:
            self.estimate, self.std = None, std
            return
        self.estimate, self.std = float(value), std

    def std_contributions(self) -> dict[str, float]:
        """Each term of eq (5) as the standard deviation it alone would give [m] (NaN without an estimate).

        Their squares add up to :attr:`std`'s square: they say what the reported uncertainty is made of (the
        odometry's increments, the biases, the bias coupling, the kinematics' disagreement, the constant).
        """
        return {part: math.sqrt(max(self.std_parts[part], 0.0)) for part in STD_PARTS}

    def _axial_effect(
        self, g: np.ndarray, starts: np.ndarray, ends: np.ndarray, turns: np.ndarray
    ) -> tuple[float, float]:
        """``A_z`` of eq (5): the change of ``e_tr`` per relative error ``u_z`` of the odometry's translation along the
        camera's optical axis ``o``, coherent over increments with sensitivities ``g`` (n×3), start poses and end
        points in one frame and turns ``Δψ``: each increment's camera displacement (its kingpin's, plus the lever
        ``(R(Δψ) − I)·p_c`` of the camera at ``p_c``) has the component ``a = o·Δ_c`` along the axis, and the error
        ``u_z·a·o`` of the increment moves ``e_tr`` by ``g_xy·o`` times that. The second value is the same for
        ``s_f`` of (3'), the square ``(t·Δ_c)·|t·Δ_c|`` of the component across the axis in its place."""
        axis, camera = self._optical_axis, self.geometry.camera_position
        c, s = np.cos(starts[:, 2]), np.sin(starts[:, 2])
        dx, dy = ends[:, 0] - starts[:, 0], ends[:, 1] - starts[:, 1]
        local = np.column_stack([c * dx + s * dy, -s * dx + c * dy])  # in each increment's start frame
        ct, st = np.cos(turns), np.sin(turns)
        lever = np.column_stack([(ct - 1.0) * camera[0] - st * camera[1], st * camera[0] + (ct - 1.0) * camera[1]])
        moved = local + lever
        along, across = moved @ axis, moved @ np.array([axis[1], -axis[0]])
        across = across * np.abs(across)
        sensitivity = g[:, :2] @ axis
        return float(np.sum(along * sensitivity)), float(np.sum(across * sensitivity))

    def _camera_displacement(self, delta: np.ndarray) -> tuple[float, float]:
        """The camera's displacement along and across its optical axis over a kingpin increment ``(dx, dy, dψ)``
        [m]: the kingpin's, plus the lever ``(R(dψ) − I)·p_c`` of the camera at ``p_c`` (as :meth:`_axial_effect`);
        "across" is along ``t = (o_y, −o_x)``, the axis turned a right angle clockwise."""
        camera, ct, st = self.geometry.camera_position, math.cos(delta[2]), math.sin(delta[2])
        mx = delta[0] + (ct - 1.0) * camera[0] - st * camera[1]
        my = delta[1] + st * camera[0] + (ct - 1.0) * camera[1]
        o = self._optical_axis
        return float(mx * o[0] + my * o[1]), float(mx * o[1] - my * o[0])

    def _bias_effect(self, g: np.ndarray, length: np.ndarray, duration: np.ndarray) -> np.ndarray:
        """``G`` of eq (5): the change of ``e_tr`` per unit error of ``(b_g, β_ψ)``, coherent over increments
        with sensitivities ``g`` (n×3), lengths [m] and durations [s]: a gyro bias turns and, through eq (1), moves
        each increment by its duration; an odometry error per metre along the frame's ambiguity by its length. The
        third entry is the part of the second that the coupling carries (the translation along the ambiguity)."""
        gyro = -float(np.sum((g[:, 2] + g[:, 1] * self.slip_point) * duration))
        c_x, c_y = self._coupling
        coupled = float(np.sum((g[:, 0] * c_x + g[:, 1] * c_y) * length))
        return np.array([gyro, coupled + float(np.sum(g[:, 2] * length)), coupled])

    @property
    def state(self) -> np.ndarray:
        """Newest state ``[Δx, Δy, Δψ, v_s, b_g, b_w, β_ψ]``, then ``ε_k`` with (K3) and ``s_z``, ``s_f`` of (3') when
        on (module notes; before the first tick, the start)."""
        return (self._history[-1].x if self._history else self._start[0]).copy()

    @property
    def covariance(self) -> np.ndarray:
        """Newest state covariance, 7×7 and one more row per state that is on (before the first tick, the start)."""
        return (self._history[-1].p if self._history else self._start[1]).copy()


def _apply_rows(
    x: np.ndarray, p: np.ndarray, rows: tuple[tuple[np.ndarray, float, float], ...]
) -> tuple[np.ndarray, np.ndarray]:
    """Sequential scalar Kalman updates with the rows ``(H, z, R)``."""
    for h, z, r in rows:
        ph = p @ h
        s = float(h @ ph) + r
        k = ph / s
        x = x + k * (z - float(h @ x))
        p = p - np.outer(k, ph)
    if rows:
        p = 0.5 * (p + p.T)
    return x, p


def _relative(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
    """Increment ``(dx, dy, dψ)`` from pose ``a`` to pose ``b`` (both in one frame), in ``a``'s frame."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return c * dx + s * dy, -s * dx + c * dy, float(b[2] - a[2])


def _into(poses: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Poses ``(n, 3)`` re-expressed in the frame of ``origin`` (a pose in their frame)."""
    c, s = math.cos(origin[2]), math.sin(origin[2])
    x = poses[:, 0] - origin[0]
    y = poses[:, 1] - origin[1]
    return np.column_stack([c * x + s * y, -s * x + c * y, poses[:, 2] - origin[2]])
