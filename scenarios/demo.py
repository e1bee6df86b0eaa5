"""A short model demonstration: the reference combination turning a full circle at 15 km/h."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from controller.speed import SpeedController
from vehicle_model.geometry import radial_extent, tractor_outline, trailer_outline
from vehicle_model.presets import vehicle_preset
from vehicle_model.simulator import Controls, Simulator, initial_state
from vehicle_model.surface import Surface
from vehicle_model.trim import trim


def run_demo(
    out_dir: Path, vehicle: str = "reference", surface: str = "dry", speed_kmh: float = 15.0
) -> dict[str, Any]:
    """Drive straight, ramp the front steer to the steady value for a 10.19 m kingpin radius, circle 360°.

    Writes ``plan.png`` (plan view with body outlines) to ``out_dir`` and returns a summary.
    """
    params = vehicle_preset(vehicle)
    road = Surface.preset(surface)
    speed = speed_kmh / 3.6
    steady = trim(params, speed, kingpin_curvature=1.0 / 10.19, mu=road.friction(np.zeros((1, 2)))[0])
    steer = steady.get(f"steer_{params.tractor.axles[0].name}")
    sim = Simulator(params, surface=road)
    sim.reset(initial_state(sim.layout, speed=speed))
    control = SpeedController(mass=params.tractor.mass + params.trailer.mass)
    period = sim.control_period
    states = [sim.state_vector]
    heading_turned = 0.0
    while heading_turned < 2.0 * math.pi + math.pi / 2:
        t = sim.time
        ramp = min(max((t - 2.0) / 2.0, 0.0), 1.0)
        prev = sim.state.psi1
        sim.step(Controls([ramp * steer], control(speed, sim.state.u, period)))
        heading_turned += sim.state.psi1 - prev
        states.append(sim.state_vector)
        if sim.time > 300:
            break
    traj = np.array(states)
    x, y, psi1, gamma = traj[:, 0], traj[:, 1], traj[:, 2], traj[:, 6]
    tractor = tractor_outline(params, x, y, psi1)
    trailer = trailer_outline(params, x, y, psi1, gamma)
    # Centre of the steady circle from the last quarter turn of tractor front corners.
    last = tractor[-len(traj) // 4 :, 1]  # front-right corner is outermost in a left turn
    centre = _fit_circle(last)
    r_out, _ = radial_extent(tractor, centre)
    _, r_in = radial_extent(trailer, centre)
    summary = {
        "vehicle": vehicle,
        "surface": surface,
        "speed_kmh": speed_kmh,
        "front_steer_deg": math.degrees(steer),
        "steady_articulation_deg": math.degrees(gamma[-1]),
        "tractor_outer_radius_m": float(r_out[-len(traj) // 4 :].max()),
        "trailer_inner_radius_m": float(r_in[-len(traj) // 4 :].min()),
        "simulated_s": sim.time,
    }
    out_dir.mkdir(parents=True, exist_ok=True)
    _plot(out_dir / "plan.png", tractor, trailer, centre, summary)
    return summary


def _fit_circle(points: np.ndarray) -> tuple[float, float]:
    """Least-squares circle centre (Kåsa fit)."""
    a = np.column_stack([2 * points[:, 0], 2 * points[:, 1], np.ones(len(points))])
    b = (points**2).sum(axis=1)
    cx, cy, _ = np.linalg.lstsq(a, b, rcond=None)[0]
    return float(cx), float(cy)


def _plot(path: Path, tractor: np.ndarray, trailer: np.ndarray, centre: tuple[float, float], summary: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 7))
    for poly, colour in ((tractor, "tab:red"), (trailer, "tab:blue")):
        for k in range(0, len(poly), 25):
            closed = np.vstack([poly[k], poly[k][:1]])
            ax.plot(closed[:, 0], closed[:, 1], color=colour, lw=0.5, alpha=0.6)
    for radius, style in ((12.5, "k-"), (5.3, "k--")):
        a = np.linspace(0, 2 * np.pi, 200)
        ax.plot(centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a), style, lw=1)
    ax.set_aspect("equal")
    ax.set_xlabel("X [m]")
    ax.set_ylabel("Y [m]")
    ax.set_title(
        f"{summary['vehicle']} at {summary['speed_kmh']:.0f} km/h on {summary['surface']}: "
        f"outer {summary['tractor_outer_radius_m']:.2f} m, inner {summary['trailer_inner_radius_m']:.2f} m"
    )
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
