"""The model-side estimators of the loop: the ground truth, Cheng's zero-slip estimate, fused VISO-OT.

All three feed the one kingpin-path buffer (:class:`vehicle_model.offtracking.OfftrackingBuffer`, de Saxe & Cebon
2018, eqs (3)–(7)) from different sources of kingpin motion: the exact increments of the simulation, zero-slip
kinematics of the tractor's signals, or a Kalman filter of the trailer's signals and the camera's motions. The
builders (:func:`ground_truth`, :func:`zero_slip` and per unit :func:`zero_slip_unit`, :func:`fused_viso_ot`) are
those of the registry's built-in entries (:mod:`.builtin_estimators`); the camera's own estimate is in
:mod:`.camera_estimator`.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from typing import Any

import numpy as np

from controller.zero_slip import ZeroSlipEstimator
from sensor.fusion import STD_PARTS, ChainSignals, FusedVisoOt, FusionNoise, TractorSignals
from sensor.signals import standstill_reading
from sensor.trailer_accelerometer import channel_name
from vehicle_model.geometry import kingpin_position
from vehicle_model.offtracking import (
    BUFFER_FILLING,
    OfftrackingBuffer,
    OfftrackingEstimate,
    increments_from_poses,
    offtracking_from_path,
)
from vehicle_model.parameters import VehicleParams

from .following_camera import FollowingCamera, following_camera, reference_counts
from .participant import Column, LoopContext, TickInput

__all__ = [
    "FUSION_STD_COLUMNS",
    "DensePath",
    "FusedVisoOtEstimator",
    "GroundTruth",
    "ZeroSlip",
    "fused_viso_ot",
    "fused_viso_ot_unit",
    "fusion_std_record",
    "ground_truth",
    "zero_slip",
    "zero_slip_unit",
]

TOO_UNCERTAIN = "too_uncertain"
"""Why the fused estimate has no value although it has a standard deviation: that exceeds its ``max_std``."""


class DensePath:
    """The recent kingpin path at dynamics-step resolution, trimmed to a little over one trailer length.

    Points live in one growing buffer (compacted when full), so :meth:`array` is a view, not a copy of
    every chunk each control tick. Chunks are trimmed from the front, whole, while more than two remain
    and the rest still spans ``keep_length``.
    """

    def __init__(self, keep_length: float, capacity: int = 4096) -> None:
        self.keep_length = keep_length
        self._buf = np.empty((capacity, 2))
        self._end = 0
        self._starts: deque[int] = deque()  # buffer index of each chunk's first point
        self.lengths: deque[float] = deque()  # each chunk's length, joined to the chunk before it

    def extend(self, points: np.ndarray) -> None:
        """Append a chunk of points ``(N, 2)``, oldest first, then trim."""
        points = np.asarray(points, dtype=float)
        if self._starts:
            joined = np.vstack([self._buf[self._end - 1 : self._end], points])
        else:
            joined = points
        length = float(np.hypot(*np.diff(joined, axis=0).T).sum()) if len(joined) > 1 else 0.0
        if self._end + len(points) > len(self._buf):
            self._compact(len(points))
        self._starts.append(self._end)
        self._buf[self._end : self._end + len(points)] = points
        self._end += len(points)
        self.lengths.append(length)
        total = sum(self.lengths)
        while len(self._starts) > 2 and total - self.lengths[0] > self.keep_length:
            total -= self.lengths.popleft()
            self._starts.popleft()

    def _compact(self, incoming: int) -> None:
        first = self._starts[0] if self._starts else self._end
        kept = self._end - first
        if kept + incoming > len(self._buf) // 2:  # grow so that compaction stays rare
            buf = np.empty((2 * (kept + incoming), 2))
        else:
            buf = self._buf
        buf[:kept] = self._buf[first : self._end]
        self._buf = buf
        self._starts = deque(i - first for i in self._starts)
        self._end = kept

    def array(self) -> np.ndarray:
        """The kept path ``(N, 2)``, oldest first (a read-only view, valid until the next :meth:`extend`)."""
        first = self._starts[0] if self._starts else self._end
        view = self._buf[first : self._end]
        view.flags.writeable = False
        return view


class GroundTruth:
    """The exact off-tracking: the buffer fed with the true kingpin increments between ticks.

    With ``geometric`` it also intersects the dense kingpin path (every dynamics step) with the follow point's
    station, directly (:func:`~vehicle_model.offtracking.offtracking_from_path`): a second truth that must agree
    with the first to well under a millimetre (``offtracking_truth_geometric``; NaN without it).

    Parameters
    ----------
    params
        The combination.
    geometric
        Compute the geometric second truth.
    """

    name = "truth"
    columns: tuple[Column, ...] = (
        Column.estimate("truth", "true off-tracking (the buffer fed with exact increments)"),
        Column(
            "offtracking_truth_geometric",
            "m",
            "the same by intersecting the dense kingpin path (a check)",
            role="diagnostic",
            vehicle_unit=2,
            estimator="truth",
        ),
    )

    def __init__(self, params: VehicleParams, geometric: bool = False) -> None:
        self.params = params
        self.follow_point_offset = params.follow_point_offset
        self.buffer = OfftrackingBuffer(self.follow_point_offset)
        self.dense = DensePath(keep_length=2.0 * self.follow_point_offset + 10.0) if geometric else None
        self._previous: tuple[np.ndarray, float] | None = None
        self.estimate = OfftrackingEstimate.of(None)
        self.geometric = math.nan

    def update(self, tick: TickInput) -> OfftrackingEstimate:
        """Push the kingpin's increment since the previous tick; the off-tracking."""
        kp, psi2 = tick.kingpin, tick.state.psi2
        if self.dense is not None:
            trajectory = tick.trajectory
            if trajectory is None:
                self.dense.extend(kp[None, :])
            else:
                self.dense.extend(kingpin_position(self.params, trajectory[:, 0], trajectory[:, 1], trajectory[:, 2]))
        if self._previous is not None:
            prev_kp, prev_psi2 = self._previous
            increment = increments_from_poses(np.vstack([prev_kp, kp]), np.array([prev_psi2, psi2]))[0]
            self.buffer.push(*increment)
        self._previous = (kp, psi2)
        if self.dense is not None:
            geometric = offtracking_from_path(self.dense.array(), kp, psi2, self.follow_point_offset)
            self.geometric = math.nan if geometric is None else float(geometric)
        self.estimate = OfftrackingEstimate.of(self.buffer.offtracking())
        return self.estimate

    def record(self) -> Mapping[str, float]:
        """Both truths."""
        return {"offtracking_truth": self.estimate.value, "offtracking_truth_geometric": self.geometric}


class ZeroSlip:
    """Cheng's zero-slip estimate (:class:`controller.zero_slip.ZeroSlipEstimator`) on the tick's signals.

    Parameters
    ----------
    params
        The combination.
    variant
        ``yaw_rate`` (the gyro) or ``steer_angle``.
    rear_point
        ``axle_mean`` or ``equivalent`` (:data:`controller.zero_slip.RearPoint`).
    unit
        The towed unit it estimates (1: the first; :class:`controller.zero_slip.ZeroSlipEstimator`).
    grade
        ``none`` or ``accelerometer`` (the wheel speed made horizontal;
        :class:`controller.zero_slip.ZeroSlipEstimator`).
    """

    name = "zero_slip"
    columns: tuple[Column, ...] = (Column.estimate("zero_slip", "zero-slip (Cheng) off-tracking"),)

    def __init__(
        self,
        params: VehicleParams,
        variant: str = "yaw_rate",
        rear_point: str = "axle_mean",
        unit: int = 1,
        grade: str = "none",
    ) -> None:
        self.estimator = ZeroSlipEstimator(params, variant, rear_point, unit, grade)  # type: ignore[arg-type]
        self.estimate = OfftrackingEstimate.of(None)

    def update(self, tick: TickInput) -> OfftrackingEstimate:
        """Dead-reckon the kingpin over the period that ended at ``tick`` (nothing on the first tick)."""
        value = None if tick.index == 0 else self.estimator.update(tick.measured, tick.period)
        self.estimate = OfftrackingEstimate.of(value)
        return self.estimate

    def record(self) -> Mapping[str, float]:
        """The estimate."""
        return {"offtracking_zero_slip": self.estimate.value}


#: The columns of the fused filter's standard deviation by term (eq (5) of :mod:`sensor.fusion`), in its order.
FUSION_STD_COLUMNS: tuple[str, ...] = tuple(f"fusion_std_{part}" for part in STD_PARTS)


def fusion_std_record(fused: FusedVisoOt) -> dict[str, float]:
    """The :data:`FUSION_STD_COLUMNS` of ``fused``'s last tick [m]
    (:meth:`~sensor.fusion.FusedVisoOt.std_contributions`)."""
    parts = fused.std_contributions()
    return {name: parts[part] for part, name in zip(STD_PARTS, FUSION_STD_COLUMNS, strict=True)}


def _fused_columns(unit: int) -> tuple[Column, ...]:
    """The columns of the fused estimate of towed unit ``unit`` (the first's as they always were; unit ``k`` of the
    combination behind it with ``k`` appended)."""
    k = "" if unit == 1 else str(unit + 1)
    diagnostic: dict[str, object] = {"role": "diagnostic", "estimator": "viso_ot_fused"}
    if unit > 1:
        diagnostic["vehicle_unit"] = unit + 1
    return (
        Column.estimate("viso_ot_fused", "fused VISO-OT off-tracking", vehicle_unit=unit + 1),
        Column.std("viso_ot_fused", vehicle_unit=unit + 1),
        Column(
            f"fusion_kinematic_std{k}",
            "m/s",
            "σ of the zero-slip kinematics in the filter: large where it saw slip",
            **diagnostic,  # type: ignore[arg-type]
        ),
        *(
            Column(f"{name}{k}", "m", f"the {part} term of the std, as the std it alone would give", **diagnostic)  # type: ignore[arg-type]
            for part, name in zip(STD_PARTS, FUSION_STD_COLUMNS, strict=True)
        ),
    )


class FusedVisoOtEstimator:
    """Fused VISO-OT (:class:`sensor.fusion.FusedVisoOt`): a towed unit's signals every tick, its camera's motions
    as the camera latency releases them.

    Parameters
    ----------
    params
        The combination.
    camera
        The VISO-OT participant of the same unit (:class:`~.camera_estimator.VisoOt`): its camera pose and its
        released frames.
    noise
        The filter's noise model and tuning.
    unit
        The towed unit it estimates (1: the first). A unit behind the first propagates on its own gyro, wheel speed
        and steer (the signals ``trailer_yaw_rate<k>``, … of :mod:`.plant`) and takes the tractor's zero-slip
        kinematics carried down the chain (:class:`sensor.fusion.ChainSignals`, with the gyros of the units ahead).
    reference
        A following unit's camera as a measurement of this unit's kingpin increments (:mod:`.following_camera`;
        ``None``: none).
    """

    name = "viso_ot_fused"
    columns: tuple[Column, ...] = _fused_columns(1)

    def __init__(
        self,
        params: VehicleParams,
        camera: object,
        noise: FusionNoise,
        unit: int = 1,
        reference: FollowingCamera | None = None,
    ) -> None:
        self.camera = camera
        self.reference = reference
        self.unit = unit
        self._suffix = "" if unit == 1 else str(unit + 1)
        if unit != 1:
            self.columns = _fused_columns(unit)
        own: dict[str, object] = {"unit": unit} if unit != 1 else {}  # the first towed unit is the filter's default
        level = getattr(getattr(camera, "feed", None), "level_reference", "planar")
        if level != "planar":  # on a terrain: the camera's motion made horizontal as its VISO-OT's
            own["level_reference"] = level
        self.filter = FusedVisoOt(params, camera.camera_in_trailer, noise, **own)  # type: ignore[attr-defined]
        self.estimate = OfftrackingEstimate.of(None)

    def _signals(self, measured: Mapping[str, np.ndarray]) -> tuple[float, float, np.ndarray, object]:
        """The unit's yaw rate, wheel speed and steer, and the zero-slip kinematics' signals, of this tick."""
        tractor_speed, tractor_rate = float(measured["wheel_speed"][0]), float(measured["tractor_yaw_rate"][0])
        lateral = float(measured["tractor_lateral_acceleration"][0])
        own = measured.get(channel_name(self.unit))  # the unit's accelerometer, when the run has one
        unit_lateral = math.nan if own is None else float(own[0])
        if self.unit == 1:
            articulation = float(measured["articulation"][0])
            signals: object = TractorSignals(tractor_speed, tractor_rate, articulation, lateral, unit_lateral)
            rate, speed = measured["trailer_yaw_rate"][0], measured["trailer_wheel_speed"][0]
            return float(rate), float(speed), measured["trailer_steer"], signals
        k = self._suffix
        articulations = (float(measured["articulation"][0]), *map(float, measured["rear_articulation"]))
        ahead = [float(measured["trailer_yaw_rate"][0])]
        ahead += [float(measured[f"trailer_yaw_rate{u + 1}"][0]) for u in range(2, self.unit)]
        signals = ChainSignals(tractor_speed, tractor_rate, articulations, lateral, tuple(ahead), unit_lateral)
        rate, speed = measured[f"trailer_yaw_rate{k}"][0], measured[f"trailer_wheel_speed{k}"][0]
        return float(rate), float(speed), measured[f"trailer_steer{k}"], signals

    def update(self, tick: TickInput) -> OfftrackingEstimate:
        """Propagate with the unit's signals, then correct with the frames the camera released on this tick."""
        fused = self.filter
        rate, speed, steer, signals = self._signals(tick.measured)
        fused.propagate(tick.index, tick.period, rate, speed, steer, signals)  # type: ignore[arg-type]
        reference = self.reference
        if reference is not None:
            reference.observe(tick.index, tick.measured)
        for shot in self.camera.released:  # type: ignore[attr-defined]
            frame = shot.frame
            motion, covariance = (frame.vo.camera_motion, frame.vo.covariance) if frame.valid else (None, None)
            coupling = reference.take(shot.tick) if reference is not None else None
            fused.measure(shot.tick, motion, covariance, getattr(shot, "tilt", None), coupling)
        if fused.estimate is not None:
            self.estimate = OfftrackingEstimate(float(fused.estimate), fused.std)
        else:
            reason = TOO_UNCERTAIN if math.isfinite(fused.std) else BUFFER_FILLING
            self.estimate = OfftrackingEstimate(math.nan, fused.std, reason)
        return self.estimate

    def report(self) -> dict[str, Any]:
        """What the run's ``metrics.json`` says of this filter beside its unit's figures: with a :attr:`reference`,
        ``coupling_reference``, its following frames measured and refused (:func:`.following_camera.
        reference_counts`); empty without one."""
        if self.reference is None:
            return {}
        return {"coupling_reference": reference_counts(self.reference)}

    def record(self) -> Mapping[str, float]:
        """The estimate, its standard deviation, the kinematics' σ and the terms of the standard deviation."""
        k = self._suffix
        return {
            f"offtracking_viso_ot_fused{k}": self.estimate.value,
            f"offtracking_viso_ot_fused{k}_std": self.estimate.std,
            f"fusion_kinematic_std{k}": self.filter.kinematic_std,
            **{f"{name}{k}": value for name, value in fusion_std_record(self.filter).items()},
        }


def ground_truth(context: LoopContext) -> GroundTruth:
    """The registry's builder of the ground truth."""
    return GroundTruth(context.setup.params, geometric=context.geometric_truth)


def zero_slip(context: LoopContext) -> ZeroSlip:
    """The registry's builder of the zero-slip estimator (``estimators.zero_slip_variant`` and ``_rear_point``)."""
    settings = context.setup.config.estimators
    return ZeroSlip(
        context.setup.params,
        settings.zero_slip_variant,
        settings.zero_slip_rear_point,
        grade=settings.zero_slip_grade,
    )


def zero_slip_unit(context: LoopContext, unit: int) -> ZeroSlip:
    """The registry's builder of the zero-slip estimate of towed unit ``unit`` behind the first (its ``update``)."""
    settings = context.setup.config.estimators
    return ZeroSlip(
        context.setup.params,
        settings.zero_slip_variant,
        settings.zero_slip_rear_point,
        unit,
        settings.zero_slip_grade,
    )


GYRO_ZEROING_STREAM = 0x2E60
"""Mixed with the run's seed into the generator of the trailer gyro's readings at standstill before the run, so that
zeroing it draws nothing from the run's own generator."""


def fused_viso_ot(context: LoopContext) -> FusedVisoOtEstimator:
    """The registry's builder of fused VISO-OT (``fusion`` settings; on the ``viso_ot`` participant's camera).

    The trailer's gyro is zeroed over ``fusion.gyro_zeroing_s`` of standstill before the run: its readings at rest
    are drawn from its own channel (``signals.trailer_yaw_rate``: bias and noise; :func:`sensor.signals.
    standstill_reading`).
    """
    return _fused(context, context.estimators["viso_ot"], 1)


def fused_viso_ot_unit(context: LoopContext, unit: int) -> FusedVisoOtEstimator | None:
    """The registry's builder of fused VISO-OT of towed unit ``unit`` ≥ 2, on that unit's VISO-OT camera (``None``:
    no camera on it). Its gyro is zeroed as the first's, from a stream of its own."""
    camera = context.unit_estimators.get(f"viso_ot{unit + 1}")
    return None if camera is None else _fused(context, camera, unit)


def _fused(context: LoopContext, camera: object, unit: int) -> FusedVisoOtEstimator:
    config = context.setup.config
    fusion = config.fusion  # a FusionNoise with a run's defaults
    estimator = FusedVisoOtEstimator(context.setup.params, camera, fusion, unit)
    fused = estimator.filter
    if fused.noise.coupling_reference:  # a side rig's: the following unit's camera, where one looks along its unit
        level = fused.geometry.level_reference
        estimator.reference = following_camera(context.setup.params, unit, context.unit_estimators, fused.noise, level)
    if fusion.gyro_zeroing_s > 0.0:
        stream = [config.seed, GYRO_ZEROING_STREAM] + ([] if unit == 1 else [unit])
        rng = np.random.default_rng(stream)
        mean, samples = standstill_reading(config.signals.trailer_yaw_rate, fusion.gyro_zeroing_s, rng)
        if samples > 0:
            estimator.filter.zero_gyro(mean, samples)
    return estimator
