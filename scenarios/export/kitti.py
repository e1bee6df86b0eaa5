"""KITTI-odometry-style datasets of a scenario's rendered camera frames (``offtrack render``).

:func:`export_kitti` simulates a scenario and renders its camera frames into a directory laid out
like the KITTI odometry benchmark (Geiger et al. 2012), so any KITTI reader (and libviso2's demo) can
load it::

    image_0/000000.png …   left camera, grey, 1344 × 391 by default
    image_1/000000.png …   right camera
    calib.txt              P0 … P3 (3×4, row-major) and Tr (identity)
    poses.txt              per frame: the 3×4 pose of the left camera in the first left camera's
                           frame, T_cam0←cam_k, OpenCV axes (x right, y down, z forward)
    times.txt              per frame: time since the first frame [s]
    offtrack.json          scenario, rig, world settings (and the lighting, with a sun) and run status
    stereo.mp4             with ``video=True``: the pairs side by side (:mod:`scenarios.export.video`)

The calibration is the *ideal* rig's (rectified, ``P1 = K·[I | −b·e_x]``): a misaligned right camera
(de Saxe & Cebon 2018, §4.4) renders rotated images that the calibration does not know about, as in the field
tests. The frames are those of the scenario's camera as an ideal pinhole rig
(:func:`scenarios.camera.build.stereo_camera`, ``ideal=True``) in its world and under its lighting
(``camera.lighting``: sun, shadows, sky and the auto-exposure, frame by frame in order); lenses, mount flex and the
odometry's rectification are left out. For a combination longer than a tractor–semi-trailer the rig may sit on
any towed unit (:attr:`sensor.camera.StereoRig.unit`) and the other units are drawn in its view at each frame's pose
(:class:`sensor.renderer.StereoRenderer`, ``bodies``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sensor.camera import StereoRig
from vehicle_model.errors import InputError
from vehicle_model.geometry import ChainPose, CombinationPose
from vehicle_model.parameters import VehicleParams

from ..camera.build import lighting_from_config, resolve_scenery_density, rig_from_config, stereo_camera
from ..config import ScenarioConfig, load_scenario
from ..loop.trailer_steer import UnsteeredTrailer, trailer_axles
from ..run.drive import simulate
from ..run.json_output import write_json
from ..run.results import check_output_dir, clear_run_dir
from ..setup.build import build_scenario
from .video import StereoVideoWriter

RenderProgress = Callable[[int, int], None]
"""``(frames done, frames in total)``."""


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


def rig_summary(rig: StereoRig, params: VehicleParams | None = None) -> dict[str, Any]:
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


def combination_poses(
    params: VehicleParams, cols: dict[str, np.ndarray], frames: np.ndarray
) -> CombinationPose | ChainPose:
    """The combination's poses at the rows ``frames`` of a run's columns: a :class:`CombinationPose` of arrays for a
    tractor–semi-trailer, a :class:`ChainPose` (every coupling's articulation: ``gamma``, ``gamma2``, …) for a
    longer combination."""
    x, y, psi1, gamma = (np.asarray(cols[k])[frames] for k in ("X", "Y", "psi1", "gamma"))
    if params.n_units <= 2:
        return CombinationPose(x, y, psi1, gamma)
    further = tuple(np.asarray(cols[f"gamma{j}"])[frames] for j in range(2, params.n_units))
    return ChainPose(x, y, psi1, (gamma, *further))


def _enough_for(config: ScenarioConfig, frames: int) -> ScenarioConfig:
    """``config`` simulated only as long as its first ``frames`` camera frames need.

    Frame ``k`` is taken at ``k / camera_hz``; the run stops two control periods after the last one (or
    earlier, if the scenario's own duration is shorter).
    """
    needed = (frames - 1) / config.rates.camera_hz + 2.0 / config.rates.control_hz
    if config.duration_s is not None and config.duration_s <= needed:
        return config
    return config.model_copy(update={"duration_s": needed})


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
    antialias: bool | None = None,
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
        defaults are the paper's §3.1: rear-facing at the trailer's rear, 0.5 m baseline).
    scenery_density : float, optional
        Fraction of roadside objects, in [0, 1] (default: the scenario's ``camera.scenery_density``).
    max_frames : int, optional
        Render at most this many camera frames (from the start); the scenario is simulated only as long
        as they need.
    progress : callable, optional
        ``progress(done, total)`` after each frame.
    video : bool
        Also write ``stereo.mp4`` (side by side, at the camera rate).
    overwrite : bool
        Replace an earlier export in ``out_dir`` (``--force``; otherwise refused): everything offtrack
        wrote there is removed first, and a directory that also holds other files is refused
        (:func:`~scenarios.run.results.clear_run_dir`).
    antialias : bool, optional
        Render with 4× multisampling (slower: benchmarks/README.md, "Rendering"); default: ``camera.antialias``.

    Returns
    -------
    dict
        ``frames``, ``status`` (of the simulation), ``out_dir``, ``render_s``, ``simulate_s``,
        ``ms_per_pair``, and ``files``: where each part went (``left``, ``right``, ``calib``, ``poses``,
        ``times``, ``metadata`` and with ``video`` ``video``), as text paths; :func:`render_summary` says it in a
        sentence.

    Raises
    ------
    InputError
        ``out_dir`` is a file, under a file or not writable, or already holds a dataset and not
        ``overwrite`` — all before anything is simulated.
    """
    if isinstance(config, str):
        config = load_scenario(config)
    if max_frames is not None and max_frames < 1:
        raise InputError(f"max_frames = {max_frames} must be at least 1")
    out = Path(out_dir)
    check_output_dir(out)
    markers = [out / "poses.txt", out / "image_0", out / "image_1", out / "calib.txt"]
    if any(m.exists() for m in markers):
        if not overwrite:
            raise InputError(f"--out {out} already holds a dataset; choose another --out or pass --force")
        clear_run_dir(out)
    rig = rig if rig is not None else rig_from_config(config)
    scenery_density = resolve_scenery_density(config, scenery_density)
    if max_frames is not None:
        config = _enough_for(config, max_frames)
    t0 = time.perf_counter()
    setup = build_scenario(config)
    outcome, cols = simulate(setup, UnsteeredTrailer(trailer_axles(setup)))  # the trailer's axles straight
    simulate_s = time.perf_counter() - t0
    frames = np.flatnonzero(np.asarray(cols["camera_frame"]) > 0.5)
    if max_frames is not None:
        frames = frames[:max_frames]
    if len(frames) == 0:
        raise InputError("the simulation produced no camera frame; check rates.camera_hz and duration_s")

    # the run's world, rig and lighting through an ideal pinhole camera (no lens, flex or rectification)
    camera = stereo_camera(
        setup,
        ideal=True,
        rig=rig,
        lighting=lighting_from_config(config),
        scenery_density=scenery_density,
        antialias=antialias,
    )
    world = camera.world
    for sub in ("image_0", "image_1"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    import cv2

    poses = combination_poses(setup.params, cols, frames)
    longer = isinstance(poses, ChainPose)  # the other units drawn in the view (a tractor-semi-trailer's as it was)
    left_poses = rig.camera_in_world(setup.params, poses, "left")
    right_poses = rig.camera_in_world(setup.params, poses, "right")
    writer = StereoVideoWriter(out / "stereo.mp4", config.rates.camera_hz) if video else None
    t1 = time.perf_counter()
    try:
        for k in range(len(frames)):
            if longer:
                raw = camera.render(ChainPose(*(np.asarray(v)[k] for v in poses[:3]), tuple(a[k] for a in poses[3])), k)
            else:
                raw = camera.render_poses(left_poses[k], right_poses[k], k)
            left, right = camera.develop(raw, k)  # in order
            cv2.imwrite(str(out / "image_0" / f"{k:06d}.png"), left)
            cv2.imwrite(str(out / "image_1" / f"{k:06d}.png"), right)
            if writer is not None:
                writer.append(left, right)
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
        "rig": rig_summary(rig, setup.params),
        "vehicle": setup.params.name,
    }
    if camera.developer.lighting is not None:  # a sun: its settings (flat lighting adds nothing)
        meta["lighting"] = camera.developer.lighting.model_dump(mode="json")
    write_json(out / "offtrack.json", meta)
    files = {
        "left": out / "image_0",
        "right": out / "image_1",
        "calib": out / "calib.txt",
        "poses": out / "poses.txt",
        "times": out / "times.txt",
        "metadata": out / "offtrack.json",
    }
    if video:
        files["video"] = out / "stereo.mp4"
    return {
        "out_dir": str(out),
        "frames": len(frames),
        "status": outcome.status,
        "simulate_s": simulate_s,
        "render_s": render_s,
        "ms_per_pair": 1000.0 * render_s / len(frames),
        "files": {k: str(v) for k, v in files.items()},
    }


def render_summary(summary: dict[str, Any]) -> str:
    """What :func:`export_kitti` did, in one sentence naming where every file went.

    Parameters
    ----------
    summary
        The dictionary :func:`export_kitti` returned.

    Returns
    -------
    str
        The frames, the simulation's status, the output directory and every file or folder in it, e.g.
        ``3 stereo pairs (simulation completed) in runs/k: left images in image_0/, right images in image_1/,
        …; <render time> ms per pair``.
    """
    out = Path(summary["out_dir"])

    def where(key: str) -> str:
        path = Path(summary["files"][key])
        name = str(path.relative_to(out)) if path.is_relative_to(out) else str(path)
        return name + "/" if key in ("left", "right") else name

    parts = [
        f"left images in {where('left')}",
        f"right images in {where('right')}",
        f"the calibration in {where('calib')}",
        f"the left camera's poses in {where('poses')}",
        f"the frame times in {where('times')}",
        f"the scenario and rig in {where('metadata')}",
    ]
    if "video" in summary["files"]:
        parts.append(f"the side-by-side video in {where('video')}")
    frames = int(summary["frames"])
    return (
        f"{frames} stereo pair{'s' if frames != 1 else ''} (simulation {summary['status']}) in {out}: "
        + ", ".join(parts[:-1])
        + f" and {parts[-1]}; {summary['ms_per_pair']:.1f} ms per pair"
    )
