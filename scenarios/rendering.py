"""Rendered camera images for scenarios: the world of a scenario, KITTI-style datasets, videos, a benchmark.

* :func:`world_for_scenario` builds the procedural world around a scenario's reference path.
* :func:`export_kitti` simulates a scenario and renders its camera frames into a directory laid out
  like the KITTI odometry benchmark (Geiger et al. 2012), so any KITTI reader (and libviso2's
  demo) can load it::

      image_0/000000.png …   left camera, grey, 1344 × 391 by default
      image_1/000000.png …   right camera
      calib.txt              P0 … P3 (3×4, row-major) and Tr (identity)
      poses.txt              per frame: the 3×4 pose of the left camera in the first left camera's
                             frame, T_cam0←cam_k, OpenCV axes (x right, y down, z forward)
      times.txt              per frame: time since the first frame [s]
      offtrack.json          scenario, rig, world settings and run status

  The calibration is the *ideal* rig's (rectified, ``P1 = K·[I | −b·e_x]``): a misaligned right
  camera (paper §4.4) renders rotated images that the calibration does not know about, as in the
  field tests.
* :func:`write_video` writes a side-by-side stereo video (H.264 through imageio-ffmpeg).
* :func:`bench_render` measures the renderer on the ``roundabout-3`` world.
"""

from __future__ import annotations

import json
import math
import os
import platform
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from sensor.camera import StereoRig
from sensor.world import World, build_world
from vehicle_model.errors import InputError

from .build import ScenarioSetup, build_scenario
from .config import ScenarioConfig, load_scenario

RenderProgress = Callable[[int, int], None]
"""``(frames done, frames in total)``."""


def rig_from_config(config: ScenarioConfig | Any) -> StereoRig:
    """The stereo rig of a scenario's ``camera`` section (degrees at this edge, SI inside).

    Parameters
    ----------
    config : ScenarioConfig or CameraConfig
        A scenario configuration (its ``camera``) or the camera section itself; a configuration
        without one gives the default rig (paper §3.1).
    """
    camera = getattr(config, "camera", config)
    if camera is None or not hasattr(camera, "psi_c2v_deg"):
        return StereoRig()
    roll, pitch, yaw = getattr(camera, "right_misalignment_deg", (0.0, 0.0, 0.0))
    return StereoRig.from_degrees(
        hfov_deg=camera.hfov_deg,
        psi_c2v_deg=camera.psi_c2v_deg,
        roll_deg=roll,
        pitch_deg=pitch,
        yaw_deg=yaw,
        width=camera.width,
        height=camera.height,
        baseline=camera.baseline,
        station=camera.station,
        lateral=camera.lateral,
        mount_height=camera.mount_height,
        noise_std=getattr(camera, "noise_std", 0.0),
        exposure_std=getattr(camera, "brightness_jitter", 0.0),
    )


def _density(config: ScenarioConfig, scenery_density: float | None) -> float:
    if scenery_density is not None:
        return float(scenery_density)
    return float(getattr(getattr(config, "camera", None), "scenery_density", 1.0))


def world_for_scenario(
    setup_or_config: ScenarioSetup | ScenarioConfig,
    scenery_density: float | None = None,
    seed: int | None = None,
    **world_settings: Any,
) -> World:
    """The procedural world around a scenario's reference path.

    Parameters
    ----------
    setup_or_config : ScenarioSetup or ScenarioConfig
        A built scenario (its ``path`` and ``config.seed`` are used) or a configuration (built here).
    scenery_density : float, optional
        Fraction of roadside objects, in [0, 1] (paper §3.2.3: 1.0, 0.5, 0.0); default: the
        scenario's ``camera.scenery_density`` (1.0 unless set).
    seed : int, optional
        Seed of the world (default: the scenario's ``seed``).
    **world_settings
        Other :class:`sensor.world.WorldConfig` fields (``road_width``, ``apron_width``, …).
    """
    setup = setup_or_config if isinstance(setup_or_config, ScenarioSetup) else build_scenario(setup_or_config)
    seed = setup.config.seed if seed is None else seed
    density = _density(setup.config, scenery_density)
    return build_world(setup.path, scenery_density=density, seed=int(seed), **world_settings)


# ------------------------------------------------------------------------------------------------
# KITTI-style export


def _kitti_line(matrix: np.ndarray) -> str:
    return " ".join(f"{v:.12e}" for v in np.asarray(matrix, dtype=float)[:3, :4].ravel())


def write_calib(path: Path, rig: StereoRig) -> None:
    """``calib.txt`` of the KITTI odometry benchmark for a rig: P0–P3 and Tr, 12 numbers each."""
    p0, p1 = rig.projection_matrices()
    lines = [
        f"P0: {_kitti_line(p0)}",
        f"P1: {_kitti_line(p1)}",
        f"P2: {_kitti_line(p0)}",
        f"P3: {_kitti_line(p1)}",
        f"Tr: {_kitti_line(np.eye(4))}",
    ]
    Path(path).write_text("\n".join(lines) + "\n")


def read_calib(path: Path) -> dict[str, np.ndarray]:
    """Parse a KITTI ``calib.txt`` into 3×4 matrices by key."""
    out = {}
    for line in Path(path).read_text().splitlines():
        if ":" in line:
            key, values = line.split(":", 1)
            out[key.strip()] = np.array([float(v) for v in values.split()]).reshape(3, 4)
    return out


def read_poses(path: Path) -> np.ndarray:
    """Parse a KITTI ``poses.txt`` into ``(n, 4, 4)`` poses."""
    rows = np.loadtxt(path, ndmin=2).reshape(-1, 3, 4)
    poses = np.tile(np.eye(4), (len(rows), 1, 1))
    poses[:, :3, :] = rows
    return poses


def export_kitti(
    config: ScenarioConfig | str,
    out_dir: str | Path,
    rig: StereoRig | None = None,
    scenery_density: float | None = None,
    max_frames: int | None = None,
    progress: RenderProgress | None = None,
    *,
    video: bool = False,
    overwrite: bool = False,
    antialias: bool = False,
) -> dict[str, Any]:
    """Simulate a scenario and write its rendered camera frames as a KITTI-odometry-style dataset.

    Parameters
    ----------
    config : ScenarioConfig or str
        The scenario (a configuration, or a catalogue name / YAML file).
    out_dir : str or Path
        Output directory (created).
    rig : StereoRig, optional
        The cameras (default: the scenario's ``camera`` section, :func:`rig_from_config`; its
        defaults are paper §3.1: rear-facing at the trailer's rear, 0.5 m baseline).
    scenery_density : float, optional
        Fraction of roadside objects, in [0, 1] (default: the scenario's ``camera.scenery_density``).
    max_frames : int, optional
        Render at most this many camera frames (from the start).
    progress : callable, optional
        ``progress(done, total)`` after each frame.
    video : bool
        Also write ``stereo.mp4`` (side by side, at the camera rate).
    overwrite : bool
        Replace an earlier export in ``out_dir`` (otherwise refused).
    antialias : bool
        Render with 4× multisampling (about 2.5× slower).

    Returns
    -------
    dict
        ``frames``, ``status`` (of the simulation), ``out_dir``, ``render_s``, ``simulate_s``,
        ``ms_per_pair``.
    """
    from sensor.renderer import StereoRenderer

    if isinstance(config, str):
        config = load_scenario(config)
    if max_frames is not None and max_frames < 1:
        raise InputError(f"max_frames = {max_frames} must be at least 1")
    out = Path(out_dir)
    markers = [out / "poses.txt", out / "image_0", out / "image_1", out / "calib.txt"]
    if any(m.exists() for m in markers) and not overwrite:
        raise InputError(f"{out} already holds a dataset; choose another directory or pass overwrite=True")
    rig = rig if rig is not None else rig_from_config(config)
    scenery_density = _density(config, scenery_density)
    t0 = time.perf_counter()
    setup = build_scenario(config)
    from .cosim import run_cosimulation

    outcome, cols = run_cosimulation(setup)
    simulate_s = time.perf_counter() - t0
    frames = np.flatnonzero(np.asarray(cols["camera_frame"]) > 0.5)
    if max_frames is not None:
        frames = frames[:max_frames]
    if len(frames) == 0:
        raise InputError("the simulation produced no camera frame; check rates.camera_hz and duration_s")

    world = world_for_scenario(setup, scenery_density)
    renderer = StereoRenderer(world, rig, setup.params, seed=config.seed, antialias=antialias)
    for sub in ("image_0", "image_1"):
        (out / sub).mkdir(parents=True, exist_ok=True)
        for old in (out / sub).glob("*.png"):
            old.unlink()
    import cv2

    x, y, psi1, gamma = (np.asarray(cols[k])[frames] for k in ("X", "Y", "psi1", "gamma"))
    left_poses = rig.camera_in_world(setup.params, x, y, psi1, gamma, "left")
    right_poses = rig.camera_in_world(setup.params, x, y, psi1, gamma, "right")
    writer = StereoVideoWriter(out / "stereo.mp4", config.rates.camera_hz) if video else None
    t1 = time.perf_counter()
    try:
        for k in range(len(frames)):
            pair = renderer.render_poses(left_poses[k], right_poses[k], frame=k)
            cv2.imwrite(str(out / "image_0" / f"{k:06d}.png"), pair.left)
            cv2.imwrite(str(out / "image_1" / f"{k:06d}.png"), pair.right)
            if writer is not None:
                writer.append(pair.left, pair.right)
            if progress is not None:
                progress(k + 1, len(frames))
    finally:
        if writer is not None:
            writer.close()
    render_s = time.perf_counter() - t1

    write_calib(out / "calib.txt", rig)
    first_inv = np.linalg.inv(left_poses[0])
    rel = first_inv @ left_poses  # T_cam0←cam_k
    (out / "poses.txt").write_text("".join(_kitti_line(p) + "\n" for p in rel))
    times = np.asarray(cols["time"])[frames]
    (out / "times.txt").write_text("".join(f"{t - times[0]:.6e}\n" for t in times))
    meta = {
        "scenario": config.name,
        "seed": config.seed,
        "status": outcome.status,
        "message": outcome.message,
        "frames": len(frames),
        "camera_hz": config.rates.camera_hz,
        "scenery_density": scenery_density,
        "world": {k: getattr(world.config, k) for k in world.config.__dataclass_fields__},
        "objects": world.object_counts,
        "rig": _rig_summary(rig, setup.params),
        "vehicle": setup.params.name,
    }
    (out / "offtrack.json").write_text(json.dumps(meta, indent=2) + "\n")
    return {
        "out_dir": str(out),
        "frames": len(frames),
        "status": outcome.status,
        "simulate_s": simulate_s,
        "render_s": render_s,
        "ms_per_pair": 1000.0 * render_s / len(frames),
    }


def _rig_summary(rig: StereoRig, params=None) -> dict[str, Any]:
    """The rig's settings with angles in degrees (for files people read)."""
    return {
        "width": rig.width,
        "height": rig.height,
        "hfov_deg": math.degrees(rig.hfov),
        "focal_px": rig.focal_length,
        "baseline_m": rig.baseline,
        "station_m": rig.resolve_station(params) if (rig.station is not None or params is not None) else None,
        "lateral_m": rig.lateral,
        "mount_height_m": rig.mount_height,
        "psi_c2v_deg": math.degrees(rig.psi_c2v),
        "misalignment_deg": {
            "roll": math.degrees(rig.misalignment.roll),
            "pitch": math.degrees(rig.misalignment.pitch),
            "yaw": math.degrees(rig.misalignment.yaw),
        },
        "noise_std": rig.noise_std,
        "exposure_std": rig.exposure_std,
    }


# ------------------------------------------------------------------------------------------------
# Video


class StereoVideoWriter:
    """Streams stereo pairs side by side (left | right, 4 px black gap) into an H.264 mp4.

    Parameters
    ----------
    path : str or Path
        Output file.
    fps : float
        Frame rate (the camera rate).
    quality : float
        imageio-ffmpeg quality, 0–10 (10 best).
    """

    GAP = 4

    def __init__(self, path: str | Path, fps: float, quality: float = 7.0) -> None:
        self.path = Path(path)
        self.fps = float(fps)
        self.quality = quality
        self.frames = 0
        self._gen = None
        self._size: tuple[int, int] | None = None

    def append(self, left: np.ndarray, right: np.ndarray) -> None:
        """Add one pair of equally sized grey (or RGB) images."""
        left, right = np.asarray(left), np.asarray(right)
        if left.shape != right.shape:
            raise InputError(f"stereo frames differ in shape: {left.shape} vs {right.shape}")
        if left.ndim == 3:
            import cv2

            left, right = cv2.cvtColor(left, cv2.COLOR_RGB2GRAY), cv2.cvtColor(right, cv2.COLOR_RGB2GRAY)
        h, _w = left.shape
        gap = np.zeros((h, self.GAP), np.uint8)
        frame = np.hstack([left, gap, right])
        # yuv420p needs even sides: pad with black.
        ph, pw = frame.shape[0] % 2, frame.shape[1] % 2
        if ph or pw:
            frame = np.pad(frame, ((0, ph), (0, pw)))
        size = (frame.shape[1], frame.shape[0])
        if self._gen is None:
            import imageio_ffmpeg

            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._gen = imageio_ffmpeg.write_frames(
                str(self.path),
                size,
                fps=self.fps,
                codec="libx264",
                pix_fmt_in="gray",
                pix_fmt_out="yuv420p",
                quality=self.quality,
                macro_block_size=1,
                ffmpeg_log_level="error",
            )
            self._gen.send(None)
            self._size = size
        elif size != self._size:
            raise InputError(f"video frames must keep one size: {size} vs {self._size}")
        self._gen.send(np.ascontiguousarray(frame, dtype=np.uint8))
        self.frames += 1

    def close(self) -> None:
        """Finish the file."""
        if self._gen is not None:
            self._gen.close()
            self._gen = None


def write_video(
    path: str | Path, frames_left: Iterable[np.ndarray], frames_right: Iterable[np.ndarray], fps: float
) -> int:
    """Write a side-by-side stereo video (mp4, H.264).

    Parameters
    ----------
    path : str or Path
        Output file (``.mp4``).
    frames_left, frames_right : iterable of numpy.ndarray
        Equally many grey uint8 images of one size (iterables are consumed lazily).
    fps : float
        Frame rate [1/s].

    Returns
    -------
    int
        Frames written.
    """
    writer = StereoVideoWriter(path, fps)
    try:
        for left, right in zip(frames_left, frames_right, strict=True):
            writer.append(left, right)
    finally:
        writer.close()
    return writer.frames


# ------------------------------------------------------------------------------------------------
# Benchmark


def bench_render(
    duration_frames: int = 50, scenario: str = "roundabout-3", antialias: bool = False, scenery_density: float = 1.0
) -> dict[str, Any]:
    """Rendering speed of stereo pairs on a scenario's default world, at the default 1344 × 391.

    The cameras ride the reference path at the scenario's cornering speed and camera rate, from
    the start of the manoeuvre (the tractor's CG on the path, the trailer in line): the same
    world and viewpoints a run would render, without paying for the simulation.

    Returns
    -------
    dict
        ``pairs_per_s``, ``ms_per_pair`` (mean) and ``ms_per_pair_median``, ``width``, ``height``,
        ``triangles`` (in the world; instanced objects outside the view are skipped), the per-pair
        breakdown ``ms_cull`` (instance culling and scene upkeep), ``ms_submit`` (Python/pyrender
        and llvmpipe's vertex work while issuing draw calls), ``ms_draw`` (waiting for llvmpipe's
        rasteriser to finish), ``ms_readback`` (resolve and ``glReadPixels``), ``ms_grey`` (RGBA →
        grey and row flip), plus ``world_build_s``, ``first_pair_s`` (context creation and
        texture upload), ``cpu_ms_per_pair`` (CPU time of all threads: llvmpipe rasterises on
        every core, so on a busy machine the wall time grows while this stays) and the OpenGL
        renderer string.
    """
    from sensor.renderer import StereoRenderer

    config = load_scenario(scenario)
    setup = build_scenario(config)
    t0 = time.perf_counter()
    world = world_for_scenario(setup, scenery_density)
    build_s = time.perf_counter() - t0
    rig = StereoRig()
    renderer = StereoRenderer(world, rig, setup.params, seed=config.seed, antialias=antialias)
    path = setup.path
    step = config.speed.cornering_kmh / 3.6 / config.rates.camera_hz
    s = path.turn_span[0] + step * np.arange(duration_frames + 1)
    x, y = np.interp(s, path.s, path.x), np.interp(s, path.s, path.y)
    h = np.interp(s, path.s, path.heading)
    t1 = time.perf_counter()
    renderer.render(x[0], y[0], h[0], 0.0, frame=0)
    first_s = time.perf_counter() - t1
    renderer.reset_timings()
    times = []
    cpu0 = time.process_time()
    for k in range(1, duration_frames + 1):
        t = time.perf_counter()
        renderer.render(x[k], y[k], h[k], 0.0, frame=k)
        times.append(time.perf_counter() - t)
    cpu_s = time.process_time() - cpu0
    times_a = np.array(times)
    tm = renderer.timings
    n = max(len(times), 1)
    info = renderer.gl_info
    return {
        "benchmark": "render",
        "scenario": scenario,
        "pairs": len(times),
        "pairs_per_s": float(len(times) / times_a.sum()),
        "ms_per_pair": float(1000.0 * times_a.mean()),
        "ms_per_pair_median": float(1000.0 * np.median(times_a)),
        "ms_per_pair_p90": float(1000.0 * np.percentile(times_a, 90)),
        "cpu_ms_per_pair": 1000.0 * cpu_s / max(len(times), 1),
        "width": rig.width,
        "height": rig.height,
        "triangles": world.triangle_count,
        "scenery_density": scenery_density,
        "antialias": antialias,
        "ms_cull": 1000.0 * tm.get("cull_s", 0.0) / n,
        "ms_submit": 1000.0 * tm.get("submit_s", 0.0) / n,
        "ms_draw": 1000.0 * tm.get("draw_s", 0.0) / n,
        "ms_readback": 1000.0 * tm.get("readback_s", 0.0) / n,
        "ms_grey": 1000.0 * tm.get("grey_s", 0.0) / n,
        "ms_effects": 1000.0 * tm.get("effects_s", 0.0) / n,
        "world_build_s": build_s,
        "first_pair_s": first_s,
        "gl_renderer": info["renderer"],
        "gl_version": info["version"],
        "pyopengl_platform": os.environ.get("PYOPENGL_PLATFORM", ""),
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
    }
