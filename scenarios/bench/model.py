"""``offtrack bench model``: the vehicle model's speed in the closed loop and its compiled integrator alone."""

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
    (compiled calls of 1 s of RK4 steps), and the cost of one RK4 step. The two alternate second by
    second, so that they see the same (shared) machine; ``*_cpu`` figures use this thread's CPU time,
    ``loop_to_integrator`` is the ratio of the real-time factors (issue 16: at least 0.75), and
    ``us_python_per_control_step_cpu`` what a control step costs beyond its RK4 steps.
    """
    params = vehicle_preset(vehicle)
    t0 = time.perf_counter()
    model = VehicleModel(params)
    build_s = time.perf_counter() - t0
    sim = Simulator(params, dt=dt, substeps=substeps, model=model)
    speed = 15.0 / 3.6
    sim.reset(initial_state(sim.layout, speed=speed))
    sc = SpeedController(mass=params.tractor.mass + params.trailer.mass)
    period = sim.control_period
    per_call = round(1.0 / dt)  # the integrator alone: calls of 1 s of RK4 steps, inputs held
    integ = model.integrator(per_call)
    x = initial_state(sim.layout, speed=speed).to_vector()
    sim.fill_inputs(Controls([0.0], 0.0))  # the surface values, as the closed loop sees them
    u = sim.input_vector
    chunk = max(1, round(1.0 / period))  # control steps per 1 s of closed loop
    n_chunks = max(1, round(duration))
    loop_s = loop_cpu = integ_s = integ_cpu = 0.0
    k = 0
    # Interleaved, 1 s of each in turn, so that both see the same machine (it is shared and its speed
    # varies); wall time and this thread's CPU time.
    for _ in range(n_chunks):
        w0, c0 = time.perf_counter(), time.thread_time()
        for _ in range(chunk):
            steer = 0.25 * math.sin(2.0 * math.pi * k * period / 8.0)
            sim.step(Controls([steer], sc(speed, sim.speed, period)))
            k += 1
        w1, c1 = time.perf_counter(), time.thread_time()
        x = integ(x, u, dt)[0]
        w2, c2 = time.perf_counter(), time.thread_time()
        loop_s, loop_cpu = loop_s + (w1 - w0), loop_cpu + (c1 - c0)
        integ_s, integ_cpu = integ_s + (w2 - w1), integ_cpu + (c2 - c1)
    n_steps, n_calls = k, n_chunks
    simulated_integ = n_calls * per_call * dt
    return {
        "benchmark": "model",
        "vehicle": vehicle,
        "simulated_s": n_steps * period,
        "step_s": dt,
        "control_period_s": period,
        "wall_s": loop_s,
        "realtime_factor": n_steps * period / loop_s,
        "realtime_factor_integrator": simulated_integ / integ_s,
        "realtime_factor_cpu": n_steps * period / loop_cpu,
        "realtime_factor_integrator_cpu": simulated_integ / integ_cpu,
        "loop_to_integrator": (n_steps * period / loop_s) / (simulated_integ / integ_s),
        "loop_to_integrator_cpu": (n_steps * period / loop_cpu) / (simulated_integ / integ_cpu),
        "us_per_rk4_step": integ_s / (n_calls * per_call) * 1e6,
        "us_per_control_step": loop_s / n_steps * 1e6,
        "us_python_per_control_step_cpu": (loop_cpu / n_steps - integ_cpu / (n_calls * per_call) * substeps) * 1e6,
        "compiled": model.compiled,
        "model_build_s": build_s,
        "final_state_finite": bool(np.all(np.isfinite(sim.state_vector))),
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
    }
