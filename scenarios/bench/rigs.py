"""``offtrack bench rigs``: several camera rigs of one combination rendered by one process's OpenGL context, pipelined.

A spawned render process builds the world once and one camera per rig (:func:`..camera.build.stereo_camera`, an
ideal pinhole rig each); the rigs share the process's one context and the world's one scene
(:mod:`sensor.gl_context`, :func:`sensor.scene.scene_for`), the combination's units drawn in every view. Two phases
over the same poses along the scenario's path:

* **ceiling** — the render process renders every rig of each frame, this process only takes the images: the
  frames per second that rendering alone allows;
* **loop** — as a pipelined camera loop does it: frame ``k + 1`` is rendered while this process computes the masks
  of the other units (:func:`sensor.vehicle_bodies.exclusion_masks`) and runs the visual odometry of every rig on
  frame ``k``.

After a short uncounted loop (:data:`WARM_UP_FRAMES`), the two phases run ``repeats`` times, each repetition a
ceiling then a loop over the same frames (a fresh odometry each time), so that other work on a shared machine
weighs on both phases of a repetition alike; every ratio is the median over the repetitions of that repetition's
ratio, and the per-repetition values are reported beside it.

``loop_to_ceiling`` is the loop's frame rate over the ceiling's (wall time); ``loop_to_cpu_bound`` the loop's frame
rate over what the CPU time per frame allows on two cores; ``cpu_bound_loop_to_ceiling`` the same ratio as the CPU
times alone bound it: rendering's CPU (every thread of the render process) over rendering's plus this process's
(every thread: receiving the images, the masks and the odometry, OpenCV's own threads included), the loop's frame
rate against the ceiling's when rendering alone fills the two cores and the loop adds this process's work to
them. The CPU-time figures survive other work on a shared machine; the wall-time ratio does not.
"""

from __future__ import annotations

import multiprocessing
import os
import platform
import statistics
import time
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from sensor.camera import StereoRig
from vehicle_model.errors import InputError
from vehicle_model.geometry import ChainPose

from ..config import load_scenario
from ..setup.build import build_scenario

DEFAULT_RIGS: tuple[StereoRig, ...] = (
    StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.25, station=-4.0, unit=1),
    StereoRig(unit=2),
)
"""A side rig on the lead trailer (left edge, looking left) and a rear rig on the rear trailer."""


WARM_UP_FRAMES = 3
"""Frames of one loop run before the repetitions and not counted: the odometry's first frames cost more CPU (its
lazily built state) and would weigh on the first repetition alone."""


def _render_main(scenario: str, vehicle: str, rigs: tuple[StereoRig, ...], conn: Connection) -> None:
    """The render process: one world, one camera per rig, every rig of a frame rendered on request."""
    from ..camera.build import stereo_camera, world_for_scenario
    from ..portable_arithmetic import apply as apply_portable_arithmetic

    apply_portable_arithmetic()  # OFFTRACK_PORTABLE_ARITHMETIC=1 (inherited): as the benchmark's own process
    setup = build_scenario(load_scenario(scenario, {"vehicle": vehicle}))
    world = world_for_scenario(setup)
    cameras = [stereo_camera(setup, ideal=True, rig=rig, world=world) for rig in rigs]
    conn.send("ready")
    while True:
        job = conn.recv()
        if job is None:
            return
        frame, pose = job
        cpu0 = time.process_time()
        images = []
        for camera in cameras:
            raw = camera.render(pose, frame)
            images.extend(camera.develop(raw, frame))
        conn.send((images, time.process_time() - cpu0))


def _poses(scenario: str, vehicle: str, frames: int) -> tuple[Any, list[ChainPose]]:
    config = load_scenario(scenario, {"vehicle": vehicle})
    setup = build_scenario(config)
    path = setup.path
    step = config.speed.cornering_kmh / 3.6 / config.rates.camera_hz
    s = path.turn_span[0] + step * np.arange(frames)
    x, y, h = np.interp(s, path.s, path.x), np.interp(s, path.s, path.y), np.interp(s, path.s, path.heading)
    n = len(setup.params.trailers)
    return setup, [ChainPose(float(a), float(b), float(c), (0.0,) * n) for a, b, c in zip(x, y, h, strict=True)]


def _ceiling(here: Connection, poses: list[ChainPose], frames: int) -> tuple[float, float]:
    """Render every rig of frames ``1..frames``, nothing else: (wall time, the render process's CPU time) [s]."""
    render_cpu_s = 0.0
    t0 = time.perf_counter()
    for k in range(1, frames + 1):
        here.send((k, poses[k]))
        render_cpu_s += here.recv()[1]
    return time.perf_counter() - t0, render_cpu_s


def _loop(here: Connection, poses: list[ChainPose], frames: int, params: Any, masks: bool) -> dict[str, float]:
    """Frames ``0..frames`` pipelined: frame ``k + 1`` rendered while this process masks and runs the odometry of
    every rig on frame ``k``. Returns wall, render-process CPU, this process's CPU (all threads and this thread),
    mask and odometry time [s]."""
    from sensor.vehicle_bodies import exclusion_masks
    from sensor.vo import StereoOdometry, VOConfig

    rigs = DEFAULT_RIGS
    odometry = [
        StereoOdometry(VOConfig.from_horizontal_fov(r.width, r.height, r.hfov, r.baseline), seed=0) for r in rigs
    ]
    k_matrices = [r.intrinsics() for r in rigs]
    out = dict.fromkeys(("wall_s", "render_cpu_s", "main_cpu_s", "main_thread_cpu_s", "vo_s", "mask_s"), 0.0)
    here.send((0, poses[0]))
    t0 = time.perf_counter()
    process0, thread0 = time.process_time(), time.thread_time()
    for k in range(frames + 1):
        images, cpu = here.recv()
        out["render_cpu_s"] += cpu
        if k + 1 <= frames:
            here.send((k + 1, poses[k + 1]))  # rendered while this frame's odometry runs
        for i, (rig, vo) in enumerate(zip(rigs, odometry, strict=True)):
            t1 = time.perf_counter()
            cams = (rig.camera_in_world(params, poses[k], "left"), rig.camera_in_world(params, poses[k], "right"))
            sizes = (rig.width, rig.height)
            mask = exclusion_masks(params, poses[k], cams, k_matrices[i], sizes, skip_unit=rig.unit) if masks else None
            t2 = time.perf_counter()
            vo.process(images[2 * i], images[2 * i + 1], mask)
            out["mask_s"] += t2 - t1
            out["vo_s"] += time.perf_counter() - t2
    out["main_cpu_s"] = time.process_time() - process0
    out["main_thread_cpu_s"] = time.thread_time() - thread0
    out["wall_s"] = time.perf_counter() - t0
    return out


def _load() -> float | None:
    try:
        return float(os.getloadavg()[0])
    except OSError:  # no load average on this platform
        return None


def bench_rigs(
    frames: int = 30,
    scenario: str = "roundabout-3",
    vehicle: str = "au-b-double",
    masks: bool = True,
    repeats: int = 3,
) -> dict[str, Any]:
    """Frames per second of the default rigs (:data:`DEFAULT_RIGS`) rendered alone and in the pipelined loop.

    Parameters
    ----------
    frames
        Frames per phase (every rig rendered in each).
    scenario, vehicle
        The catalogue scenario whose path the poses follow, and the combination.
    masks
        Mask the other units out of the odometry.
    repeats
        Repetitions of the two phases (module notes); the ratios are medians over them.

    Returns
    -------
    dict
        ``ceiling_fps`` and ``loop_fps`` (medians), ``loop_to_ceiling`` (median of each repetition's ratio) and
        ``loop_to_ceiling_runs``; ``render_cpu_ms_per_frame`` (in the loop; ``ceiling_render_cpu_ms_per_frame`` in
        the ceiling), ``main_cpu_ms_per_frame`` (this process, every
        thread), ``main_thread_cpu_ms_per_frame``, ``vo_ms_per_frame`` and ``mask_ms_per_frame`` (this process,
        all rigs; medians); ``cpu_bound_fps``, ``loop_to_cpu_bound``, ``cpu_bound_loop_to_ceiling`` (medians)
        and ``cpu_bound_loop_to_ceiling_runs``; ``load_average`` (one minute, before and after), ``rigs``,
        ``width``, ``height``, ``frames``, ``repeats``.
    """
    if repeats < 1:
        raise InputError(f"repeats = {repeats}: the repetitions of the two phases, 1 or more")
    rigs = DEFAULT_RIGS
    setup, poses = _poses(scenario, vehicle, frames + 1)
    ctx = multiprocessing.get_context("spawn")
    here, there = ctx.Pipe(duplex=True)
    proc = ctx.Process(target=_render_main, args=(scenario, vehicle, rigs, there), daemon=True)
    load_before = _load()
    proc.start()
    there.close()
    runs: list[dict[str, float]] = []
    try:
        if here.recv() != "ready":
            raise RuntimeError("the render process did not start")
        here.send((0, poses[0]))
        here.recv()  # the first frame: context, texture upload
        _loop(here, poses, WARM_UP_FRAMES, setup.params, masks)  # the odometry's first frames: not counted
        for _ in range(repeats):
            ceiling_s, ceiling_cpu_s = _ceiling(here, poses, frames)
            run = _loop(here, poses, frames, setup.params, masks)
            run.update(ceiling_s=ceiling_s, ceiling_render_cpu_s=ceiling_cpu_s)
            runs.append(run)
        here.send(None)
    finally:
        proc.join(timeout=10)
        if proc.is_alive():
            proc.terminate()
    cores = min(os.cpu_count() or 1, 2)  # the render process and this one
    return {
        "benchmark": "rigs",
        "scenario": scenario,
        "vehicle": vehicle,
        "rigs": [f"towed unit {r.unit}, psi_c2v {np.degrees(r.psi_c2v):.0f} deg" for r in rigs],
        "width": rigs[0].width,
        "height": rigs[0].height,
        "frames": frames,
        "repeats": repeats,
        "masks": masks,
        **rigs_figures(runs, frames, cores),
        "load_average": [load_before, _load()],
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
    }


def rigs_figures(runs: list[dict[str, float]], frames: int, cores: int) -> dict[str, Any]:
    """The benchmark's figures from its repetitions (:func:`bench_rigs`' returns, module notes).

    Parameters
    ----------
    runs
        Per repetition: ``ceiling_s`` and ``ceiling_render_cpu_s`` (wall and render CPU time of the ceiling's
        ``frames`` frames) and the loop's ``wall_s``,
        ``render_cpu_s``, ``main_cpu_s`` (this process, every thread), ``main_thread_cpu_s``, ``vo_s``, ``mask_s``
        over ``frames + 1`` frames [s].
    frames
        The ceiling's frames (the loop renders one more, its first).
    cores
        The cores the CPU-bound rate assumes.

    Returns
    -------
    dict
        The figures of :func:`bench_rigs` from ``ceiling_fps`` to ``mask_ms_per_frame``: medians over the runs,
        each ratio the median of the runs' own ratios.
    """
    per_frame = frames + 1

    def median(values: list[float]) -> float:
        return float(statistics.median(values))

    ceiling_fps = [frames / r["ceiling_s"] for r in runs]
    loop_fps = [per_frame / r["wall_s"] for r in runs]
    cpu_bound_fps = [cores * per_frame / (r["render_cpu_s"] + r["main_cpu_s"]) for r in runs]
    cpu_ratio = [r["render_cpu_s"] / (r["render_cpu_s"] + r["main_cpu_s"]) for r in runs]
    wall_ratio = [loop / ceiling for loop, ceiling in zip(loop_fps, ceiling_fps, strict=True)]
    return {
        "ceiling_fps": median(ceiling_fps),
        "loop_fps": median(loop_fps),
        "loop_to_ceiling": median(wall_ratio),
        "loop_to_ceiling_runs": wall_ratio,
        "render_cpu_ms_per_frame": median([1e3 * r["render_cpu_s"] / per_frame for r in runs]),
        "ceiling_render_cpu_ms_per_frame": median([1e3 * r["ceiling_render_cpu_s"] / frames for r in runs]),
        "main_cpu_ms_per_frame": median([1e3 * r["main_cpu_s"] / per_frame for r in runs]),
        "main_thread_cpu_ms_per_frame": median([1e3 * r["main_thread_cpu_s"] / per_frame for r in runs]),
        "cpu_bound_fps": median(cpu_bound_fps),
        "loop_to_cpu_bound": median([loop / bound for loop, bound in zip(loop_fps, cpu_bound_fps, strict=True)]),
        "cpu_bound_loop_to_ceiling": median(cpu_ratio),
        "cpu_bound_loop_to_ceiling_runs": cpu_ratio,
        "vo_ms_per_frame": median([1e3 * r["vo_s"] / per_frame for r in runs]),
        "mask_ms_per_frame": median([1e3 * r["mask_s"] / per_frame for r in runs]),
    }
