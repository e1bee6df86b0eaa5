"""``offtrack bench model``: the vehicle model's speed in the closed loop and its compiled integrator alone."""

from __future__ import annotations

import math
import os
import platform
import time
from typing import Any

import numpy as np

from controller.speed import SpeedController
from scenarios.config import ConfigError, load_vehicle_file
from vehicle_model.combination import CombinationSpec
from vehicle_model.dynamics import VehicleModel
from vehicle_model.parameters import VehicleParams
from vehicle_model.period import context_views, load_period, new_context
from vehicle_model.presets import vehicle_preset
from vehicle_model.simulator import Controls, Simulator, initial_state


def _vehicle_params(vehicle: str) -> VehicleParams:
    """A preset by name, or the combination in a ``.yaml`` file (docs/vehicles.md): any combination the model
    simulates, longer ones included."""
    if not vehicle.endswith((".yaml", ".yml")):
        return vehicle_preset(vehicle)
    try:
        return CombinationSpec.model_validate(load_vehicle_file(vehicle)).params()
    except ValueError as exc:  # pydantic's ValidationError is one
        raise ConfigError(f"vehicle file {vehicle}: {str(exc).splitlines()[-1].strip()}") from None


def bench_model(
    duration: float = 60.0, dt: float = 0.002, substeps: int = 10, vehicle: str = "reference"
) -> dict[str, Any]:
    """Model-only speed on a turning manoeuvre.

    Drives ``duration`` seconds of a slalom-into-circle manoeuvre at 15 km/h (sinusoidal front
    steer of ±0.25 rad, period 8 s) with the PI speed controller in the loop, stepping at the
    control period ``dt·substeps`` through :meth:`Simulator.step_inputs`, the co-simulation's path.
    Reports the closed-loop real-time factor (everything the co-simulation pays for the model:
    surface look-up, controller, checks) and the integrator alone, in calls of 1 s of RK4 steps with
    the inputs held. After every second of closed loop the integrator runs 1 s from the loop's state
    with the loop's inputs (the same motion: a step costs more while turning than in exactly straight
    running, where the lateral states are zero), two ways: the compiled control-period function of
    :mod:`vehicle_model.period` (a C loop over the compiled RK4 step; absent without a C compiler)
    and casadi's ``mapaccum`` integrator (:meth:`VehicleModel.integrator`); and from straight running at
    15 km/h with zero inputs (``*_straight``, the reference of the older figures in ``benchmarks/README.md``).
    The segments alternate second by second, so that they see the same (shared) machine; ``*_cpu`` figures
    use this thread's CPU time. ``realtime_factor_integrator`` is the faster of the two integrators on the
    loop's states, ``loop_to_integrator`` the ratio of the loop's real-time factor to it (target at least
    0.75, docs/design.md §11), and ``us_python_per_control_step_cpu`` what a control step costs beyond its
    RK4 steps at that speed.
    """
    params = _vehicle_params(vehicle)
    t0 = time.perf_counter()
    model = VehicleModel(params)
    build_s = time.perf_counter() - t0
    sim = Simulator(params, dt=dt, substeps=substeps, model=model)
    speed = 15.0 / 3.6
    sim.reset(initial_state(sim.layout, speed=speed))
    sc = SpeedController(mass=sum(unit.mass for unit in params.units))
    period = sim.control_period
    per_call = round(1.0 / dt)  # the integrator alone: calls of 1 s of RK4 steps, inputs held
    integ = model.integrator(per_call)
    n_x, n_u = sim.layout.n_states, sim.layout.n_inputs
    c_integ = load_period(model.library) if model.library is not None else None
    # contexts of the compiled integrator: no limits (integration and the finiteness check only)
    ctx, ctx_straight = new_context(n_x, n_u, per_call, dt, [], 0), new_context(n_x, n_u, per_call, dt, [], 0)
    c_x, c_u, _, _ = context_views(ctx, n_x, n_u, per_call)
    s_x, s_u, _, _ = context_views(ctx_straight, n_x, n_u, per_call)
    s_x[:] = initial_state(sim.layout, speed=speed).to_vector()
    sim.fill_inputs(Controls([0.0], 0.0))  # the surface values, as the closed loop sees them
    s_u[:] = sim.input_vector
    c_address, s_address = ctx.ctypes.data, ctx_straight.ctypes.data
    chunk_starts, tick_inputs = _record_inputs(sim, sc, speed, duration)
    r_ctx = new_context(n_x, n_u, substeps, dt, [], 0)  # the replay: the loop's ticks, C calls only
    r_x, r_u, _, _ = context_views(r_ctx, n_x, n_u, substeps)
    r_address, drive_index = r_ctx.ctypes.data, sim.layout.drive_index
    r_u[:] = s_u
    chunk = max(1, round(1.0 / period))  # control steps per 1 s of closed loop
    n_chunks = max(1, round(duration))
    wall = {"loop": 0.0, "c": 0.0, "casadi": 0.0, "c_straight": 0.0, "replay": 0.0}
    cpu = dict(wall)
    k = 0
    step, sin, two_pi = sim.step_inputs, math.sin, 2.0 * math.pi
    # Interleaved, 1 s of each in turn, so that all see the same machine (it is shared and its speed
    # varies); wall time and this thread's CPU time.
    for i_chunk in range(n_chunks):
        w0, c0 = time.perf_counter(), time.thread_time()
        for _ in range(chunk):
            step([0.25 * sin(two_pi * k * period / 8.0)], sc(speed, sim.speed, period))
            k += 1
        w1, c1 = time.perf_counter(), time.thread_time()
        x, u = sim.state_vector, sim.input_vector
        c_x[:], c_u[:] = x, u
        w2, c2 = time.perf_counter(), time.thread_time()
        integ(x, u, dt)
        w3, c3 = time.perf_counter(), time.thread_time()
        if c_integ is not None and c_integ(c_address) != 0:
            raise RuntimeError("the compiled integrator gave a non-finite state")
        w4, c4 = time.perf_counter(), time.thread_time()
        if c_integ is not None and c_integ(s_address) != 0:
            raise RuntimeError("the compiled integrator gave a non-finite state")
        w5, c5 = time.perf_counter(), time.thread_time()
        if c_integ is not None:
            r_x[:] = chunk_starts[i_chunk]
            w5, c5 = time.perf_counter(), time.thread_time()
            for steer, force in tick_inputs[i_chunk * chunk : (i_chunk + 1) * chunk]:
                r_u[0], r_u[drive_index] = steer, force
                c_integ(r_address)
        w6, c6 = time.perf_counter(), time.thread_time()
        segments = (("loop", w1 - w0, c1 - c0), ("casadi", w3 - w2, c3 - c2), ("c", w4 - w3, c4 - c3))
        for key, dw, dc in (*segments, ("c_straight", w5 - w4, c5 - c4), ("replay", w6 - w5, c6 - c5)):
            wall[key] += dw
            cpu[key] += dc
    n_steps, n_calls = k, n_chunks
    simulated_loop = n_steps * period
    simulated_integ = n_calls * per_call * dt
    fastest = "c" if c_integ is not None and cpu["c"] < cpu["casadi"] else "casadi"
    loop_s, loop_cpu, integ_s, integ_cpu = wall["loop"], cpu["loop"], wall[fastest], cpu[fastest]
    # Straight running: the reference of the older figures in benchmarks/README.md.
    rf_straight = simulated_integ / cpu["c_straight"] if c_integ is not None else None
    return {
        "benchmark": "model",
        "vehicle": vehicle,
        "units": params.n_units,
        "simulated_s": simulated_loop,
        "step_s": dt,
        "control_period_s": period,
        "wall_s": loop_s,
        "realtime_factor": simulated_loop / loop_s,
        "realtime_factor_integrator": simulated_integ / integ_s,
        "realtime_factor_cpu": simulated_loop / loop_cpu,
        "realtime_factor_integrator_cpu": simulated_integ / integ_cpu,
        "integrator": "compiled period function" if fastest == "c" else "casadi mapaccum",
        "realtime_factor_integrator_c_cpu": simulated_integ / cpu["c"] if c_integ is not None else None,
        "realtime_factor_integrator_casadi_cpu": simulated_integ / cpu["casadi"],
        "realtime_factor_integrator_straight_cpu": rf_straight,
        "loop_to_integrator_straight_cpu": simulated_loop / loop_cpu / rf_straight if rf_straight else None,
        "us_replay_per_control_step_cpu": cpu["replay"] / n_steps * 1e6 if c_integ is not None else None,
        "loop_to_replay_cpu": cpu["replay"] / loop_cpu if c_integ is not None else None,
        "loop_to_integrator": (simulated_loop / loop_s) / (simulated_integ / integ_s),
        "loop_to_integrator_cpu": (simulated_loop / loop_cpu) / (simulated_integ / integ_cpu),
        "us_per_rk4_step": integ_s / (n_calls * per_call) * 1e6,
        "us_per_rk4_step_cpu": integ_cpu / (n_calls * per_call) * 1e6,
        "us_per_control_step": loop_s / n_steps * 1e6,
        "us_per_control_step_cpu": loop_cpu / n_steps * 1e6,
        "us_python_per_control_step_cpu": (loop_cpu / n_steps - integ_cpu / (n_calls * per_call) * substeps) * 1e6,
        "compiled": model.compiled,
        "model_build_s": build_s,
        "final_state_finite": bool(np.all(np.isfinite(sim.state_vector))),
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
    }


def _record_inputs(
    sim: Simulator, sc: SpeedController, speed: float, duration: float
) -> tuple[list[np.ndarray], list[tuple[float, float]]]:
    """An untimed pass of the benchmark's closed loop (on a copy of ``sim``'s set-up; ``sc`` is left
    unchanged): the state at the start of every 1 s chunk and every tick's (steer, drive force)."""
    twin = Simulator(sim.params, sim.surface, dt=sim.dt, substeps=sim.substeps, model=sim.model)
    twin.reset(sim.state)
    pi = SpeedController(sc.mass, sc.kp, sc.ki, sc.max_force)
    period = twin.control_period
    chunk = max(1, round(1.0 / period))
    starts, inputs = [], []
    for k in range(chunk * max(1, round(duration))):
        if k % chunk == 0:
            starts.append(twin.state_vector)
        steer, force = 0.25 * math.sin(2.0 * math.pi * k * period / 8.0), pi(speed, twin.speed, period)
        twin.step_inputs([steer], force)
        inputs.append((steer, force))
    return starts, inputs
