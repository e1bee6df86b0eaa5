"""``offtrack estimate RECORDING --rig RIG.yaml``: VISO-OT on a recorded sequence, written as a run directory.

:func:`estimate_recording` runs, frame by frame in the recording's own times, what the closed loop runs on rendered
frames — :class:`sensor.frame_odometry.FrameOdometry` (the stereo odometry, VISO-OT of de Saxe & Cebon 2018 §2.2
with its plausibility check over the frame's actual interval) — and beside it every estimator of
:mod:`scenarios.registry` that declares an offline adapter (:mod:`scenarios.loop.offline`): with signals, the
fused filter (:class:`sensor.fusion.FusedVisoOt`, a run's ``fusion`` defaults) and Cheng's zero-slip estimate
(:class:`controller.zero_slip.ZeroSlipEstimator`), and any plug-in's. The rows are the frames' times and, with
signals, the signals' times between them (the fused filter propagates on every row and takes each frame's motion on
the frame's own row; no latency). Raw images are rectified first with the calibration. A frame without images
(dropped) is skipped: the odometry measures the next one against the last it saw, over the actual interval, with
its constant-velocity motion prior stretched over the gap (:data:`SAME_PERIOD`).

The run directory (:mod:`.report`) holds what a simulated run's does — ``timeseries.parquet`` with the same
columns where they mean the same (``offtracking_*``, the per-frame ``vo_*`` quality and reasons,
``camera_frame``), ``metrics.json`` (:func:`scenarios.run.metrics.compute_metrics`, so the errors against the
reference are reported exactly as a run's), ``offtracking.png``, ``plan_view.png`` — plus ``recording.yaml`` (what
was given; it stands for a run's ``config.yaml``) and, in ``metrics.json``, ``recording``: the frames missing,
refused and why, and the gaps in the times; for a side rig's fused filter, ``coupling_reference``: the following unit
whose camera it took and the measurements it used (:func:`.following.coupling_summary`).

Columns of a recorded run besides a run's: ``frame`` (the frame's number in the recording), ``frame_missing``,
``kingpin_x_viso_ot``/``kingpin_y_viso_ot``/``trailer_heading_viso_ot`` (the kingpin's path dead-reckoned from the
accepted motions), ``vo_rpe_translation_m``/``vo_rpe_rotation_rad`` (the frame's relative pose error against
reference poses, :func:`sensor.recordings.vo_metrics.relative_pose_error`), the signals at the row. ``kingpin_x`` and
``kingpin_y`` are the reference's path when there are reference poses, else the dead-reckoned one. The built-in
estimates keep their place in the columns (the fused filter's, zero-slip's, then the signals); a plug-in's columns
follow, in registry order.
"""

from __future__ import annotations

import functools
import math
import time as wallclock
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sensor.frame_odometry import FrameOdometry
from sensor.recordings.sequence import GAP_FACTOR, MISSING_REASONS, time_gaps
from sensor.recordings.vo_metrics import relative_pose_error

from ..config import FusionConfig
from ..loop.camera_estimator import CAMERA_COLUMNS, VisoOt, camera_row
from ..loop.ends import RunStatus
from ..loop.estimators import GroundTruth
from ..loop.offline import SIGNAL_KEYS, OfflineContext, OfflineEstimator, OfflineFusedVisoOt
from ..loop.participant import Column
from ..loop.plant import VehicleParticipant
from ..registry import estimator_entries
from ..run.results import TIMESERIES_FILE, TimeSeriesWriter, write_metrics
from .following import FollowerTrace, coupling_summary, following_reference
from .inputs import EstimateInputs
from .reference import reference_columns
from .report import write_recorded_report, write_recording_file
from .unit_fusion import UnitFusedVisoOt

__all__ = ["estimate_recording", "offline_estimators", "row_times"]

SAME_PERIOD = GAP_FACTOR
"""Intervals within this factor of the one before are taken as the same frame period — timestamps jitter by
milliseconds while a camera's period holds — and leave the odometry's constant-velocity prior as it is; a longer one
(frames dropped) or a shorter one stretches the prior to it (:meth:`sensor.vo.StereoOdometry.scale_prior`)."""

SAME_INSTANT = 1e-6
"""Times closer than this [s] are one instant (a signal sample at a frame's time)."""

Progress = Callable[[int, int], None]
"""``(frames done, frames in all)``."""

_SIGNAL = {"role": "signal", "vehicle_unit": 1}
_TRAILER_SIGNAL = {"role": "signal", "vehicle_unit": 2}
_SIGNAL_COLUMNS: tuple[Column, ...] = (
    Column("wheel_speed", "m/s", "the tractor's wheel speed, the recorded signal at the row's time", **_SIGNAL),
    Column("tractor_yaw_rate", "rad/s", "the tractor's yaw rate, the recorded signal at the row's time", **_SIGNAL),
    Column("articulation", "rad", "the articulation angle, the recorded signal at the row's time", **_TRAILER_SIGNAL),
    Column(
        "trailer_yaw_rate", "rad/s", "the trailer's yaw rate, the recorded signal at the row's time", **_TRAILER_SIGNAL
    ),
    Column(
        "trailer_wheel_speed",
        "m/s",
        "the trailer's wheel speed, the recorded signal at the row's time",
        **_TRAILER_SIGNAL,
    ),
    Column(
        "tractor_lateral_acceleration",
        "m/s²",
        "the tractor's lateral accelerometer, the recorded signal at the row's time (NaN: not recorded)",
        **_SIGNAL,
    ),
)
_SIGNALS = tuple(column.name for column in _SIGNAL_COLUMNS)
_LONGITUDINAL_COLUMN = Column(
    "tractor_longitudinal_acceleration",
    "m/s²",
    "the tractor's longitudinal accelerometer, the recorded signal at the row's time (only where recorded)",
    **_SIGNAL,
)
_VISO_OT = {"role": "diagnostic", "vehicle_unit": 2, "estimator": "viso_ot"}
_REFERENCE = {"role": "state", "vehicle_unit": 2}
_RECORDING_COLUMNS: tuple[Column, ...] = (
    Column("frame", "-", "the frame's index in the recording", role="diagnostic"),
    Column(
        "frame_missing",
        "-",
        "1 on a row whose frame was missing or refused (the reason is in metrics.json)",
        role="flag",
    ),
    Column(
        "kingpin_x_viso_ot",
        "m",
        "the kingpin dead-reckoned from the accepted motions, first frame's trailer X",
        **_VISO_OT,
    ),
    Column("kingpin_y_viso_ot", "m", "the same, Y", **_VISO_OT),
    Column("trailer_heading_viso_ot", "rad", "the trailer's heading from the accepted motions", **_VISO_OT),
    Column("kingpin_x", "m", "the reference's kingpin, first frame's trailer X", **_REFERENCE),
    Column("kingpin_y", "m", "the reference's kingpin, Y", **_REFERENCE),
    Column("trailer_heading", "rad", "the reference's trailer heading", **_REFERENCE),
    Column(
        "vo_rpe_translation_m",
        "m",
        "the frame's relative pose error in translation against the reference",
        role="diagnostic",
        estimator="viso_ot",
    ),
    Column(
        "vo_rpe_rotation_rad",
        "rad",
        "the frame's relative pose error in rotation against the reference",
        role="diagnostic",
        estimator="viso_ot",
    ),
)


def row_times(inputs: EstimateInputs) -> tuple[np.ndarray, np.ndarray]:
    """The run's rows: their times [s since the first frame] and the frame slot of each (−1: a signals' row).

    The frames' times, and with signals the signals' times between the first and the last frame; a signal sample
    within :data:`SAME_INSTANT` of a frame is that frame's row (the two files' clocks written to different digits).
    """
    frames = inputs.recording.times
    times = frames
    if inputs.signals is not None:
        extra = inputs.signals.time - inputs.recording.t0
        extra = extra[(extra > frames[0]) & (extra < frames[-1])]
        nearest = np.clip(np.searchsorted(frames, extra), 1, len(frames) - 1)
        gap = np.minimum(np.abs(extra - frames[nearest - 1]), np.abs(frames[nearest] - extra))
        times = np.union1d(frames, extra[gap > SAME_INSTANT])
    slot = np.full(times.size, -1)
    slot[np.searchsorted(times, frames)] = np.arange(frames.size)
    return times, slot


BUILT_IN_LAYOUT = ("viso_ot_fused", "zero_slip")
"""The offline estimators whose columns come before the signals', in this order (a recorded run's layout)."""


def _columns(inputs: EstimateInputs, offline: list[OfflineEstimator]) -> list[Column]:
    """The run's columns with their units: those a simulated run declares under the same name (the camera's, the
    truth's, the plant's time), the offline estimators' (the built-ins', the signals', then the others'), and the
    recording's own."""
    declared = {
        column.name: column
        for column in (
            *VehicleParticipant.columns,
            *CAMERA_COLUMNS,
            *VisoOt.columns,
            *GroundTruth.columns,
            *_RECORDING_COLUMNS,
            *_SIGNAL_COLUMNS,
        )
    }
    names = ["time", "frame", "camera_frame", "frame_missing", "offtracking_viso_ot", *(c.name for c in CAMERA_COLUMNS)]
    names += ["kingpin_x_viso_ot", "kingpin_y_viso_ot", "trailer_heading_viso_ot", "kingpin_x", "kingpin_y"]
    names += ["offtracking_truth", "offtracking_truth_geometric"]
    if inputs.reference_poses is not None:
        names += ["trailer_heading", "vo_rpe_translation_m", "vo_rpe_rotation_rad"]
    first = sorted((e for e in offline if e.name in BUILT_IN_LAYOUT), key=lambda e: BUILT_IN_LAYOUT.index(e.name))
    others = [e for e in offline if e.name not in BUILT_IN_LAYOUT]
    own = [c for estimator in first for c in estimator.columns]
    if inputs.signals is not None:
        own += _SIGNAL_COLUMNS
        if inputs.signals.longitudinal_acceleration is not None:
            own.append(_LONGITUDINAL_COLUMN)
    own += [c for estimator in others for c in estimator.columns]
    return [declared[name] for name in names] + own


def offline_estimators(context: OfflineContext) -> list[OfflineEstimator]:
    """The registered estimators' offline adapters that run on these inputs, in registry order."""
    adapters = (entry.offline(context) for entry in estimator_entries() if entry.offline is not None)
    return [adapter for adapter in adapters if adapter is not None]


class _DeadReckoning:
    """The kingpin's path from the accepted motions' increments (eqs (1)–(2)), in the first frame's trailer frame."""

    def __init__(self) -> None:
        self.pose = np.zeros(3)

    def push(self, dx: float, dy: float, dpsi: float) -> None:
        c, s = math.cos(self.pose[2]), math.sin(self.pose[2])
        self.pose = self.pose + np.array([c * dx - s * dy, s * dx + c * dy, dpsi])

    def record(self) -> dict[str, float]:
        x, y, psi = (float(v) for v in self.pose)
        return {"kingpin_x_viso_ot": x, "kingpin_y_viso_ot": y, "trailer_heading_viso_ot": psi}


def estimate_recording(
    inputs: EstimateInputs,
    run_dir: Path,
    *,
    plots: bool = True,
    progress: Progress | None = None,
    fusion: FusionConfig | None = None,
    followers: dict[int, FollowerTrace] | None = None,
    trace: FollowerTrace | None = None,
) -> dict[str, Any]:
    """Run the estimators over the recording and write the run directory (module notes); return ``metrics.json``.

    Parameters
    ----------
    inputs : EstimateInputs
        The checked inputs (:func:`.inputs.resolve_inputs`).
    run_dir : Path
        The run directory (exists, empty).
    plots : bool
        Draw ``offtracking.png`` and ``plan_view.png``.
    progress : callable, optional
        ``progress(frames done, frames in all)`` after every frame.
    fusion : FusionConfig, optional
        The fused filter's settings (a run's ``fusion``; default a run's defaults).
    followers : dict, optional
        The units behind already estimated, by towed unit (:class:`.following.FollowerTrace`): the nearest whose
        camera looks along its unit is the reference of a side rig's filter (:mod:`.following`).
    trace : FollowerTrace, optional
        Filled with this unit's processed frames, for a unit ahead of it.
    """
    t_start = wallclock.perf_counter()
    params = inputs.rig.params
    write_recording_file(run_dir, inputs.record)
    write_metrics(
        run_dir,
        {"scenario": f"recording {inputs.recording.source}", "status": RunStatus.RUNNING, "message": "running"},
    )
    times, slots = row_times(inputs)
    frame_times = inputs.recording.times
    first_interval = float(frame_times[1] - frame_times[0]) if frame_times.size > 1 else 0.1
    odometry = FrameOdometry(
        params, inputs.vo_config, inputs.camera_in_trailer, first_interval, inputs.seed, unit=inputs.rig.unit
    )
    truth = reference_columns(
        times,
        inputs.rig.follow_point_offset,
        inputs.camera_in_trailer,
        inputs.reference_poses,
        inputs.reference_offtracking,
    )
    camera_pose = truth.pop("camera_pose", None)
    signals = None if inputs.signals is None else inputs.signals.at(times + inputs.recording.t0, params)
    following = None
    if followers:
        following = functools.partial(following_reference, inputs, followers, times, slots, signals)
    context = OfflineContext(inputs, times, signals, fusion, following)
    if inputs.rig.unit == 1:
        offline = offline_estimators(context)
    else:  # a unit behind the first: its own fused filter on the chain's signals (the registry's are the first's)
        offline = [] if signals is None else [UnitFusedVisoOt(context)]
    fused = next((e.fused for e in offline if isinstance(e, OfflineFusedVisoOt)), None)
    path = _DeadReckoning()
    writer = TimeSeriesWriter(run_dir / TIMESERIES_FILE, _columns(inputs, offline))
    refused: list[list[Any]] = []
    missing: list[list[Any]] = []
    estimate = math.nan
    last: tuple[float, np.ndarray | None] | None = None  # time and reference pose of the last frame processed
    previous_interval: float | None = None
    pairs = inputs.recording.pairs()
    status, message = RunStatus.COMPLETED, "the recording was processed to its end"
    t = 0.0
    try:
        for row, (t, slot_index) in enumerate(zip(times, slots, strict=True)):
            record: dict[str, float] = {"time": float(t)}
            frame = None
            if slot_index >= 0:
                slot, left, right = next(pairs)
                record.update(frame=float(slot.index), camera_frame=1.0, frame_missing=float(left is None))
                if left is None or right is None:
                    missing.append([slot.index, slot.time, slot.missing or "image_missing"])
                else:
                    if inputs.calibration is not None:
                        left, right = inputs.calibration.rectify(left, right)
                    if last is not None and t > last[0]:
                        interval = float(t - last[0])
                        odometry.estimator.frame_interval = interval  # VISO-OT's plausibility over the actual interval
                        ratio = interval / previous_interval if previous_interval is not None else 1.0
                        if not 1.0 / SAME_PERIOD <= ratio <= SAME_PERIOD:
                            odometry.vo.scale_prior(ratio)  # the prior stretched over a gap
                        previous_interval = interval
                    frame = odometry.process(left, right)
                    record.update(camera_row(frame))
                    estimate = math.nan if frame.estimate is None else float(frame.estimate)
                    if frame.valid:
                        path.push(*odometry.estimator.kingpin_increment(frame.vo.camera_motion))
                    elif last is not None:
                        refused.append([slot.index, slot.time, frame.reason])
                    pose = camera_pose[row] if camera_pose is not None else None
                    if pose is not None and last is not None and last[1] is not None and np.all(np.isfinite(pose)):
                        true_motion = np.linalg.solve(pose, last[1])  # inv(T_k)·T_{k−1}
                        rpe = relative_pose_error(frame.vo.motion if frame.vo.valid else None, true_motion)
                        record.update(vo_rpe_translation_m=rpe[0], vo_rpe_rotation_rad=rpe[1])
                    last = (float(t), pose)
            if progress is not None and slot_index >= 0:
                progress(int(slot_index) + 1, len(frame_times))
            reference = {name: float(values[row]) for name, values in truth.items()}
            if signals is not None:
                record.update({c: float(signals[k][row]) for k, c in zip(SIGNAL_KEYS, _SIGNALS, strict=True)})
                if "longitudinal_acceleration" in signals:
                    record[_LONGITUDINAL_COLUMN.name] = float(signals["longitudinal_acceleration"][row])
            for estimator in offline:
                estimator.update(row, frame, reference)
                record.update(estimator.record())
            if trace is not None and frame is not None:  # after the unit's filter has taken the row
                trace.add(float(t) + inputs.recording.t0, frame, fused)
            record["offtracking_viso_ot"] = estimate  # held between frames, as a run's
            record.update(path.record())
            record.update(reference)
            if "kingpin_x" not in truth:
                record.update(kingpin_x=float(path.pose[0]), kingpin_y=float(path.pose[1]))
            writer.append(record)
    except BaseException as exc:
        status = RunStatus.INTERRUPTED if isinstance(exc, KeyboardInterrupt) else RunStatus.FAILED
        message = f"stopped at {float(t):.3f} s: {type(exc).__name__}: {exc}"
        raise
    finally:
        writer.close()
        run = {
            "status": status,
            "message": message,
            "wall_time_s": wallclock.perf_counter() - t_start,
            "recording": _recording_summary(inputs, missing, refused),
        }
        coupling = next((c for e in offline if (c := coupling_summary(e)) is not None), None)
        if coupling is not None:
            run["coupling_reference"] = coupling
        metrics = write_recorded_report(run_dir, inputs.record, run, plots=plots and status == RunStatus.COMPLETED)
    return metrics


def _recording_summary(inputs: EstimateInputs, missing: list[list[Any]], refused: list[list[Any]]) -> dict[str, Any]:
    """``metrics.json``'s ``recording``: the frames, those missing and refused (frame, time, reason), the gaps."""
    times = inputs.recording.times
    intervals = np.diff(times)
    return {
        "source": inputs.recording.source,
        "frames": len(times),
        "processed": len(times) - len(missing),
        "time_span_s": float(times[-1]) if times.size else 0.0,
        "median_interval_s": float(np.median(intervals)) if intervals.size else None,
        "interval_range_s": [float(intervals.min()), float(intervals.max())] if intervals.size else None,
        "missing": {"count": len(missing), "frames": missing, "reasons": MISSING_REASONS},
        "refused": {"count": len(refused), "frames": refused},
        "gaps": [{"frame": k, "interval_s": dt, "median_interval_s": m} for k, dt, m in time_gaps(times)],
    }
