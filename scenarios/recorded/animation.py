"""``offtrack animate`` on a recorded run: the trailer's path, the camera's image with its matches, the traces.

Each frame of the video shows

* a plan view following the trailer: the kingpin's path dead-reckoned from the camera (and the reference's, when
  there is one) up to the instant, and the trailer's body on the best path there is (:mod:`.plots`);
* with ``camera`` (default: when the recording can still be opened), the left image of the latest camera frame with
  its matched features, the odometry run again on that frame and the one before (as
  :mod:`scenarios.export.animation` does for rendered runs: inliers green with their flow, outliers red);
* beneath, the off-tracking of the truth (if any) and of every estimator, scrolling with time.

The recording is opened again from ``recording.yaml`` (:func:`.inputs.resolve_inputs`), so its files must still be
where they were.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Polygon

from vehicle_model.errors import InputError

from ..export.animation import (
    ANIMATION_FILE,
    OfftrackingTrace,
    check_animation_settings,
    draw_matches,
    frame_times,
    frame_writer,
    grab_frame,
)
from ..run.metrics import estimator_names
from ..run.results import read_timeseries
from ..run.swept_path import TRAILER_COLOUR
from .inputs import EstimateInputs, resolve_inputs
from .plots import trailer_body
from .report import read_recording_file, recorded_run_title
from .rig import rig_from_fields

__all__ = ["animate_recorded_run"]


def _inputs(record: dict[str, Any]) -> EstimateInputs:
    """The recording opened again from its record (its rig, camera model and settings)."""

    def path(key: str) -> Path | None:
        return Path(record[key]) if record.get(key) else None

    return resolve_inputs(
        Path(record["recording"]),
        rig=Path(record["rig"]) if record.get("rig") else rig_from_fields(record["rig_file"], "recording.yaml"),
        calibration=path("calibration"),
        calib=path("calib"),
        right_video=path("right_video"),
        times=path("times"),
        left_topic=record.get("left_topic"),
        right_topic=record.get("right_topic"),
        pair_tolerance=record.get("pair_tolerance_s"),
        use_folder_poses=False,
        refinement=int(record.get("refinement", 2)),
        seed=int(record.get("seed", 0)),
    )


class _Camera:
    """The left image of a camera frame with the matches the odometry finds on it and the frame before."""

    def __init__(self, inputs: EstimateInputs, rows: np.ndarray, frames: np.ndarray) -> None:
        from sensor.vo import StereoOdometry

        self.inputs = inputs
        self.vo = StereoOdometry(inputs.vo_config, inputs.seed)
        self.rows, self.frames = rows, frames  # the time series' rows of camera frames, their frame numbers
        width, height = inputs.recording.size
        self.shape = (height, width)
        self._last: int | None = None
        self._image: np.ndarray | None = None
        self.info = ""

    def image(self, k: int) -> np.ndarray:
        """The left image (RGB) of the latest camera frame at or before row ``k``, its matches drawn."""
        j = int(np.searchsorted(self.rows, k, side="right")) - 1
        if j < 0:
            return np.zeros((*self.shape, 3), np.uint8)
        if j == self._last and self._image is not None:
            return self._image
        index = int(self.frames[j])
        self.vo.reset()
        start = max(index - 1, 0)
        left = None
        result = None
        for slot, lft, rgt in self.inputs.recording.pairs(start):
            if lft is not None and rgt is not None:
                if self.inputs.calibration is not None:
                    lft, rgt = self.inputs.calibration.rectify(lft, rgt)
                result = self.vo.process(lft, rgt)
                left = lft
            if slot.index >= index:
                break
        if left is None or result is None:
            image = np.zeros((*self.shape, 3), np.uint8)
            self.info = f"camera frame {index}: no images"
        else:
            image, _, self.info = draw_matches(left, result, index)
        self._last, self._image = j, image
        return image


def animate_recorded_run(
    run_dir: Path,
    out: Path | None = None,
    fps: float = 10.0,
    max_frames: int | None = None,
    *,
    speed: float = 4.0,
    camera: bool | None = None,
    size: tuple[int, int] = (1280, 720),
    view_half_width: float = 20.0,
    window_s: float = 30.0,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Animate a recorded run from its directory (module notes) into an mp4 (or a GIF); return the file.

    Parameters as :func:`scenarios.export.animation.animate_run`; ``camera`` defaults to whether the recording can
    be opened again.

    Raises
    ------
    InputError
        The run has fewer than two rows, the settings are not positive, or the camera is asked for and the
        recording cannot be opened.
    """
    width, height = check_animation_settings(fps, speed, size)
    run_dir = Path(run_dir)
    record = read_recording_file(run_dir)
    params = rig_from_fields(record["rig_file"], "recording.yaml").params
    cols = read_timeseries(run_dir)
    time = np.asarray(cols.get("time", np.zeros(0)), dtype=float)
    if time.size < 2:
        raise InputError(f"{run_dir}: the run has {time.size} rows; an animation needs two or more")
    cam = None
    if camera is None or camera:
        try:
            inputs = _inputs(record)
        except InputError:
            if camera:
                raise
        else:
            valid = np.isfinite(cols.get("vo_valid", np.full(time.size, np.nan)))
            rows = np.flatnonzero(valid)
            cam = _Camera(inputs, rows, cols["frame"][rows])
    out = Path(out) if out is not None else run_dir / ANIMATION_FILE
    out.parent.mkdir(parents=True, exist_ok=True)
    times = frame_times(time, fps, speed, max_frames)
    samples = np.clip(np.searchsorted(time, times + 1e-9, side="right") - 1, 0, time.size - 1)

    fig = plt.figure(figsize=(width / 100.0, height / 100.0), dpi=100)
    grid = fig.add_gridspec(2, 2, height_ratios=[1.9, 1], width_ratios=[1, 2.1 if cam else 1.0])
    grid.update(left=0.06, right=0.99, bottom=0.08, top=0.93, wspace=0.12, hspace=0.25)
    plan, side, trace = fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[0, 1]), fig.add_subplot(grid[1, :])
    vo = np.column_stack([cols["kingpin_x_viso_ot"], cols["kingpin_y_viso_ot"]])
    reference = "trailer_heading" in cols and np.isfinite(cols["trailer_heading"]).any()
    path, heading = (
        (np.column_stack([cols["kingpin_x"], cols["kingpin_y"]]), cols["trailer_heading"])
        if reference
        else (vo, cols["trailer_heading_viso_ot"])
    )
    (vo_line,) = plan.plot([], [], color="tab:blue", lw=1.2, label="camera (dead-reckoned)")
    ref_line = plan.plot([], [], "k--", lw=1.0, label="reference")[0] if reference else None
    body = plan.add_patch(Polygon(np.zeros((4, 2)), closed=True, fc="white", ec=TRAILER_COLOUR, alpha=0.85))
    plan.set_aspect("equal")
    plan.legend(fontsize=7, loc="lower left")
    plan.tick_params(labelsize=7)
    plan.set_xlabel("x [m]", fontsize=8)
    plan.set_ylabel("y [m]", fontsize=8)
    if cam is not None:
        picture = side.imshow(np.zeros((*cam.shape, 3), np.uint8))
        side.set_axis_off()
        side_title = side.set_title("", fontsize=9)
    else:
        side.plot(vo[:, 0], vo[:, 1], color="tab:blue", lw=0.8)
        (marker,) = side.plot([], [], "o", color="k", ms=6)
        side.set_aspect("equal", adjustable="datalim")
        side.tick_params(labelsize=7)
        side.set_xlabel("x [m]", fontsize=8)
        side.set_ylabel("y [m]", fontsize=8)
        side_title = side.set_title("whole recording", fontsize=9)
    names = [n for n in ("truth", *estimator_names(cols)) if np.isfinite(cols[f"offtracking_{n}"]).any()]
    panel = OfftrackingTrace(trace, time, cols, names, window_s)
    fig.text(0.01, 0.995, recorded_run_title(record), ha="left", va="top", fontsize=9)

    append, close = frame_writer(out, fps, (width, height))
    try:
        for i, k in enumerate(samples):
            k = int(k)
            vo_line.set_data(vo[: k + 1, 0], vo[: k + 1, 1])
            if ref_line is not None:
                ref_line.set_data(path[: k + 1, 0], path[: k + 1, 1])
            if np.all(np.isfinite(path[k])) and np.isfinite(heading[k]):
                body.set_xy(trailer_body(params, path[k, 0], path[k, 1], heading[k]))
                centre = path[k]
            else:
                centre = vo[k]
            plan.set_xlim(centre[0] - view_half_width, centre[0] + view_half_width)
            plan.set_ylim(centre[1] - view_half_width, centre[1] + view_half_width)
            if cam is not None:
                picture.set_data(cam.image(k))
                side_title.set_text(cam.info)
            else:
                marker.set_data([vo[k, 0]], [vo[k, 1]])
            panel.show(k)
            append(grab_frame(fig, width, height))
            if progress is not None:
                progress(i + 1, len(samples))
    finally:
        close()
        plt.close(fig)
    return out
