"""``offtrack bench loop``: the rendered closed loop (render + VO + VISO-OT + control), pipelined and serial.

The loop is ``roundabout-3`` with the LST steered by VISO-OT feedback, the camera latency at its default
(one frame period), run by :func:`scenarios.run.drive.simulate` exactly as ``offtrack run`` does.
The figures leave out the start (building the world, the workers' OpenGL contexts): the real-time factor
is simulated seconds per wall second from ``warmup`` simulated seconds to the end, and the per-frame CPU and
waiting times are those of the frames after the first ones (whose one-off costs, the OpenGL contexts, texture
uploads and compiled kernels loading, are reported apart as ``*_startup_*``). The shares say where the
CPU time went: rendering (every thread of the rendering processes), visual odometry and VISO-OT (thread CPU
time), and the control side (everything else the co-simulation process did: model, driver, signals,
estimators, recording, waiting excluded). On a shared machine the wall time varies; the CPU figures much
less so, and ``realtime_factor_cpu_bound`` (simulated seconds per CPU second per core) is what the loop
would reach with the cores to itself.
"""

from __future__ import annotations

import os
import platform
import time
from typing import Any

import numpy as np

from ..camera.workers import DEFAULT_WORKERS
from ..config import load_scenario
from ..run.drive import simulate
from ..setup.build import build_scenario


def _one_run(duration: float, workers: int, warmup: float) -> dict[str, Any]:
    config = load_scenario(
        "roundabout-3",
        {"vehicle": "lst", "estimators": {"viso_ot": True}, "feedback": "viso_ot", "duration_s": duration},
    )
    setup = build_scenario(config)
    marks: list[tuple[float, float, float]] = []

    def progress(sim_time: float, fraction: float) -> None:
        if not marks and sim_time >= warmup:
            marks.append((sim_time, time.perf_counter(), time.process_time()))

    outcome, columns = simulate(setup, progress=progress, camera_workers=workers)  # the PID on viso_ot feedback
    t_end, cpu_end = time.perf_counter(), time.process_time()
    if outcome.status != "completed" or not marks:
        raise RuntimeError(f"the benchmark run did not complete: {outcome.status}: {outcome.message}")
    sim_end = float(columns["time"][-1])
    sim0, wall0, cpu0 = marks[0]
    cam = outcome.camera
    # CPU after the warm-up: this process's directly, the camera's per frame (steady: without the first frames'
    # one-off costs, which fall before the warm-up mark) times the frames taken after it
    taken = np.flatnonzero(columns["camera_frame"] > 0.5)
    frames = int(np.count_nonzero(columns["time"][taken] >= sim0))
    steady = max(cam["frames"] - cam["startup_frames"], 1.0)
    render_cpu = (cam["render_cpu_s"] - cam["startup_render_cpu_s"]) / steady * frames
    vo_cpu = (cam["vo_cpu_s"] - cam["startup_vo_cpu_s"]) / steady * frames
    control_cpu = (cpu_end - cpu0) - vo_cpu - (render_cpu if workers == 0 else 0.0)
    total_cpu = render_cpu + vo_cpu + control_cpu
    frames = max(frames, 1)
    cores = min(os.cpu_count() or 1, workers + 1)
    sim_window = sim_end - sim0
    return {
        "realtime_factor": sim_window / (t_end - wall0),
        "realtime_factor_end_to_end": sim_end / outcome.wall_time_s,
        "realtime_factor_cpu_bound": sim_window / (total_cpu / cores),
        "wall_s": outcome.wall_time_s,
        "wall_to_warmup_s": wall0 - (t_end - outcome.wall_time_s),
        "render_share": render_cpu / total_cpu,
        "vo_share": vo_cpu / total_cpu,
        "control_share": control_cpu / total_cpu,
        "render_cpu_ms_per_frame": 1e3 * render_cpu / frames,
        "vo_cpu_ms_per_frame": 1e3 * vo_cpu / frames,
        "control_cpu_ms_per_frame": 1e3 * control_cpu / frames,
        "wait_ms_per_frame": 1e3 * (cam["wait_s"] - cam["startup_wait_s"]) / steady,
        "render_startup_cpu_s": cam["startup_render_cpu_s"],
        "vo_startup_cpu_s": cam["startup_vo_cpu_s"],
        "wait_startup_s": cam["startup_wait_s"],
        "frames": int(cam["frames"]),
        "latency_ticks": int(cam["latency_ticks"]),
    }


def bench_loop(
    duration: float = 15.0, workers: int = DEFAULT_WORKERS, compare_serial: bool = True, warmup: float = 2.0
) -> dict[str, Any]:
    """Speed of the rendered closed loop, pipelined over ``workers`` render processes (and serial, to compare).

    Returns
    -------
    dict
        ``realtime_factor`` (simulated s per wall s after ``warmup``), ``realtime_factor_end_to_end``,
        ``realtime_factor_cpu_bound``, the CPU ``render_share``, ``vo_share`` and ``control_share``, per-frame
        CPU ms of each and ``wait_ms_per_frame`` (the co-simulation waiting for a render), the first frames'
        one-off ``render_startup_cpu_s``, ``vo_startup_cpu_s`` and ``wait_startup_s``; with
        ``compare_serial`` the same of the serial run prefixed ``serial_`` and ``speedup`` (the ratio of the
        real-time factors, measured in this one call).
    """
    result: dict[str, Any] = {
        "benchmark": "loop",
        "scenario": "roundabout-3",
        "vehicle": "lst",
        "feedback": "viso_ot",
        "simulated_s": duration,
        "workers": workers,
    }
    result.update(_one_run(duration, workers, warmup))
    if compare_serial:
        serial = _one_run(duration, 0, warmup)
        result.update({f"serial_{k}": v for k, v in serial.items()})
        result["speedup"] = result["realtime_factor"] / serial["realtime_factor"]
        result["cpu_speedup_bound"] = result["realtime_factor_cpu_bound"] / serial["realtime_factor_cpu_bound"]
    result.update({"python": platform.python_version(), "cpu_count": os.cpu_count()})
    return result
