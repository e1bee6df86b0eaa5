"""What ``offtrack estimate`` is given, resolved and checked before any work: recording, camera model, rig, extras.

:func:`resolve_inputs` turns the command line into :class:`EstimateInputs`:

* the **recording** (:mod:`sensor.recordings`): a KITTI-odometry folder (``image_0/``, ``image_1/``, ``times.txt``),
  a ROS 1/2 bag (``--left-topic``, ``--right-topic``), or a left video with ``--right-video`` and ``--times``;
* the **camera model**: raw (distorted) images with ``--calibration FILE.yaml`` (``offtrack calibrate``'s OpenCV
  YAML, rectified on the fly with ``cv2.initUndistortRectifyMap``: the odometry's motion is then in the rectified
  left camera's frame), or already-rectified images with a KITTI ``calib.txt`` (the folder's, or ``--calib``);
* the **rig** (:mod:`.rig`): the camera's mounting and the combination;
* optional **signals** (:mod:`sensor.recordings.signals`) for the fused and the zero-slip estimates;
* an optional **reference**: camera poses (KITTI, or TUM with times on the recording's clock; a KITTI folder's
  own ``poses.txt`` unless ``--no-reference``) or an off-tracking series (:mod:`sensor.recordings.poses`).

Every check here is one :class:`~vehicle_model.errors.InputError` naming the file or option (exit 2), made before
the first image is decoded.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, get_args

import numpy as np

from controller.zero_slip import GradeSource
from sensor.calibration import CalibrationResult
from sensor.recordings.bag import BagPair, is_bag
from sensor.recordings.kitti import KittiFolder, RectifiedCamera, read_kitti_calib
from sensor.recordings.poses import read_kitti_poses, read_offtracking_series, read_tum_poses
from sensor.recordings.sequence import StereoRecording
from sensor.recordings.signals import SignalSeries, read_signals
from sensor.recordings.video import VideoPair
from sensor.vo import VOConfig
from vehicle_model.errors import InputError
from vehicle_model.kinematics import RearPoint

from ..extras import require
from .plausibility import check_baseline, check_road_disparity
from .rig import RecordingRig, load_rig

__all__ = [
    "EstimateInputs",
    "camera_model",
    "check_signals_clock",
    "check_unit_signals",
    "open_recording",
    "resolve_inputs",
]


@dataclass
class EstimateInputs:
    """Everything an estimate runs on, checked (module notes).

    Attributes
    ----------
    recording : StereoRecording
        The frames.
    rig : RecordingRig
        The combination and the camera's mounting.
    vo_config : VOConfig
        The odometry's camera model of the images it gets and its settings.
    camera_in_trailer : numpy.ndarray
        ``T_trailer←camera`` (4×4) of the frame the odometry's motion is in.
    calibration : CalibrationResult or None
        Raw images are rectified with it (None: the images are rectified already).
    signals : SignalSeries or None
        The combination's signals.
    reference_poses : (numpy.ndarray, numpy.ndarray) or None
        Times [s since the first frame] and poses ``T_ref←camera`` of the camera.
    reference_offtracking : (numpy.ndarray, numpy.ndarray) or None
        Times [s since the first frame] and reference off-tracking [m].
    seed : int
        Seed of the odometry's RANSAC.
    rear_point : str
        Where the zero-slip and fused estimators put the tractor's point without lateral velocity
        (:data:`~vehicle_model.kinematics.RearPoint`).
    record : dict
        What was given, for ``recording.yaml``.
    zero_slip_grade : str
        The zero-slip estimate's grade (:data:`controller.zero_slip.GradeSource`): ``none``, or ``accelerometer``
        from the signals' longitudinal accelerometer.
    """

    recording: StereoRecording
    rig: RecordingRig
    vo_config: VOConfig
    camera_in_trailer: np.ndarray
    calibration: CalibrationResult | None
    signals: SignalSeries | None
    reference_poses: tuple[np.ndarray, np.ndarray] | None
    reference_offtracking: tuple[np.ndarray, np.ndarray] | None
    seed: int
    rear_point: RearPoint
    record: dict[str, Any]
    zero_slip_grade: GradeSource = "none"


def open_recording(
    path: Path,
    *,
    right_video: Path | None = None,
    times: Path | None = None,
    left_topic: str | None = None,
    right_topic: str | None = None,
    pair_tolerance: float | None = None,
) -> StereoRecording:
    """The recording at ``path``: a KITTI folder, a bag (with its two topics), or a left video (with the right one
    and the timestamps)."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"RECORDING {path}: not found")
    if is_bag(path):
        if not left_topic or not right_topic:
            raise InputError(f"RECORDING {path} is a bag: give --left-topic and --right-topic (its image topics)")
        if left_topic == right_topic:
            raise InputError(
                f"--left-topic and --right-topic are both {left_topic}; allowed: the two cameras' different topics"
            )
        require("rosbags", "ros", "reading a ROS bag")
        require("rosbags.image", "ros", "reading a ROS bag")
        return BagPair(path, left_topic, right_topic, pair_tolerance)
    if path.is_dir():
        return KittiFolder(path)
    if right_video is None or times is None:
        raise InputError(
            f"RECORDING {path}: a file that is not a bag; allowed: a KITTI-odometry folder, a ROS bag, or a left video "
            "with --right-video FILE and --times FILE"
        )
    if Path(right_video).resolve() == path.resolve():
        raise InputError(f"--right-video {right_video} is RECORDING itself; allowed: the right camera's own video")
    return VideoPair(path, Path(right_video), Path(times))


def check_signals_clock(series: SignalSeries, recording: StereoRecording, option: str = "--signals") -> None:
    """Refuse signals that cover none of the recording's frames: they are on another clock (or of another drive).

    The frames' times are ``recording.t0 + recording.times`` on the recording's own clock; the signals must share
    it (module notes of :mod:`sensor.recordings.signals`), so their span must hold at least one frame.
    """
    frames = recording.t0 + recording.times
    start, end = float(series.time[0]), float(series.time[-1])
    if not np.any((frames >= start) & (frames <= end)):
        raise InputError(
            f"{option} {series.source}: time_s spans [{start:.6g}, {end:.6g}] s, the recording's frames "
            f"[{frames[0]:.6g}, {frames[-1]:.6g}] s: no frame inside; allowed: signals on the recording's clock "
            "(times.txt, the bag's stamps) over its frames"
        )


def check_unit_signals(series: SignalSeries, unit: int) -> None:
    """Refuse signals beside a rig on towed unit ``unit`` behind the first that lack what its fused filter takes:
    every coupling's articulation down to the unit's own and the unit's own gyro and wheel speed
    (:mod:`sensor.recordings.signals`)."""
    missing = [f"articulation{k}_deg" for k in range(len(series.rear_articulations) + 2, unit + 1)]
    if series.trailer_yaw_rate is None:
        missing.append("trailer_yaw_rate_deg_s (the unit's gyro)")
    if series.trailer_speed is None:
        missing.append("trailer_speed_m_s (the unit's wheel speed)")
    if missing:
        raise InputError(
            f"signals {series.source} beside a rig on towed unit {unit}: no column {', '.join(missing)}; allowed: "
            "the tractor's signals, every coupling's articulation down to the unit's, its own gyro and wheel speed"
        )


def camera_model(
    recording: StereoRecording, calibration_file: Path | None, calib_file: Path | None
) -> tuple[RectifiedCamera, CalibrationResult | None]:
    """The rectified camera the odometry uses, and the calibration that rectifies raw images (None: rectified)."""
    width, height = recording.size
    if calibration_file is not None:
        if calib_file is not None:
            raise InputError("give --calibration (raw images) or --calib (rectified images), not both")
        calibration = CalibrationResult.read(Path(calibration_file))
        if tuple(calibration.image_size) != (width, height):
            w, h = calibration.image_size
            raise InputError(
                f"--calibration {calibration_file} is for {w}×{h} px images; the recording's are {width}×{height} px"
            )
        par = calibration.rectified_rig_parameters()
        camera = RectifiedCamera(par.f, par.cu, par.cv, par.baseline)
        check_baseline(camera, str(calibration_file))
        return camera, calibration
    if calib_file is not None:
        camera = read_kitti_calib(Path(calib_file))
    elif isinstance(recording, KittiFolder) and recording.camera is not None:
        camera = recording.camera
    else:
        raise InputError(
            f"{recording.source}: no camera model; allowed: --calibration FILE.yaml (raw images, from offtrack "
            "calibrate) or a KITTI calib.txt with P0 and P1 (rectified images; in the folder or --calib FILE)"
        )
    folder_calib = Path(getattr(recording, "folder", ".")) / "calib.txt"
    check_baseline(camera, str(calib_file if calib_file is not None else folder_calib))
    if not (0.0 < camera.cu < width and 0.0 < camera.cv < height):
        raise InputError(
            f"calib: principal point ({camera.cu:g}, {camera.cv:g}) px lies outside the {width}×{height} px images"
        )
    return camera, None


def _reference_text(path: Path) -> str:
    """The text of a ``--reference`` poses file (InputError naming it: missing, a directory, not text)."""
    allowed = "allowed: a text file of camera poses, KITTI (12 numbers a line) or TUM (8)"
    if not path.is_file():
        raise InputError(f"--reference {path}: {'a directory' if path.is_dir() else 'not found'}; {allowed}")
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"--reference {path}: not text (byte {exc.start} is not UTF-8); {allowed}") from None
    except OSError as exc:
        raise InputError(f"--reference {path}: cannot be read ({exc.strerror}); {allowed}") from None


def _reference(
    recording: StereoRecording,
    reference: Path | None,
    reference_format: str | None,
    reference_offtracking: Path | None,
    use_folder_poses: bool,
) -> tuple[tuple[np.ndarray, np.ndarray] | None, tuple[np.ndarray, np.ndarray] | None, str]:
    if reference is not None and reference_offtracking is not None:
        raise InputError("give --reference (camera poses) or --reference-offtracking (a series), not both")
    times = recording.times
    if reference_offtracking is not None:
        t, values = read_offtracking_series(Path(reference_offtracking))
        return None, (t - recording.t0, values), str(reference_offtracking)
    if reference is None:
        if use_folder_poses and isinstance(recording, KittiFolder) and recording.poses_file is not None:
            return (times, read_kitti_poses(recording.poses_file, len(times))), None, str(recording.poses_file)
        return None, None, ""
    fmt = reference_format
    if fmt is None:  # by the numbers on its first line: 12 (KITTI) or 8 (TUM)
        first = next((ln for ln in _reference_text(Path(reference)).splitlines() if ln.split("#")[0].strip()), "")
        fmt = "tum" if len(first.split("#")[0].replace(",", " ").split()) == 8 else "kitti"
    if fmt == "kitti":
        return (times, read_kitti_poses(Path(reference), len(times))), None, str(reference)
    if fmt == "tum":
        t, poses = read_tum_poses(Path(reference))
        return (t - recording.t0, poses), None, str(reference)
    raise InputError(f"--reference-format {reference_format!r}: allowed: kitti or tum")


def resolve_inputs(
    recording: Path,
    *,
    rig: Path | RecordingRig,
    calibration: Path | None = None,
    calib: Path | None = None,
    right_video: Path | None = None,
    times: Path | None = None,
    left_topic: str | None = None,
    right_topic: str | None = None,
    pair_tolerance: float | None = None,
    signals: Path | None = None,
    reference: Path | None = None,
    reference_format: str | None = None,
    reference_offtracking: Path | None = None,
    use_folder_poses: bool = True,
    refinement: int = 2,
    seed: int = 0,
    rear_point: str = "axle_mean",
    zero_slip_grade: str = "none",
) -> EstimateInputs:
    """Everything ``offtrack estimate`` is given, opened and checked (module notes); nothing decoded yet.

    ``refinement`` is the odometry's match refinement (0, 1, 2; the loop's ``camera.vo_refinement``, 2 by default)
    and ``seed`` its RANSAC's seed (a run's ``seed``, 0 by default): with both as a run had them, the odometry
    repeats the run's. ``rear_point`` is the tractor's rear point of the zero-slip and fused estimators
    (:data:`~vehicle_model.kinematics.RearPoint`; a run's ``estimators.zero_slip_rear_point`` and
    ``fusion.kinematic_rear_point``); ``lateral_acceleration`` needs the signals' accelerometer column.
    ``zero_slip_grade`` ``accelerometer`` (a run's ``estimators.zero_slip_grade``) needs, beside a rig on the first
    towed unit (the one the zero-slip estimate runs for), the signals' longitudinal accelerometer column. ``rig`` is a
    rig file or a rig already read (one of a rigs file, :mod:`.rigs`).

    Raises
    ------
    InputError
        Any input that cannot work, one line naming it.
    """
    rig_ = rig if isinstance(rig, RecordingRig) else load_rig(Path(rig))
    if refinement not in (0, 1, 2):
        raise InputError(f"--refinement {refinement!r}: allowed: 0 (none), 1 (pixel), 2 (sub-pixel)")
    if not (isinstance(seed, int) and seed >= 0):
        raise InputError(f"--seed {seed!r}: allowed: an integer ≥ 0")
    if rear_point not in get_args(RearPoint):
        raise InputError(f"--rear-point {rear_point!r}: allowed: {', '.join(get_args(RearPoint))}")
    if zero_slip_grade not in get_args(GradeSource):
        raise InputError(f"--zero-slip-grade {zero_slip_grade!r}: allowed: {', '.join(get_args(GradeSource))}")
    rec = open_recording(
        Path(recording),
        right_video=right_video,
        times=times,
        left_topic=left_topic,
        right_topic=right_topic,
        pair_tolerance=pair_tolerance,
    )
    camera, cal = camera_model(rec, calibration, calib)
    model_file = calibration or calib or Path(getattr(rec, "folder", ".")) / "calib.txt"
    check_road_disparity(camera, rec.size, rig_, str(model_file))
    par = cal.rectified_rig_parameters() if cal is not None else None
    series = read_signals(Path(signals)) if signals is not None else None
    if series is not None:
        check_signals_clock(series, rec)
        if rig_.unit != 1:
            check_unit_signals(series, rig_.unit)
    if rear_point == "lateral_acceleration" and (series is None or series.lateral_acceleration is None):
        raise InputError(
            "--rear-point lateral_acceleration needs the tractor's accelerometer: a --signals CSV with a "
            "lateral_acceleration_m_s2 column"
        )
    if (
        zero_slip_grade == "accelerometer"
        and rig_.unit == 1
        and (series is None or series.longitudinal_acceleration is None)
    ):
        raise InputError(
            "--zero-slip-grade accelerometer needs the tractor's longitudinal accelerometer: a --signals CSV with a "
            "longitudinal_acceleration_m_s2 column"
        )
    poses, offtracking, reference_source = _reference(
        rec, reference, reference_format, reference_offtracking, use_folder_poses
    )
    record = {
        "recording": str(Path(recording).resolve()),
        "source": rec.source,
        "right_video": str(Path(right_video).resolve()) if right_video else None,
        "times": str(Path(times).resolve()) if times else None,
        "left_topic": left_topic,
        "right_topic": right_topic,
        "pair_tolerance_s": pair_tolerance,
        "rig": None if isinstance(rig, RecordingRig) else str(Path(rig).resolve()),
        "rig_file": rig_.file,
        "calibration": str(Path(calibration).resolve()) if calibration else None,
        "calib": str(Path(calib).resolve()) if calib else None,
        "camera": {"f_px": camera.f, "cu_px": camera.cu, "cv_px": camera.cv, "baseline_m": camera.baseline},
        "image_size": list(rec.size),
        "signals": str(Path(signals).resolve()) if signals else None,
        "reference": str(Path(reference_source).resolve()) if reference_source else None,
        "reference_kind": "poses" if poses is not None else ("offtracking" if offtracking is not None else None),
        "refinement": refinement,
        "seed": seed,
        "rear_point": rear_point,
        "zero_slip_grade": zero_slip_grade,
    }
    return EstimateInputs(
        recording=rec,
        rig=rig_,
        vo_config=camera.vo_config(refinement=refinement),
        camera_in_trailer=rig_.camera_in_trailer(camera.baseline, par),
        calibration=cal,
        signals=series,
        reference_poses=poses,
        reference_offtracking=offtracking,
        seed=seed,
        rear_point=rear_point,  # checked above
        record=record,
        zero_slip_grade=zero_slip_grade,  # checked above
    )
