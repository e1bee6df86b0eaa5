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

``loop_to_ceiling`` is the loop's frame rate over the ceiling's; ``loop_to_cpu_bound`` the loop's frame rate over what
the CPU time per frame (rendering, every thread of the render process; masks and odometry, this thread) allows on
two cores; ``cpu_bound_loop_to_ceiling`` the same ratio as the CPU times alone bound it (rendering alone against
rendering with the masks and odometry, on the same cores) — the figures that survive other work on a shared
machine.
"""

from __future__ import annotations

import multiprocessing
import os
import platform
import time
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from sensor.camera import StereoRig
from vehicle_model.geometry import ChainPose

from ..config import load_scenario
from ..setup.build import build_scenario

DEFAULT_RIGS: tuple[StereoRig, ...] = (
    StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.25, station=-4.0, unit=1),
    StereoRig(unit=2),
)
"""A side rig on the lead trailer (left edge, looking left) and a rear rig on the rear trailer."""


def _render_main(scenario: str, vehicle: str, rigs: tuple[StereoRig, ...], conn: Connection) -> None:
    """The render process: one world, one camera per rig, every rig of a frame rendered on request."""
    from ..camera.build import stereo_camera, world_for_scenario

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


def bench_rigs(
    frames: int = 30, scenario: str = "roundabout-3", vehicle: str = "au-b-double", masks: bool = True
) -> dict[str, Any]:
    """Frames per second of the default rigs (:data:`DEFAULT_RIGS`) rendered alone and in the pipelined loop.

    Returns
    -------
    dict
        ``ceiling_fps`` (every rig of a frame rendered, nothing else), ``loop_fps`` (rendering pipelined with the
        masks and the odometry of every rig), ``loop_to_ceiling``, ``vo_ms_per_frame`` and ``mask_ms_per_frame``
        (this process, all rigs), ``render_cpu_ms_per_frame`` and ``main_cpu_ms_per_frame`` (CPU time),
        ``cpu_bound_fps``, ``loop_to_cpu_bound`` and ``cpu_bound_loop_to_ceiling``, ``rigs``, ``width``, ``height``,
        ``frames``.
    """
    from sensor.vehicle_bodies import exclusion_masks
    from sensor.vo import StereoOdometry, VOConfig

    rigs = DEFAULT_RIGS
    setup, poses = _poses(scenario, vehicle, frames + 1)
    params = setup.params
    ctx = multiprocessing.get_context("spawn")
    here, there = ctx.Pipe(duplex=True)
    proc = ctx.Process(target=_render_main, args=(scenario, vehicle, rigs, there), daemon=True)
    proc.start()
    there.close()
    try:
        if here.recv() != "ready":
            raise RuntimeError("the render process did not start")
        here.send((0, poses[0]))
        here.recv()  # the first frame: context, texture upload
        t0 = time.perf_counter()
        for k in range(1, frames + 1):
            here.send((k, poses[k]))
            here.recv()
        ceiling_s = time.perf_counter() - t0
        render_cpu_s = 0.0
        odometry = [
            StereoOdometry(VOConfig.from_horizontal_fov(r.width, r.height, r.hfov, r.baseline), seed=0) for r in rigs
        ]
        k_matrices = [r.intrinsics() for r in rigs]
        vo_s = mask_s = main_cpu_s = 0.0
        here.send((0, poses[0]))
        t0 = time.perf_counter()
        for k in range(frames + 1):
            images, cpu = here.recv()
            render_cpu_s += cpu
            cpu0 = time.thread_time()
            if k + 1 <= frames:
                here.send((k + 1, poses[k + 1]))  # rendered while this frame's odometry runs
            for i, (rig, vo) in enumerate(zip(rigs, odometry, strict=True)):
                t1 = time.perf_counter()
                cams = (rig.camera_in_world(params, poses[k], "left"), rig.camera_in_world(params, poses[k], "right"))
                sizes = (rig.width, rig.height)
                mask = (
                    exclusion_masks(params, poses[k], cams, k_matrices[i], sizes, skip_unit=rig.unit) if masks else None
                )
                t2 = time.perf_counter()
                vo.process(images[2 * i], images[2 * i + 1], mask)
                mask_s += t2 - t1
                vo_s += time.perf_counter() - t2
            main_cpu_s += time.thread_time() - cpu0
        loop_s = time.perf_counter() - t0
        here.send(None)
    finally:
        proc.join(timeout=10)
        if proc.is_alive():
            proc.terminate()
    ceiling_fps = frames / ceiling_s
    loop_fps = (frames + 1) / loop_s
    cpu_per_frame = (render_cpu_s + main_cpu_s) / (frames + 1)
    cores = min(os.cpu_count() or 1, 2)  # the render process and this one
    return {
        "benchmark": "rigs",
        "scenario": scenario,
        "vehicle": vehicle,
        "rigs": [f"unit {r.unit}, psi_c2v {np.degrees(r.psi_c2v):.0f} deg" for r in rigs],
        "width": rigs[0].width,
        "height": rigs[0].height,
        "frames": frames,
        "masks": masks,
        "ceiling_fps": ceiling_fps,
        "loop_fps": loop_fps,
        "loop_to_ceiling": loop_fps / ceiling_fps,
        "render_cpu_ms_per_frame": 1e3 * render_cpu_s / (frames + 1),
        "main_cpu_ms_per_frame": 1e3 * main_cpu_s / (frames + 1),
        "cpu_bound_fps": cores / cpu_per_frame,
        "loop_to_cpu_bound": loop_fps / (cores / cpu_per_frame),
        "cpu_bound_loop_to_ceiling": render_cpu_s / (render_cpu_s + main_cpu_s),
        "vo_ms_per_frame": 1e3 * vo_s / (frames + 1),
        "mask_ms_per_frame": 1e3 * mask_s / (frames + 1),
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
    }
