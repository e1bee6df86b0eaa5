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
