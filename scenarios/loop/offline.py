"""Estimators over recorded rows: what an estimator of :mod:`scenarios.registry` declares as its ``offline`` adapter.

``offtrack estimate`` (:mod:`scenarios.recorded.estimate`) runs the recording's own stereo odometry (VISO-OT) on its
frames and, beside it, every registered estimator that declares an offline adapter: ``offline(context)`` is given
an :class:`OfflineContext` — the recording's inputs, the rows' times and, where the recording has signals, the
signals at the rows — and returns an :class:`OfflineEstimator`, or ``None`` when it cannot run on these inputs
(the built-in ones need signals). On every row, in time order, each gets :meth:`OfflineEstimator.update` with the
row, the frame processed on it (or ``None``) and the reference's columns at the row, and then its
:meth:`~OfflineEstimator.record` joins the row.

The built-in adapters: Cheng's zero-slip estimate (:class:`OfflineZeroSlip`) and fused VISO-OT
(:class:`OfflineFusedVisoOt`: the filter propagates on every row and takes each frame's motion on the frame's own
row; no latency), both on the signals at the rows and silent outside the signals' span. The fused filter takes a
run's ``fusion`` settings (the context's, by default a run's defaults with the inputs' rear point), a side rig's
``fusion.side_rig`` among them, and, where those have ``coupling_reference`` on and the context gives a following
unit's camera, that camera's motion carried forward through the couplings with each of its own frames, as a run's
filter does (:mod:`scenarios.recorded.following`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from controller.zero_slip import ZeroSlipEstimator

from ..config import FusionConfig
from .estimators import FusedVisoOtEstimator, ZeroSlip, fusion_std_record
from .participant import Column

__all__ = [
    "SIGNAL_KEYS",
    "OfflineContext",
    "OfflineEstimator",
    "OfflineFusedVisoOt",
    "OfflineZeroSlip",
    "fused_viso_ot_offline",
    "zero_slip_offline",
]

SIGNAL_KEYS = ("speed", "yaw_rate", "articulation", "trailer_yaw_rate", "trailer_speed", "lateral_acceleration")
"""The signals at the rows, by key (:meth:`sensor.recordings.signals.SignalSeries.at`); where recorded,
``longitudinal_acceleration`` besides."""


@dataclass(frozen=True)
class OfflineContext:
    """What an offline adapter is built from.

    Attributes
    ----------
    inputs : EstimateInputs
        The checked inputs of ``offtrack estimate`` (:class:`scenarios.recorded.inputs.EstimateInputs`: the rig's
        parameters, the camera's mounting, the tractor's rear point, …).
    times : numpy.ndarray
        The rows' times [s since the first frame].
    signals : dict or None
        The signals at the rows (:data:`SIGNAL_KEYS`; NaN outside the signals' span), or ``None`` without signals.
    fusion : FusionConfig or None
        The fused filter's settings (``None``: a run's defaults); the inputs' rear point replaces their
        ``kinematic_rear_point``.
    following : callable or None
        Given the fused filter's settings (a side rig's in place where it is one), the following unit's camera as
        its reference (an object with ``observe(row)`` and ``take(row)``, :class:`scenarios.recorded.following.
        RecordedFollowingCamera`), or ``None``; ``None``: no unit behind is estimated.
    """

    inputs: Any
    times: np.ndarray
    signals: dict[str, np.ndarray] | None
    fusion: FusionConfig | None = None
    following: Callable[[Any], Any] | None = None

    def fusion_settings(self) -> FusionConfig:
        """The fused filter's settings: :attr:`fusion` (a run's defaults) with the inputs' rear point."""
        fusion = self.fusion if self.fusion is not None else FusionConfig()
        return fusion.replace(kinematic_rear_point=self.inputs.rear_point)


@runtime_checkable
class OfflineEstimator(Protocol):
    """An estimator over recorded rows (module notes)."""

    name: str
    columns: tuple[Column, ...]

    def update(self, row: int, frame: Any, reference: Mapping[str, float]) -> None:
        """Take row ``row``: the frame processed on it (:class:`sensor.frame_odometry.CameraFrame`, or ``None``)
        and the reference's columns at it (``offtracking_truth``, … where the recording has them)."""
        ...

    def record(self) -> Mapping[str, float]:
        """The values of :attr:`columns` for the row last updated (missing keys are written as NaN)."""
        ...


class _OnSignals:
    """The step between the rows with signals, and whether the row is within the signals' span."""

    def __init__(self, context: OfflineContext) -> None:
        assert context.signals is not None
        self.signals, self.times = context.signals, context.times
        self.previous: int | None = None
        self.active = False

    def step(self, row: int) -> float | None:
        """The time since the previous row with signals [s] (0 on the first), or ``None`` outside their span."""
        self.active = bool(np.isfinite(self.signals["speed"][row]))
        if not self.active:
            return None
        dt = float(self.times[row] - self.times[self.previous]) if self.previous is not None else 0.0
        self.previous = row
        return dt

    def value(self, row: int, key: str) -> float:
        return float(self.signals[key][row])


class OfflineZeroSlip(_OnSignals):
    """Cheng's zero-slip estimate on the signals at the rows, with the tractor's rear point and the grade source the
    inputs ask for (``accelerometer``: the estimator's own grade filter on the recorded longitudinal accelerometer,
    as a run's ``estimators.zero_slip_grade``)."""

    name = "zero_slip"
    columns = ZeroSlip.columns

    def __init__(self, context: OfflineContext) -> None:
        super().__init__(context)
        inputs = context.inputs
        self.estimator = ZeroSlipEstimator(
            inputs.rig.params, rear_point=inputs.rear_point, grade=inputs.zero_slip_grade
        )
        self.value_m: float | None = None

    def update(self, row: int, frame: Any, reference: Mapping[str, float]) -> None:
        """Dead-reckon over the step to ``row``."""
        dt = self.step(row)
        if dt is None:
            return
        sample = {
            "wheel_speed": np.array([self.value(row, "speed")]),
            "tractor_yaw_rate": np.array([self.value(row, "yaw_rate")]),
            "articulation": np.array([self.value(row, "articulation")]),
            "tractor_lateral_acceleration": np.array([self.value(row, "lateral_acceleration")]),
            "front_steer": np.array([0.0]),
        }
        if "longitudinal_acceleration" in self.signals:
            sample["tractor_longitudinal_acceleration"] = np.array([self.value(row, "longitudinal_acceleration")])
        self.value_m = self.estimator.update(sample, dt)

    def record(self) -> Mapping[str, float]:
        """The estimate, within the signals' span."""
        if not self.active:
            return {}
        return {"offtracking_zero_slip": math.nan if self.value_m is None else float(self.value_m)}


class OfflineFusedVisoOt(_OnSignals):
    """Fused VISO-OT (:class:`sensor.fusion.FusedVisoOt`, :meth:`OfflineContext.fusion_settings`): the trailer's
    and tractor's signals on every row, each frame's motion on its own row with, for a filter whose settings have
    ``coupling_reference`` on, the following unit's measurement of the same frame (:attr:`reference`).

    Attributes
    ----------
    reference
        The following unit's camera (:attr:`OfflineContext.following`; ``None``: none).
    """

    name = "viso_ot_fused"
    columns = FusedVisoOtEstimator.columns

    def __init__(self, context: OfflineContext) -> None:
        super().__init__(context)
        self.fused = self.build_filter(context)
        self.reference = self.following_camera(context)

    def build_filter(self, context: OfflineContext) -> Any:
        """The filter (:class:`sensor.fusion.FusedVisoOt` of the first towed unit)."""
        from sensor.fusion import FusedVisoOt

        inputs = context.inputs
        return FusedVisoOt(inputs.rig.params, inputs.camera_in_trailer, context.fusion_settings())

    def following_camera(self, context: OfflineContext) -> Any:
        """The following unit's camera, where the filter's settings take it and the context gives one."""
        if context.following is None or not self.fused.noise.coupling_reference:
            return None
        return context.following(self.fused.noise)

    def update(self, row: int, frame: Any, reference: Mapping[str, float]) -> None:
        """Propagate to ``row``; then the frame's motion (or none, if refused) on the same row."""
        dt = self.step(row)
        if dt is None:
            return
        self.fused.propagate(
            row, dt, self.value(row, "trailer_yaw_rate"), self.value(row, "trailer_speed"), None, self.kinematics(row)
        )
        if self.reference is not None:
            self.reference.observe(row)
        if frame is not None:
            usable = frame.valid
            coupling = self.reference.take(row) if self.reference is not None else None
            motion, covariance = (frame.vo.camera_motion, frame.vo.covariance) if usable else (None, None)
            self.fused.measure(row, motion, covariance, None, coupling)

    def kinematics(self, row: int) -> Any:
        """The zero-slip measurement's signals at ``row``: the tractor's (:class:`sensor.fusion.TractorSignals`)."""
        from sensor.fusion import TractorSignals

        return TractorSignals(
            self.value(row, "speed"),
            self.value(row, "yaw_rate"),
            self.value(row, "articulation"),
            self.value(row, "lateral_acceleration"),
        )

    def record(self) -> Mapping[str, float]:
        """The estimate, its standard deviation and its terms, within the signals' span."""
        if not self.active:
            return {}
        fused = self.fused
        return {
            "offtracking_viso_ot_fused": math.nan if fused.estimate is None else float(fused.estimate),
            "offtracking_viso_ot_fused_std": float(fused.std),
            "fusion_kinematic_std": float(fused.kinematic_std),
            **fusion_std_record(fused),
        }


def zero_slip_offline(context: OfflineContext) -> OfflineZeroSlip | None:
    """The registry's offline adapter of zero-slip (``None`` without signals)."""
    return None if context.signals is None else OfflineZeroSlip(context)


def fused_viso_ot_offline(context: OfflineContext) -> OfflineFusedVisoOt | None:
    """The registry's offline adapter of fused VISO-OT (``None`` without signals)."""
    return None if context.signals is None else OfflineFusedVisoOt(context)
