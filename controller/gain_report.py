"""Gain design report: tables and step figure for docs/controller_design.md (``python -m controller.gain_report``)."""

from __future__ import annotations

import math
from pathlib import Path

import control
import numpy as np

from vehicle_model.parameters import VehicleParams

from .gain_design import DEFAULT_DELAY, DesignResult, design_gains, measurement_delay

__all__ = ["design_table", "main", "plot_step_responses"]


def plot_step_responses(results: list[DesignResult], path: str | Path, distance: float = 150.0) -> Path:
    """Save the closed-loop step responses of ``results`` against distance travelled as a PNG.

    Parameters
    ----------
    results
        Designs to plot (e.g. both plants at 15 and 80 km/h).
    path
        Output file.
    distance
        Distance axis length [m].

    Returns
    -------
    pathlib.Path
        The file written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.0), dpi=120)
    for res in results:
        if not res.stable:
            continue
        t = np.linspace(0.0, distance / res.speed, 2001)
        resp = control.step_response(res.closed_loop, timepts=t)
        label = (
            f"{res.speed * 3.6:.0f} km/h, {res.plant_kind}: PM {res.phase_margin_deg:.0f}°, "
            f"GM {res.gain_margin_db:.1f} dB"
        )
        ax.plot(t * res.speed, np.squeeze(resp.outputs), label=label)
    ax.axhline(1.0, color="0.6", lw=0.8, ls="--")
    ax.set_xlabel("distance travelled [m]")
    ax.set_ylabel("off-tracking / set-point step [-]")
    ax.set_title(f"Path-following loop, step in the off-tracking set-point (dead time {results[0].delay:.2f} s)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out


def design_table(
    params: VehicleParams,
    speeds: tuple[float, ...] = (15.0 / 3.6, 80.0 / 3.6),
    delays: tuple[float, ...] = (measurement_delay(0.0, 0.02, 0.02), DEFAULT_DELAY),
) -> list[DesignResult]:
    """Designs for both plants at every speed and dead time (the tables of ``docs/controller_design.md``)."""
    return [
        design_gains(params, speed, plant=kind, delay=delay)  # type: ignore[arg-type]
        for delay in delays
        for speed in speeds
        for kind in ("kinematic", "dynamic")
    ]


def main(argv: list[str] | None = None) -> None:
    """``python -m controller.gain_report [FIGURE.png]``: print the design tables, save the step figure."""
    import sys

    from vehicle_model.presets import lst_laden, reference_laden

    args = sys.argv[1:] if argv is None else argv
    data = reference_laden().model_dump()
    for axle in data["trailer"]["axles"]:
        axle["steerable"] = True
    data["name"] = "reference-all-steer"
    vehicles = [lst_laden(), VehicleParams(**data)]
    print("| vehicle | speed | plant | dead time | kp | ki | GM | PM | ω_c | rise | settle | overshoot | settle dist |")
    print("|" + "---|" * 13)
    for vehicle in vehicles:
        for r in design_table(vehicle):
            print(
                f"| {vehicle.name} | {r.speed * 3.6:.0f} km/h | {r.plant_kind} | {r.delay:.2f} s | {r.gains.kp:.3f} "
                f"| {r.gains.ki:.4f} | {r.gain_margin_db:.1f} dB | {r.phase_margin_deg:.1f}° | "
                f"{r.gain_crossover:.2f} rad/s | {r.step.get('RiseTime', math.nan):.2f} s | "
                f"{r.step.get('SettlingTime', math.nan):.2f} s | {r.step.get('Overshoot', math.nan):.1f} % | "
                f"{r.step.get('SettlingDistance', math.nan):.1f} m |"
            )
    if args:
        results = design_table(vehicles[0], delays=(DEFAULT_DELAY,))
        print(f"figure: {plot_step_responses(results, args[0])}")


if __name__ == "__main__":
    main()
