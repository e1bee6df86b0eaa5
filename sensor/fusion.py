"""Fused VISO-OT: a Kalman filter of the trailer's signals, the zero-slip kinematics and the stereo camera's odometry.

VISO-OT (de Saxe & Cebon 2018, §2.2; :mod:`sensor.viso_ot`) gives the off-tracking at the camera rate, a camera latency
late, and has nothing between frames or across failed ones; Cheng's zero-slip kinematics (Cheng 2009;
docs/vehicle_dynamics.md §2.3, §7.2) give the kingpin's motion at every control tick from the tractor's signals, but are
blind to tyre slip. The paper lists a Kalman filter as future work (§5). This one propagates at the control rate with
the trailer's yaw-rate gyro, a wheel-speed sensor on an unsteered trailer axle and the trailer's own steer angles; takes
Cheng's kinematics as a measurement whose noise follows the evidence of slip; and corrects with every visual-odometry
motion, weighted by its Gauss–Newton covariance, with the odometry's own systematic yaw error as a state. The kingpin
increments it produces feed the one path buffer (:class:`~vehicle_model.offtracking.OfftrackingBuffer`, eqs (3)–(7)).
docs/field_bias.md says why each part is there and what it removes under field conditions.

Any towed unit. Everything below is written for the first towed unit (the semi-trailer behind the tractor), and holds
for any towed unit ``k`` of a longer combination (``unit``): "the trailer" is unit ``k`` with its own gyro, wheel speed,
steerable axles and follow point, "the kingpin" its front coupling (the fifth wheel of unit ``k − 1``, or a dolly's
drawbar eye), and "the tractor's signals" of the zero-slip measurement are carried down the chain of units ahead of it
(:mod:`sensor.unit_kinematics`).

The model (state, propagation (1)–(2), zero-slip measurement (K1), camera's motion (3), (3')) is in
:mod:`sensor.fusion_model`; the zero-slip noise, the evidence of slip (K2)–(K4), in :mod:`sensor.fusion_slip`; the std
(4)–(5) in :mod:`sensor.fusion_std` (a following unit's persisting error: :mod:`sensor.fusion_consider`). This module
runs them: the ticks since the last frame, the delayed measurements, the commit.

Delayed measurements. A frame taken on tick ``k`` is released ``latency`` ticks later
(:mod:`scenarios.camera.delivery`). The filter keeps the state, covariance, inputs and zero-slip measurements of every
tick since the anchor; :meth:`FusedVisoOt.measure` updates the stored state of tick ``k`` and re-filters to the present
with the stored inputs and measurements (an out-of-sequence update by re-filtering). With zero latency this is the
ordinary update; with any latency it is exactly what the filter would have done had the motion come on tick ``k``, seen
no earlier than its release.

Commit. After each frame (measured or not) the increments from the anchor to the frame are pushed into the path buffer
(the propagated per-tick increments, the last one carrying the correction: control-rate resolution), the frame becomes
the anchor, ``(Δx, Δy, Δψ)`` restart from zero and only the covariance of the other states is carried on (the usual
reset of a delta state). A failed, refused or dropped frame is committed from the prediction alone: a gap is bridged
with a covariance that grows with its length.
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

from .fusion_adaptive import AdaptiveCovariance
from .fusion_axial import AxialRegression
from .fusion_consider import Transition, consider_of
from .fusion_coupling import CouplingMeasurement
from .fusion_coupling_ratio import CouplingRatio
from .fusion_model import (
    BG,
    BPSI,
    BW,
    VS,
    ProcessModel,
    StateLayout,
    apply_rows,
    camera_displacement,
    camera_increment,
    gated_update,
    into_frame,
    relative_pose,
    yaw_coupling,
)
from .fusion_noise import FusionNoise
from .fusion_reference import OwnReference
from .fusion_slip import (
    ScrubDemand,
    ZeroSlipNoise,
    coupling_correction_std,
    kinematic_disagreement,
    kinematic_lateral_step,
    scrub_bias_share,
    scrub_coupling_yield,
)
from .fusion_std import MIN_INNOVATION_RATIO, STD_PARTS, IncrementWindow, path_effects, reference_share, window_nis
from .level_reference import horizontal_speed
from .unit_kinematics import ChainKinematics, ChainSignals, TractorSignals, slip_kinematics, unit_axles
from .unit_slip_reference import TRAILER_REFERENCE
from .viso_ot import VisoOtEstimator

__all__ = [
    "MIN_INNOVATION_RATIO",
    "STD_PARTS",
    "ChainSignals",
    "CouplingMeasurement",
    "FusedVisoOt",
    "FusionNoise",
    "TractorSignals",
    "slip_kinematics",
]


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
    scrub: float = 0.0  # the scrub demand D of (K5) on the step into this tick
    transition: Transition | None = None  # Φ from the anchor, of sensor.fusion_consider (None: not kept)


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
    level_reference
        How the camera's motion is made horizontal (:class:`~sensor.viso_ot.VisoOtEstimator`): ``planar`` (default,
        the level road), ``accelerometer`` (each frame's tilt given to :meth:`measure`) or ``odometry``.

    Attributes
    ----------
    estimate : float or None
        Off-tracking [m] at the last tick (``None``: no estimate yet, or too uncertain).
    std : float
        Its standard deviation [m] (NaN without an estimate).
    frames, updates, rejected : int
        Frames seen, motions used, motions refused by the gate.
    coupling_updates, coupling_rejected : int
        A following unit's measurements (:mod:`sensor.fusion_coupling`) used and refused by the gate.
    kinematic_std : float
        σ_k of (K2), the zero-slip measurement's standard deviation at the last tick [m/s] (NaN before the first):
        small where the filter trusts the kinematics, large where it has seen slip.
    innovation_ratio : float
        ``ρ/3`` of eq (5): the camera motions' mean normalised innovation squared over its expectation.
    std_parts : dict[str, float]
        The five variance terms of eq (5) at the last tick [m²], keyed by :data:`STD_PARTS` (NaN without an
        estimate); :meth:`std_contributions` gives them as standard deviations.
    scrub_demand, frame_scrub_demand : float
        ``D`` of (K5) on the last tick (:mod:`sensor.fusion_slip`): 0 while every axle rolls within its tyres'
        linear range, 1 where one runs at twice ``scrub_slip_angle``; ``frame_scrub_demand`` that of the last camera
        frame's tick, which its motion and the coupled correction were taken at ((K5)–(K6)).
    noise : FusionNoise
        The settings it runs with: ``noise``, with a side rig's or a linked rig's in their place
        (:meth:`~sensor.fusion_noise.FusionNoise.for_camera`).
    """

    def __init__(
        self,
        params: VehicleParams,
        camera_in_trailer: np.ndarray,
        noise: FusionNoise | None = None,
        unit: int = 1,
        level_reference: str = "planar",
    ) -> None:
        self.params = params
        # eqs (1)–(2): camera motion → kingpin increment (it also checks the unit and the level reference)
        self.geometry = VisoOtEstimator(params, camera_in_trailer, unit=unit, level_reference=level_reference)
        axis = self.geometry.mount_rotation[:2, 2]  # the optical axis in the unit's ground plane
        self._optical_axis = axis / max(float(np.hypot(*axis)), 1e-12)
        noise = noise if noise is not None else FusionNoise()
        self.unit = self.geometry.unit  # a side rig's settings, or a linked rig's on unit 2 or further:
        self.noise = noise.for_camera((float(self._optical_axis[0]), float(self._optical_axis[1])), self.unit)
        self.follow_point_offset = params.follow_point_offset_of(self.unit)
        self.slip_point, self.steer_weights = slip_kinematics(params, self.unit)
        point = self.noise.kinematic_rear_point
        # (K1)'s z_c: the tractor's kinematics carried down the chain, or the unit's own accelerometer's slip (T2)
        own = point == TRAILER_REFERENCE
        self._own_reference = OwnReference(params, self.unit, self.noise) if own else None  # (T2), (R1)
        self._chain = ChainKinematics(params, self.unit, "lateral_acceleration" if own else point)  # type: ignore[arg-type]
        self.buffer = OfftrackingBuffer(self.follow_point_offset)
        layout = StateLayout.of(self.noise)
        self._layout = layout
        self._error_state = layout.error_state  # ε_k of (K1) an eighth state, (K3)
        self._axial_state = layout.sz is not None  # s_z of (3') a state
        self._flow_state = layout.sf is not None  # s_f of (3') a state
        self._sz, self._sf, self._states = layout.sz, layout.sf, layout.size
        self._biases = layout.biases
        self._model = ProcessModel(self.noise, self.slip_point, layout)
        self._zero_slip = ZeroSlipNoise(self.noise, layout, self.slip_point)
        self._evidence = self._zero_slip.evidence
        self._scrub = ScrubDemand(self.noise, *unit_axles(params, self.unit), self.slip_point, self.steer_weights)
        self._consider = consider_of(layout.size, self.noise.coupling_persisting_error)  # the reference's, persisting
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
        self.frames = self.updates = self.rejected = self.coupling_updates = self.coupling_rejected = 0
        self._gated = self._coupling_gated = 0
        self._history: deque[_Tick] = deque()
        self._previous_input: tuple[float, float, float] | None = None
        x0, p0 = self._layout.start(n)
        if self._gyro_zero is not None:  # zeroed at standstill: the mean reading and its variance
            x0[BG] = self._gyro_zero[0]
            p0[BG, BG] = n.gyro_noise**2 / self._gyro_zero[1]
        self._start = (x0, p0)
        self._zero_slip.reset()  # m_k, V_k, e_k and v_m of (K2)
        self._consider.reset()
        self._chain.reset()
        self._coupling = np.zeros(2)  # the last frame's (c_x, c_y)
        self.frame_scrub_demand = 0.0
        self.scrub_demand = 0.0
        self._nis: deque[float] = deque(maxlen=n.innovation_window)
        self._adaptive = AdaptiveCovariance(n)  # m of (V1): the camera's covariance grown by its innovations
        self._ratio = CouplingRatio(n)  # ρ̂ of (L2): the lasting coupling's ratio to eq (3)'s (off: 1)
        self.innovation_ratio = 1.0
        # Committed increments still ahead of the follow point: start pose (x, y, ψ), end station x_e and
        # covariance, all in the anchor's frame.
        self._starts, self._ends, self._covs = np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 3, 3))
        self._durations = np.zeros(0)
        self._demands, self._shares = np.zeros(0), np.zeros((0, 3, 3))  # D of (K5) and (4')'s I − K_Δ of each
        axial_states = [i for i in (self._sz, self._sf) if i is not None]  # (A1) of sensor.fusion_axial, when asked
        posterior = n.vo_axial_effect == "posterior" and axial_states
        self._axial_regression = AxialRegression(axial_states) if posterior else None

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
            wheel-speed sensor, along the ground: made horizontal with the tilt of the last frame, ``u·cos θ``).
        steer
            Measured steer of the unit's steerable axles [rad] (layout order; empty or ``None`` for none).
        tractor
            The signals of the zero-slip measurement (K1) (``None``: none this tick): :class:`TractorSignals` for
            the first towed unit, :class:`ChainSignals` for any (:mod:`sensor.unit_kinematics`); the tractor's wheel
            speed made horizontal with this unit's tilt, as the unit's own (the filter knows no other pitch).
        """
        sample = (float(yaw_rate), horizontal_speed(float(wheel_speed), self.geometry.tilt), self._steer_term(steer))
        if not all(math.isfinite(v) for v in sample):
            raise InputError(f"trailer signals {sample} must be finite")
        # σ_k² of (K3) on this step, kept for re-filtering (the inflated model has no such state)
        if self._error_state:
            kinematic_variance = self._zero_slip.variance(self._history[-1].x if self._history else self._start[0])
        else:
            kinematic_variance = 0.0
        before = self._history[-1].x if self._history else self._start[0]
        scrub = self._scrub(sample[0] - before[BG], sample[1] - before[BW], steer, float(before[VS]))  # (K5)
        self.scrub_demand = scrub
        if self._previous_input is None:
            x, p = self._start
            x, p = x.copy(), p.copy()
            inputs, step = (0.0, *sample), None
        else:
            prev = self._previous_input
            inputs = (float(dt), *(0.5 * (a + b) for a, b in zip(prev, sample, strict=True)))
            last = self._history[-1]
            x, p = self._step(last.x, last.p, inputs, kinematic_variance, scrub)
            step = (last.transition, self._model.transition)  # Φ before and F of sensor.fusion_consider
        stepped = p
        kinematic: tuple[tuple[np.ndarray, float, float], ...] = ()
        lateral = math.nan
        if tractor is not None and self.noise.kinematics and self._previous_input is not None:
            if self._own_reference is not None:  # (T2) of sensor.unit_slip_reference
                own = tractor.unit_lateral_acceleration
                lateral, slip = self._own_reference.lateral(float(yaw_rate), sample[1], steer, own)
                self._zero_slip.modelled_slip = slip  # the slip it predicts, uncertain by the stiffnesses, (K2)
                self._zero_slip.residual_variance = self._own_reference.floor_variance(sample[1], own)
                self._zero_slip.rate_sensitivity = self._own_reference.rate_sensitivity(steer, own)
            else:
                level = replace(tractor, speed=horizontal_speed(tractor.speed, self.geometry.tilt))  # the unit's θ
                lateral = self._chain.lateral(level, float(dt))
                self._zero_slip.modelled_slip = self._chain.modelled_slip  # the compensated points' rear slip, (K2)
            if math.isfinite(lateral):
                kinematic = self._zero_slip.rows(sample, lateral, float(dt), x)
                x, p = apply_rows(x, p, kinematic)
        elif tractor is not None and self.noise.kinematics:
            self._chain.remember(tractor)
        transition = self._consider.advance(step, stepped, kinematic, inputs[0])
        self._history.append(_Tick(tick, inputs, x, p, kinematic, lateral, kinematic_variance, scrub, transition))
        self._previous_input = sample
        self._read()

    def _step(
        self,
        x: np.ndarray,
        p: np.ndarray,
        inputs: tuple[float, ...],
        kinematic_variance: float = 0.0,
        scrub: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray]:
        """One control period of eqs (1)–(2) (:class:`~sensor.fusion_model.ProcessModel`), the slip velocity's walk
        widened by the scrub demand ``scrub`` of (K5)."""
        return self._model.step(x, p, inputs, kinematic_variance, scrub * self.noise.scrub_slip_walk)

    @property
    def kinematic_std(self) -> float:
        """σ_k of (K2) at the last tick [m/s] (class notes)."""
        return self._zero_slip.kinematic_std

    @property
    def kinematic_share(self) -> float:
        """The share of the lateral information the zero-slip kinematics carry against the camera's (eq (5))."""
        return self._zero_slip.kinematic_share

    # ------------------------------------------------------------------ measurement

    def measurement(
        self, camera_motion: np.ndarray, covariance: np.ndarray | None, tilt: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Kingpin increment ``(dx, dy, dψ)`` of one camera motion and its 3×3 covariance
        (:func:`~sensor.fusion_model.camera_increment`); ``covariance`` the odometry's 6×6 (``None``: the floor);
        ``tilt`` the unit's tilt at the frame (3×3) off the level road."""
        return camera_increment(self.geometry, self.noise, camera_motion, covariance, tilt)

    def measure(
        self,
        tick: int,
        camera_motion: np.ndarray | None,
        covariance: np.ndarray | None = None,
        tilt: tuple[float, float] | None = None,
        coupling: CouplingMeasurement | None = None,
    ) -> bool:
        """The motion of the frame taken on control tick ``tick`` (since the frame before it), released now.

        ``None`` (a failed, refused or dropped frame) commits the prediction to that tick. Ticks at or before
        the anchor are ignored. Returns whether the motion was used. Updates :attr:`estimate`. ``tilt``: the
        unit's (pitch, roll) [rad] when the frame was taken, required with ``level_reference="accelerometer"``.
        ``coupling``: the kingpin increment over the same frame from a following unit's camera
        (:mod:`sensor.fusion_coupling`), applied after the motion when ``noise.coupling_reference`` is on and it
        starts at the anchor (otherwise, or ``None``, none).
        """
        given = self.geometry.given_tilt(tilt)
        level_tilt = given
        if camera_motion is not None and np.all(np.isfinite(camera_motion)) and given is None:
            planar = self.geometry.level_reference == "planar"
            level_tilt = None if planar else self.geometry.level_increment(np.asarray(camera_motion, dtype=float))[1]
        try:
            return self._measure(tick, camera_motion, covariance, given, coupling)
        finally:
            if level_tilt is not None:  # the next frame's motion starts from this frame's tilt
                self.geometry.tilt = level_tilt

    def _measure(
        self,
        tick: int,
        camera_motion: np.ndarray | None,
        covariance: np.ndarray | None,
        given: np.ndarray | None,
        reference: CouplingMeasurement | None = None,
    ) -> bool:
        """:meth:`measure` with the frame's tilt as a rotation (``None`` on the level road or integrated)."""
        if not self._history or tick <= self._history[0].tick:
            return False
        index = next((i for i, h in enumerate(self._history) if h.tick == tick), None)
        if index is None:
            raise InputError(f"frame of tick {tick} is ahead of the filter (last tick {self._history[-1].tick})")
        self.frames += 1
        entry = self._history[index]
        self._consider.frame(entry.transition)
        x, p = entry.x.copy(), entry.p.copy()
        used, share = False, np.eye(3)  # share: of the increment's prior error, what a reference left, (4')
        if camera_motion is not None and np.all(np.isfinite(camera_motion)):
            z, r = self.measurement(np.asarray(camera_motion, dtype=float), covariance, given)
            r_floor, r = r, self._adaptive.scaled(r)  # (V1) of sensor.fusion_adaptive; off: r itself
            h = np.zeros((3, self._states))
            h[:, :3] = np.eye(3)
            # eq (3)'s translation coupled to the yaw error (the lever's along the optical axis with (3''))
            coupling = yaw_coupling(self.noise, r, self.geometry.camera_position, self._optical_axis)
            coupling = self._ratio.coupled(coupling)  # (L3) of sensor.fusion_coupling_ratio; off: the same array
            self._coupling, self.frame_scrub_demand = coupling, entry.scrub
            coupling = coupling * scrub_coupling_yield(self.noise, entry.scrub)  # (K5): gives way while scrubbing
            h[:2, BPSI] = x[0] * coupling  # the odometry's error per metre over the distance since the anchor
            h[2, BPSI] = x[0]
            if entry.scrub > 0.0:  # (K6): the odometry's systematic error released while the tyres scrub
                h[:, BPSI] *= scrub_bias_share(self.noise, entry.scrub)
            if self._sz is not None or self._sf is not None:  # (3'): the camera's displacement, along its axis
                along, across = camera_displacement(x[:3], self.geometry.camera_position, self._optical_axis)
                if self._sz is not None:
                    h[:2, self._sz] = along * self._optical_axis
                if self._sf is not None:
                    h[:2, self._sf] = across * abs(across) * self._optical_axis
            innovation = z - h @ x
            innovation[2] = math.remainder(innovation[2], 2.0 * math.pi)
            interval = sum(t.inputs[0] for t in list(self._history)[1 : index + 1])
            kinematic_y = kinematic_lateral_step(
                [(t.inputs, t.tractor_lateral) for t in list(self._history)[1 : index + 1]], x
            )
            # (K2): the camera's lateral motion against the tractor's kinematics; not against the unit's own slip
            # reference (T2), which measures the slip itself: the disagreement is then the camera's error, not slip
            if kinematic_y is not None and self._own_reference is None:
                camera_y = z[1] - h[1, BPSI] * x[BPSI]
                for i in (self._sz, self._sf):  # less the estimated error along the optical axis, (3')
                    if i is not None:
                        camera_y -= h[1, i] * x[i]
                self._evidence.weigh(camera_y - kinematic_y, float(r[1, 1]), interval)
            self._ratio.observe(z, x, r, kinematic_y, self.kinematic_std * interval)  # (L1)–(L2); off: nothing
            refuse, prior = self._gated < self.noise.max_gated, p
            x, p, nis, used = gated_update(x, p, h, innovation, r, self.noise.gate, refuse)
            self._consider.update(prior, h, r, nis, self.noise.gate, used)
            self._adaptive.observe(h, prior, innovation, r_floor)
            if not used:
                self._gated += 1
                self.rejected += 1
            else:
                self._gated = 0
                self.updates += 1
                self._nis.append(window_nis(self.noise, nis, innovation, h, prior, r))
                self.innovation_ratio = max(MIN_INNOVATION_RATIO, float(np.mean(self._nis)) / 3.0)
        if reference is not None and self.noise.coupling_reference and reference.start_tick == self._history[0].tick:
            x, p, share = self._couple(x, p, reference)
        self._commit(index, x, p, share)
        self._read()
        return used

    def _couple(self, x: np.ndarray, p: np.ndarray, coupling: CouplingMeasurement) -> tuple[np.ndarray, ...]:
        """The following unit's measurement (:meth:`~sensor.fusion_consider.NoConsider.coupled`: the filter's own
        gain, or the Schmidt–Kalman gain of :mod:`sensor.fusion_schmidt`), counted."""
        refuse = self._coupling_gated < self.noise.max_gated
        x, posterior, _nis, used = self._consider.coupled(x, p, coupling, self.noise.gate, refuse)
        self._coupling_gated = 0 if used else self._coupling_gated + 1
        self.coupling_updates += int(used)
        self.coupling_rejected += int(not used)
        return x, posterior, reference_share(p[:3, :3], posterior[:3, :3])

    def _commit(self, index: int, x: np.ndarray, p: np.ndarray, share: np.ndarray) -> None:
        """Push the increments up to history ``index`` (ending at ``x``, ``share`` its (4')) and make it the anchor."""
        poses = [h.x[:3] for h in list(self._history)[: index + 1]]
        poses[-1] = x[:3]
        for a, b in itertools.pairwise(poses):
            self.buffer.push(*relative_pose(a, b))
        end = x[:3].copy()
        # Move the committed increments into the new anchor frame, add this one, drop those behind the follow point.
        starts = np.vstack([self._starts, [[0.0, 0.0, 0.0]]])
        ends = np.vstack([self._ends, end[None, :2]])
        covs = np.concatenate([self._covs, p[None, :3, :3]])
        durations = np.append(self._durations, sum(t.inputs[0] for t in list(self._history)[1 : index + 1]))
        demands = np.append(self._demands, self._history[index].scrub)
        shares = np.concatenate([self._shares, share[None]])
        starts = into_frame(starts, end)
        ends = into_frame(np.column_stack([ends, np.zeros(len(ends))]), end)[:, :2]
        keep = starts[:, 0] > -self.follow_point_offset - 2.0
        if self._axial_regression is not None:  # the increment's regression on the axial states, before the reset
            self._axial_regression.commit(p, keep)
        self._consider.commit(keep)
        self._starts, self._ends, self._covs = starts[keep], ends[keep], covs[keep]
        self._durations, self._demands, self._shares = durations[keep], demands[keep], shares[keep]
        # The new anchor: Δ restarts from zero; the other states keep their covariance.
        anchor_x = x.copy()
        anchor_x[:3] = 0.0
        anchor_p = np.zeros_like(p)
        anchor_p[3:, 3:] = p[3:, 3:]
        rest = list(self._history)[index + 1 :]
        identity = self._consider.advance(None, anchor_p, (), 0.0)
        self._history = deque([_Tick(self._history[index].tick, (0.0,) * 4, anchor_x, anchor_p, transition=identity)])
        for h in rest:  # re-filter to the present with the stored inputs and measurements (delayed measurement)
            last = self._history[-1]
            nx, stepped = self._step(last.x, last.p, h.inputs, h.kinematic_variance, h.scrub)
            nx, np_ = apply_rows(nx, stepped, h.kinematic)
            step = self._consider.advance((last.transition, self._model.transition), stepped, h.kinematic, h.inputs[0])
            self._history.append(replace(h, x=nx, p=np_, transition=step))

    # ------------------------------------------------------------------ estimate

    def _read(self) -> None:
        """Off-tracking (eq (7) of the path buffer) and its std (eqs (4)–(5), :mod:`sensor.fusion_std`) now."""
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
        elapsed = sum(t.inputs[0] for t in list(self._history)[1:])
        shares = self._shares if self.noise.coupling_bias_share else None
        window = IncrementWindow(self._starts, self._ends, self._covs, self._durations, self._demands, shares)
        axis = (
            self._optical_axis
            if self.noise.vo_axial_scale_uncertainty > 0.0 or self._axial_state or self._flow_state
            else None
        )
        effects_ = path_effects(
            d,
            now.p[:3, :3],
            elapsed,
            window,
            lfp,
            self.slip_point,
            self._coupling,
            axis,
            self.geometry.camera_position,
            self.scrub_demand,
        )
        independent, coherent, axial, cross = effects_.independent, effects_.coherent, effects_.axial, effects_.cross
        self._lateral_lever = effects_.lever
        biases = now.p[np.ix_(self._biases, self._biases)]
        effects = np.array(  # (3'): s_z and s_f are coherent over the path too
            [*coherent[:2], *((axial,) if self._axial_state else ()), *((cross,) if self._flow_state else ())]
        )
        if self._axial_regression is not None:  # (A2): at the fused increments' sensitivity instead
            effects[2:] = self._axial_regression.effect(d, now.p, self._starts, self._ends, lfp)
        evidence, share = self._evidence.evidence, self.kinematic_share
        disagreement = kinematic_disagreement(self.noise, evidence, float(now.x[VS]), share, self._lateral_lever)
        demands = (effects_.coupled_demand, self.frame_scrub_demand)
        coupling = coupling_correction_std(self.noise, now.x[BPSI], coherent[2], *demands)
        if self.frame_scrub_demand > 0.0:  # (K5): the biases' effect with the coupling given way
            scrub = self.frame_scrub_demand
            coherent = coherent - scrub * np.array([0.0, coherent[2], coherent[2]])
        self.std_parts = {
            "increments": self.innovation_ratio * independent,
            "biases": self.innovation_ratio * self.noise.bias_std_scale**2 * float(effects @ biases @ effects)
            + self._consider.variance(now.transition, d, self._starts, self._ends, lfp),  # sensor.fusion_consider
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

    @property
    def state(self) -> np.ndarray:
        """Newest state ``[Δx, Δy, Δψ, v_s, b_g, b_w, β_ψ]``, then ``ε_k`` with (K3) and ``s_z``, ``s_f`` of (3') when
        on (:mod:`sensor.fusion_model`; before the first tick, the start)."""
        return (self._history[-1].x if self._history else self._start[0]).copy()

    @property
    def covariance(self) -> np.ndarray:
        """Newest state covariance, 7×7 and one more row per state that is on (before the first tick, the start)."""
        return (self._history[-1].p if self._history else self._start[1]).copy()
