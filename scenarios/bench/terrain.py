"""``offtrack bench terrain``: what a control period's surface look-up costs the vehicle model on a rough terrain,
each body's slope taken from its supports (``terrain.body_slope: supports``, the default) against its axles.

The rough wet-clay yard of the off-highway study (``gravel-yard``, :data:`scenarios.studies.off_highway.ROUGHNESS`
``rough``: undulations, ruts, potholes) with a combination; states along the yard's path (every metre, seeded
lateral offsets, heading errors and articulation angles). A tick is what the co-simulation asks of the model at a
new state: the tractor's accelerometer gravity (:meth:`~vehicle_model.simulator.Simulator.sensed_gravity`, through
its contact plane with ``supports``), then the next period's surface inputs
(:meth:`~vehicle_model.simulator.Simulator.surface_inputs`: μ and each body's slope). The two forms alternate in
chunks of ticks over the same states, so that they see the same (shared) machine; this thread's CPU time.
"""

from __future__ import annotations

import platform
import time
from typing import Any

import numpy as np

from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from scenarios.studies.off_highway import ROUGHNESS
from vehicle_model.simulator import Simulator, VehicleState

FORMS = ("supports", "axles")
"""The ``terrain.body_slope`` forms timed side by side."""


def _states(sim: Simulator, n: int, seed: int) -> list[VehicleState]:
    """``n`` states along the terrain's path, a metre apart, with seeded offsets (±0.5 m), heading errors (±0.1 rad)
    and articulation angles (±0.3 rad)."""
    terrain = sim.surface.slope.terrain
    points, heading, station = terrain.points, terrain.heading, terrain.station
    rng = np.random.default_rng(seed)
    index = np.searchsorted(station, station[0] + np.arange(n) % max(1.0, np.floor(station[-1] - station[0])))
    states = []
    for i in np.minimum(index, len(points) - 1):
        x = sim.state_vector.copy()
        normal = np.array([-np.sin(heading[i]), np.cos(heading[i])])
        x[0], x[1] = points[i] + rng.uniform(-0.5, 0.5) * normal
        x[2] = heading[i] + rng.uniform(-0.1, 0.1)
        x[6] = rng.uniform(-0.3, 0.3)
        trailing = np.arange(len(x))[sim.layout.trailing_slice][0::2]
        x[trailing] = rng.uniform(-0.3, 0.3, len(trailing))
        states.append(VehicleState.from_vector(x, 0.0, len(sim.layout.axles)))
    return states


def bench_terrain(vehicle: str = "lst", ticks: int = 1000, rounds: int = 3, seed: int = 0) -> dict[str, Any]:
    """Milliseconds of thread CPU a tick with ``supports`` and with ``axles`` (module docstring), and their ratio.

    Parameters
    ----------
    vehicle
        The combination (a catalogue name).
    ticks
        States a round, each a new tick.
    rounds
        Rounds over the states; in each the forms alternate in chunks of 50 ticks. The figures are the rounds'
        median (per-round values alongside).
    seed
        Seed of the states' offsets and angles.

    Returns
    -------
    dict
        One JSON object: ``ms_per_tick_supports_cpu``, ``ms_per_tick_axles_cpu``, ``supports_to_axles_cpu`` (medians)
        and each round's values.
    """
    if ticks < 50 or rounds < 1:
        raise ValueError(f"ticks = {ticks} must be at least 50 and rounds = {rounds} at least 1")
    overrides = {"vehicle": vehicle, "surface.preset": "wet_clay", **dict(ROUGHNESS["rough"])}
    sims = {}
    for form in FORMS:
        setup = build_scenario(load_scenario("gravel-yard", {**overrides, "terrain.body_slope": form}))
        sims[form] = Simulator(setup.params, setup.surface)
    states = _states(sims["supports"], ticks, seed)
    cpu = {form: [0.0] * rounds for form in FORMS}
    chunk = 50
    for r in range(rounds):
        for start in range(0, ticks, chunk):
            for form in FORMS if (start // chunk + r) % 2 == 0 else FORMS[::-1]:
                sim = sims[form]
                for state in states[start : start + chunk]:
                    sim.reset(state)  # a new state: nothing kept from the last
                    x = sim.state_vector
                    t0 = time.thread_time()
                    sim.sensed_gravity(0, state.psi1)
                    sim.surface_inputs(x)
                    cpu[form][r] += time.thread_time() - t0
    per_tick = {form: [c / ticks * 1e3 for c in cpu[form]] for form in FORMS}
    ratios = [s / a for s, a in zip(per_tick["supports"], per_tick["axles"], strict=True)]
    return {
        "benchmark": "terrain",
        "vehicle": vehicle,
        "units": sims["supports"].params.n_units,
        "scenario": "gravel-yard, wet_clay, rough",
        "ticks": ticks,
        "rounds": rounds,
        "ms_per_tick_supports_cpu": float(np.median(per_tick["supports"])),
        "ms_per_tick_axles_cpu": float(np.median(per_tick["axles"])),
        "supports_to_axles_cpu": float(np.median(ratios)),
        "ms_per_tick_supports_cpu_rounds": per_tick["supports"],
        "ms_per_tick_axles_cpu_rounds": per_tick["axles"],
        "supports_to_axles_cpu_rounds": ratios,
        "python": platform.python_version(),
    }
