"""An animation of a run, rebuilt from its run directory alone (``config.yaml``, ``timeseries.parquet``).

Each frame shows

* a plan view that follows the combination: the reference path, the swept envelopes so far (tractor red,
  trailer blue), the outer front corner and follow-point paths, the combination with its steered wheels
  and, for the roundabout test, the 12.50/5.30 m circles;
* when the camera ran (``estimators.viso_ot``), the left camera image with its matched features (as de Saxe
  & Cebon 2018, Figs 5 and 13): the run's own camera (:class:`CameraPanel`: its lens, calibration, lighting,
  mount flex and odometry) is fed the recorded states of every camera tick in order, so the images and the
  features are those the run's odometry saw; inliers green with their flow since the previous frame, outliers
  red. Without the camera the panel is an overview of the whole run with the current position;
* beneath, for every towed unit with a true off-tracking (the first, then each unit behind it, one panel each),
  the off-tracking of the truth and of every estimator of that unit, each estimate's ±2σ band where it gives a
  standard deviation, scrolling with time, with a cursor at the current instant.

Frames are written as an H.264 mp4 through imageio-ffmpeg (or a GIF, by the file's suffix). One renderer per
process: it is kept between calls and replaced only for a run of another world or rig.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import PathPatch, Polygon

from vehicle_model.errors import InputError
from vehicle_model.simulator import VehicleState

from ..run.plan_marks import draw_circles
from ..run.plots import SavedRun, load_run
from ..run.swept_path import (
    TRACTOR_COLOUR,
    UNIT_COLOURS,
    draw_envelopes,
    envelope_path,
    envelope_samples,
    outer_front_corner_path,
    turn_sign,
    unit_colour,
)
from ..run.unit_shapes import pose_polygons, unit_names, unit_outlines
from .trace_panel import OfftrackingTrace, towed_unit_traces

ANIMATION_FILE = "animation.mp4"
"""Default output file in the run directory."""

ANIMATION_ENVELOPE_SPACING = 0.25
"""Corner movement [m] between the outlines that make up the envelopes of a frame (coarser than a figure's)."""


def frame_times(time: np.ndarray, fps: float, speed: float, max_frames: int | None = None) -> np.ndarray:
    """Simulated times of the frames: every ``speed / fps`` seconds from the first to the last sample.

    With ``max_frames`` and more frames than that, ``max_frames`` times evenly spread over the run instead
    (the animation plays faster but still shows all of it).
    """
    time = np.asarray(time, dtype=float)
    if time.size == 0:
        return np.zeros(0)
    t0, t1 = float(time[0]), float(time[-1])
    step = speed / fps
    n = int(np.floor((t1 - t0) / step + 1e-9)) + 1
    if max_frames is not None and n > max_frames:
        return np.linspace(t0, t1, max(int(max_frames), 1))
    return t0 + step * np.arange(n)


def draw_matches(left: np.ndarray, result: Any, frame: int) -> tuple[np.ndarray, tuple[int, int], str]:
    """A grey left image (RGB) with the odometry's matches of a frame drawn (as de Saxe & Cebon 2018, Figs 5 and 13):
    inliers green with their flow since the previous frame, outliers red.

    Returns
    -------
    image, (matches, inliers), caption
        The drawn image, the matches and the inliers drawn, and a caption naming frame ``frame``'s counts and
        why its motion failed.
    """
    import cv2

    image = cv2.cvtColor(left, cv2.COLOR_GRAY2RGB)
    inliers = np.asarray(result.inliers, dtype=bool)
    points = np.rint(np.asarray(result.matches, dtype=float).reshape(-1, 8)).astype(int)
    for i, m in enumerate(points.tolist()):
        colour = (40, 220, 40) if i < inliers.size and inliers[i] else (230, 40, 40)
        cv2.line(image, (m[0], m[1]), (m[4], m[5]), colour, 1, cv2.LINE_AA)
        cv2.circle(image, (m[4], m[5]), 2, colour, -1, cv2.LINE_AA)
    caption = f"camera frame {frame}: {len(result.matches)} matches, {int(inliers.sum())} inliers" + (
        "" if result.valid else f" ({result.reason or 'failed'})"
    )
    return image, (len(points), int(inliers.sum())), caption


class CameraPanel:
    """The run's own camera replayed frame by frame, the left image of a frame drawn with its matched features.

    The camera and its odometry are built from the run's configuration as the run built them
    (:class:`scenarios.camera.delivery.CameraFeed`, rendering in this process) and fed the recorded states of
    the camera ticks in order: lens, calibration, lighting and auto-exposure, mount flex, self-calibration and
    the odometry's state are the run's, so the images and matches are those the run's odometry saw.

    Parameters
    ----------
    run : SavedRun
        The run (its configuration and time series).

    Attributes
    ----------
    shape : (int, int)
        Height and width of the images [px].
    info : str
        The latest drawn frame's number, matches, inliers and failure reason.
    frame : CameraFrame or None
        What the odometry made of the latest drawn frame (:class:`sensor.frame_odometry.CameraFrame`).
    drawn : (int, int)
        The matches and the inliers drawn on the latest image.
    """

    def __init__(self, run: SavedRun) -> None:
        from ..camera.delivery import CameraFeed

        self.feed = CameraFeed(run.setup, workers=0)
        self.columns = run.columns
        self.rows = np.flatnonzero(np.asarray(run.columns.get("camera_frame", np.zeros(0))) > 0.5)
        rig = self.feed.rig
        self.shape = (rig.height, rig.width)
        self._replayed = 0  # camera frames fed to the feed so far
        self._last: int | None = None
        self._image: np.ndarray | None = None
        self.info = ""
        self.frame: Any = None
        self.drawn = (0, 0)

    def _state(self, r: int) -> VehicleState:
        """The recorded state of row ``r`` (the camera reads the pose — every unit's, for a rig behind the first
        and the other units in view — and, for the mount flex, the velocities)."""
        c = self.columns
        values = {k: float(c[k][r]) for k in ("time", "X", "Y", "psi1", "u", "v1", "r1", "gamma", "r2")}
        trailing = []
        j = 2
        while f"gamma{j}" in c and f"r{j + 1}" in c:  # the further units' (Γ_k, r_{k+1}) pairs
            trailing += [float(c[f"gamma{j}"][r]), float(c[f"r{j + 1}"][r])]
            j += 1
        return VehicleState(**values, slip=np.zeros(0), trailing=np.array(trailing))

    def _replay(self, j: int) -> tuple[np.ndarray, Any]:
        """Feed the camera ticks up to frame ``j`` in order; frame ``j``'s left image and odometry result."""
        if j < self._replayed - 1:
            raise ValueError(f"camera frame {j} is behind the replay (frame {self._replayed - 1}); frames go forward")
        feed = self.feed
        while self._replayed <= j:
            r = int(self.rows[self._replayed])
            shot = feed.capture(r, self._state(r))
            feed.deliver(r + feed.latency_ticks)  # released at once: the estimates are not drawn
            self._replayed += 1
            self.frame = shot.frame
        assert feed.last_pair is not None
        return feed.last_pair[0], self.frame

    def image(self, k: int) -> np.ndarray:
        """The left image (RGB) of the latest camera frame at or before sample ``k``, features drawn.

        Samples must not go back in time past the latest drawn frame.
        """

        j = int(np.searchsorted(self.rows, k, side="right")) - 1
        if j < 0:
            return np.zeros((*self.shape, 3), np.uint8)
        if j == self._last and self._image is not None:
            return self._image
        left, frame = self._replay(j)
        image, self.drawn, self.info = draw_matches(left, frame.vo, j)
        self._last, self._image = j, image
        return image

    def close(self) -> None:
        """Release the camera."""
        self.feed.close()


def _fit(frame: np.ndarray, width: int, height: int) -> np.ndarray:
    """Crop or pad (black) an RGB frame to exactly ``height × width``."""
    frame = frame[:height, :width]
    if frame.shape[:2] != (height, width):
        frame = np.pad(frame, ((0, height - frame.shape[0]), (0, width - frame.shape[1]), (0, 0)))
    return frame


def check_animation_settings(fps: float, speed: float, size: tuple[int, int]) -> tuple[int, int]:
    """Refuse settings no animation can use; return the frame size rounded down to even numbers (H.264).

    Raises
    ------
    InputError
        ``fps`` or ``speed`` not positive, or a side of ``size`` below 16 px.
    """
    if fps <= 0 or speed <= 0 or min(size) < 16:
        raise InputError(
            f"animation needs fps > 0, speed > 0 and a size of at least 16 px (got {fps}, {speed}, {size})"
        )
    return int(size[0]) // 2 * 2, int(size[1]) // 2 * 2


def grab_frame(fig: Any, width: int, height: int) -> np.ndarray:
    """The figure drawn and its RGB pixels cropped or padded to exactly ``height × width``."""
    fig.canvas.draw()
    return _fit(np.asarray(fig.canvas.buffer_rgba())[..., :3], width, height)


def _writer(out: Path, fps: float, size: tuple[int, int]) -> tuple[Callable[[np.ndarray], None], Callable[[], None]]:
    """``(append(frame), close())`` for an mp4 (H.264, streamed) or a GIF (frames kept until closed)."""
    if out.suffix.lower() == ".gif":
        import imageio.v3 as iio

        frames: list[np.ndarray] = []

        def close_gif() -> None:
            iio.imwrite(out, np.stack(frames), duration=1000.0 / fps, loop=0)

        return (lambda frame: frames.append(np.array(frame))), close_gif  # a copy: the canvas is reused
    import imageio_ffmpeg

    gen = imageio_ffmpeg.write_frames(
        str(out),
        size,
        fps=fps,
        codec="libx264",
        pix_fmt_in="rgb24",
        pix_fmt_out="yuv420p",
        quality=7,
        macro_block_size=1,
        ffmpeg_log_level="error",
    )
    gen.send(None)
    return (lambda frame: gen.send(np.ascontiguousarray(frame))), gen.close


def animation_title(run: SavedRun) -> str:
    """The run's title, with the roundabout test's verdict and radii where the run has one."""
    test = run.metrics.get("roundabout_test")
    if not test:
        return run.title
    verdict = "PASS" if test.get("pass") else "FAIL"
    return (
        f"{run.title} — roundabout test {verdict}: tractor max r {test['outer_radius_max']:.3f} m (limit 12.50), "
        f"trailer min r {test['inner_radius_min']:.3f} m (limit 5.30)"
    )


def frame_writer(
    out: Path, fps: float, size: tuple[int, int]
) -> tuple[Callable[[np.ndarray], None], Callable[[], None]]:
    """``(append(frame), close())`` writing RGB frames of ``size`` (width, height) to an mp4 (H.264) or a GIF."""
    return _writer(out, fps, size)


def animate_run(
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
    """Animate a run from its directory (module docstring) into an mp4 (or a GIF); return the file.

    Parameters
    ----------
    run_dir
        The run directory (``config.yaml``, ``timeseries.parquet``; ``metrics.json`` if there is one).
    out
        The output file, ``.mp4`` or ``.gif`` (default ``run_dir/animation.mp4``).
    fps
        Frames per second of the video.
    max_frames
        At most this many frames, spread evenly over the run (default: every ``speed / fps`` s).
    speed
        Simulated seconds per second of video.
    camera
        Show the left camera image with its matched features (re-rendered; needs headless OpenGL). Default:
        when the camera ran (``estimators.viso_ot``). Costs one render and one odometry frame per camera frame
        up to the last one shown.
    size
        Frame size (width, height) [px]; rounded down to even numbers for H.264.
    view_half_width
        Half the side of the following plan view [m].
    window_s
        Width of the scrolling off-tracking window [s].
    progress
        ``progress(frames written, frames in all)`` after every frame.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    InputError
        The run has fewer than two samples, or ``fps``, ``speed`` or ``size`` are not positive.
    """
    width, height = check_animation_settings(fps, speed, size)
    run = load_run(Path(run_dir))
    cols, params = run.columns, run.params
    time = np.asarray(cols.get("time", np.zeros(0)), dtype=float)
    if time.size < 2:
        raise InputError(f"{run_dir}: the run has {time.size} samples; an animation needs two or more")
    out = Path(out) if out is not None else Path(run_dir) / ANIMATION_FILE
    out.parent.mkdir(parents=True, exist_ok=True)
    use_camera = bool(run.config.estimators.viso_ot) if camera is None else bool(camera)
    cam = CameraPanel(run) if use_camera else None
    times = frame_times(time, fps, speed, max_frames)
    samples = np.clip(np.searchsorted(time, times + 1e-9, side="right") - 1, 0, time.size - 1)

    traced = towed_unit_traces(cols)
    fig = plt.figure(figsize=(width / 100.0, height / 100.0), dpi=100)
    rows_traced = len(traced)
    grid = fig.add_gridspec(
        2, 2, height_ratios=[1.9, 1.0 + 0.6 * (rows_traced - 1)], width_ratios=[1, 2.1 if cam else 1.4]
    )
    grid.update(left=0.06, right=0.99, bottom=0.08, top=0.93, wspace=0.12, hspace=0.25)
    plan, side = fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[0, 1])
    trace_grid = grid[1, :].subgridspec(rows_traced, 1, hspace=0.08)
    traces = [fig.add_subplot(trace_grid[i, 0]) for i in range(rows_traced)]
    centre = run.setup.annulus_centre
    ref = run.setup.path.points
    outlines = unit_outlines(params, cols)
    kept = {unit: envelope_samples(polys, ANIMATION_ENVELOPE_SPACING) for unit, polys in outlines.items()}
    corner = outer_front_corner_path(params, cols, turn_sign(cols))
    plan.plot(ref[:, 0], ref[:, 1], "k--", lw=0.7)
    if centre is not None:
        draw_circles(plan, centre)
    envelopes = {}
    for unit in unit_names(params)[::-1]:
        colour = UNIT_COLOURS[unit]
        envelopes[unit] = PathPatch(envelope_path(outlines[unit][:1]), facecolor=colour, edgecolor="none", alpha=0.22)
        plan.add_patch(envelopes[unit])
    (corner_line,) = plan.plot([], [], color=TRACTOR_COLOUR, lw=1.2)
    (follow_line,) = plan.plot([], [], color="tab:green", lw=1.0)
    steer_names = [c for c in cols if c.startswith("steer_")]

    def polygons(k: int) -> list[tuple[str, np.ndarray]]:
        steer = {c.removeprefix("steer_"): float(cols[c][k]) for c in steer_names}
        return pose_polygons(params, cols, k, steer)

    body = []
    for unit, poly in polygons(0):
        tyre = unit.endswith("tyre")
        edge = unit_colour(unit)
        patch = Polygon(poly, closed=True, fc="0.25" if tyre else "white", ec="none" if tyre else edge, alpha=0.85)
        body.append(plan.add_patch(patch))
    plan.set_aspect("equal")
    plan.set_xlabel("X [m]", fontsize=8)
    plan.set_ylabel("Y [m]", fontsize=8)
    plan.tick_params(labelsize=7)
    status = plan.text(
        0.02,
        0.98,
        "",
        transform=plan.transAxes,
        ha="left",
        va="top",
        fontsize=8,
        zorder=10,
        bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "0.6", "alpha": 0.85},
    )

    if cam is not None:
        picture = side.imshow(np.zeros((*cam.shape, 3), np.uint8))
        side.set_axis_off()
        side_title = side.set_title("", fontsize=9)
        marker = None
    else:
        draw_envelopes(side, params, cols, alpha=0.18, spacing=ANIMATION_ENVELOPE_SPACING)
        side.plot(ref[:, 0], ref[:, 1], "k--", lw=0.6)
        if centre is not None:
            draw_circles(side, centre)
            side.legend(fontsize=6, loc="upper right")
        (marker,) = side.plot([], [], "o", color="k", ms=6)
        side.set_aspect("equal", adjustable="datalim")
        side.autoscale_view()
        side.tick_params(labelsize=7)
        side.set_xlabel("X [m]", fontsize=8)
        side.set_ylabel("Y [m]", fontsize=8)
        side_title = side.set_title("whole run", fontsize=9)

    panels = [
        OfftrackingTrace(axes, time, cols, names, window_s, unit=unit)
        for axes, (unit, names) in zip(traces, traced, strict=True)
    ]
    for axes in traces[:-1]:
        axes.tick_params(labelbottom=False)
        axes.set_xlabel("")
    fig.text(0.01, 0.995, animation_title(run), ha="left", va="top", fontsize=9)

    append, close = _writer(out, fps, (width, height))
    try:
        for i, k in enumerate(samples):
            k = int(k)
            for unit, patch in envelopes.items():
                upto = np.append(kept[unit][kept[unit] < k], k)
                patch.set_path(envelope_path(outlines[unit][upto], spacing=0.0))
            corner_line.set_data(corner[: k + 1, 0], corner[: k + 1, 1])
            follow_line.set_data(cols["follow_x"][: k + 1], cols["follow_y"][: k + 1])
            for patch, (_, poly) in zip(body, polygons(k), strict=True):
                patch.set_xy(poly)
            mid = 0.5 * np.array([cols["kingpin_x"][k] + cols["X"][k], cols["kingpin_y"][k] + cols["Y"][k]])
            plan.set_xlim(mid[0] - view_half_width, mid[0] + view_half_width)
            plan.set_ylim(mid[1] - view_half_width, mid[1] + view_half_width)
            status.set_text(
                f"t = {time[k]:5.1f} s   u = {3.6 * cols['u'][k]:4.1f} km/h   Γ = {np.degrees(cols['gamma'][k]):+5.1f}°"
                if "u" in cols
                else f"t = {time[k]:5.1f} s"
            )
            if cam is not None:
                picture.set_data(cam.image(k))
                side_title.set_text(cam.info)
            elif marker is not None:
                marker.set_data([cols["X"][k]], [cols["Y"][k]])
            for panel in panels:
                panel.show(k)
            append(grab_frame(fig, width, height))
            if progress is not None:
                progress(i + 1, len(samples))
    finally:
        close()
        plt.close(fig)
        if cam is not None:
            cam.close()
    return out
