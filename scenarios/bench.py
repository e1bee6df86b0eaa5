"""Benchmarks: speed figures printed as machine-readable JSON (run them with ``offtrack bench``)."""

from __future__ import annotations

import math
import os
import platform
import time
from typing import Any

import numpy as np

from controller.speed import SpeedController
from vehicle_model.dynamics import VehicleModel
from vehicle_model.presets import vehicle_preset
from vehicle_model.simulator import Controls, Simulator, initial_state


def bench_model(
    duration: float = 60.0, dt: float = 0.002, substeps: int = 10, vehicle: str = "reference"
) -> dict[str, Any]:
    """Model-only speed on a turning manoeuvre.

    Drives ``duration`` seconds of a slalom-into-circle manoeuvre at 15 km/h (sinusoidal front
    steer of ±0.25 rad, period 8 s) with the PI speed controller in the loop, stepping at the
    control period ``dt·substeps``. Reports the closed-loop real-time factor (everything the
    co-simulation pays for the model: surface look-up, controller, checks), the integrator alone
    (one compiled call of ``duration/dt`` RK4 steps), and the cost of one RK4 step.
    """
    params = vehicle_preset(vehicle)
    t0 = time.perf_counter()
    model = VehicleModel(params)
    build_s = time.perf_counter() - t0
    sim = Simulator(params, dt=dt, substeps=substeps, model=model)
    speed = 15.0 / 3.6
    sim.reset(initial_state(sim.layout, speed=speed))
    sc = SpeedController(mass=params.tractor.mass + params.trailer.mass)
    n_steps = round(duration / sim.control_period)
    period = sim.control_period
    t0 = time.perf_counter()
    for k in range(n_steps):
        steer = 0.25 * math.sin(2.0 * math.pi * k * period / 8.0)
        sim.step(Controls([steer], sc(speed, sim.speed, period)))
    loop_s = time.perf_counter() - t0

    # Integrator alone: the same number of RK4 steps in calls of 1 s each, inputs held.
    per_call = round(1.0 / dt)
    integ = model.integrator(per_call)
    x = initial_state(sim.layout, speed=speed).to_vector()
    u = sim.input_vector
    n_calls = round(duration / (per_call * dt))
    t0 = time.perf_counter()
    for _ in range(n_calls):
        x = integ(x, u, dt)[0]
    integ_s = time.perf_counter() - t0
    return {
        "benchmark": "model",
        "vehicle": vehicle,
        "simulated_s": n_steps * period,
        "step_s": dt,
        "control_period_s": period,
        "wall_s": loop_s,
        "realtime_factor": n_steps * period / loop_s,
        "realtime_factor_integrator": n_calls * per_call * dt / integ_s,
        "us_per_rk4_step": integ_s / (n_calls * per_call) * 1e6,
        "us_per_control_step": loop_s / n_steps * 1e6,
        "compiled": model.compiled,
        "model_build_s": build_s,
        "final_state_finite": bool(np.all(np.isfinite(sim.state_vector))),
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
    }


def bench_vo(frames: int = 30, scenario: str = "roundabout-3") -> dict[str, Any]:
    """Visual odometry alone, one thread, on rendered 1344×391 frames of a scenario's default world.

    Renders ``frames`` stereo pairs along the scenario's run at its camera rate first, then times
    :meth:`sensor.vo.StereoOdometry.process` on them with OpenCV limited to one thread; ``fps`` is
    one over the median per-frame thread CPU time (robust to other processes on the machine),
    ``fps_wall`` the same in wall-clock time.
    """
    import cv2

    from scenarios.build import build_scenario
    from scenarios.config import load_scenario
    from scenarios.cosim import run_cosimulation
    from scenarios.rendering import rig_from_config, world_for_scenario
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
