"""``offtrack bench vo``: the stereo visual odometry alone, one thread, on rendered frames of a scenario."""

from __future__ import annotations

import platform
import time
from typing import Any

import numpy as np

from ..camera.rig import rig_from_config
from ..camera.world import world_for_scenario
from ..config import load_scenario
from ..run.cosim import run_cosimulation
from ..setup.build import build_scenario


def bench_vo(frames: int = 30, scenario: str = "roundabout-3") -> dict[str, Any]:
    """Visual odometry alone, one thread, on rendered 1344×391 frames of a scenario's default world.

    Renders ``frames`` stereo pairs along the scenario's run at its camera rate first, then times
    :meth:`sensor.vo.StereoOdometry.process` on them with OpenCV limited to one thread; ``fps`` is
    one over the median per-frame thread CPU time (robust to other processes on the machine),
    ``fps_wall`` the same in wall-clock time.
    """
    import cv2

    from sensor.renderer import StereoRenderer
    from sensor.vo import StereoOdometry, VOConfig

    config = load_scenario(scenario, {"duration_s": frames / 10.0 + 1.0, "estimators.zero_slip": False})
    setup = build_scenario(config)
    _, cols = run_cosimulation(setup)
    rig = rig_from_config(config)
    renderer = StereoRenderer(world_for_scenario(setup), rig, setup.params, seed=config.seed)
    ticks = np.flatnonzero(cols["camera_frame"] > 0.5)[:frames]
    pairs = [renderer.render(cols["X"][k], cols["Y"][k], cols["psi1"][k], cols["gamma"][k]) for k in ticks]
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        vo = StereoOdometry(VOConfig.from_horizontal_fov(rig.width, rig.height, rig.hfov, rig.baseline), seed=0)
        cpu, wall, inliers, matches, valid = [], [], [], [], []
        for pair in pairs:
            c0, w0 = time.thread_time(), time.perf_counter()
            result = vo.process(pair.left, pair.right)
            cpu.append(time.thread_time() - c0)
            wall.append(time.perf_counter() - w0)
            inliers.append(result.n_inliers)
            matches.append(result.n_matches)
            valid.append(result.valid)
    finally:
        cv2.setNumThreads(threads)
    steady_cpu, steady_wall = np.median(cpu[1:]), np.median(wall[1:])
    return {
        "benchmark": "vo",
        "scenario": scenario,
        "frames": len(pairs),
        "width": rig.width,
        "height": rig.height,
        "fps": 1.0 / steady_cpu,
        "ms_per_frame": 1e3 * steady_cpu,
        "fps_wall": 1.0 / steady_wall,
        "ms_per_frame_wall": 1e3 * steady_wall,
        "mean_matches": float(np.mean(matches[1:])),
        "mean_inliers": float(np.mean(inliers[1:])),
        "valid_fraction": float(np.mean(valid[1:])),
        "opencv_threads": 1,
        "python": platform.python_version(),
    }
