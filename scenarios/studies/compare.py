"""Compare feedback sources on one scenario: the same manoeuvre steered by each off-tracking estimate."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..config import ScenarioConfig, validate_config
from ..run.cosim import ProgressCallback
from ..run.files import write_atomic
from ..run.results import TIMESERIES_FILE
from ..run.runner import run_scenario

FEEDBACK_ORDER = ("none", "zero_slip", "viso_ot", "truth")
COLOURS = {"none": "0.4", "zero_slip": "tab:orange", "viso_ot": "tab:green", "truth": "k"}


def summary_row(feedback: str, metrics: dict[str, Any]) -> dict[str, Any]:
    """One table row from a run's metrics."""
    settled = metrics["offtracking"]["truth_after_warmup"]
    steering = metrics.get("trailer_steering") or {}
    test = metrics.get("roundabout_test")
    return {
        "feedback": feedback,
        "status": metrics["status"],
        "true_offtracking_rms_m": settled["rms"],
        "true_offtracking_max_m": settled["max_abs"],
        "max_trailer_steer_deg": max((v["max_abs_steer_deg"] for v in steering.values()), default=0.0),
        "saturated_fraction": max((v["saturated_fraction"] for v in steering.values()), default=0.0),
        "roundabout_pass": None if test is None else test["pass"],
        "outer_radius_max_m": None if test is None else test["outer_radius_max"],
        "inner_radius_min_m": None if test is None else test["inner_radius_min"],
    }


def compare_feedback(
    config: ScenarioConfig,
    out_dir: Path,
    feedbacks: tuple[str, ...] = FEEDBACK_ORDER,
    progress: ProgressCallback | None = None,
) -> pd.DataFrame:
    """Run ``config`` once per feedback source into ``out_dir/<feedback>/``; write the table and the figure.

    Writes ``comparison.csv``, ``comparison.md`` and ``comparison.png`` (true off-tracking of every run
    against time, and their swept follow-point paths).
    """
    configs = {}
    for feedback in feedbacks:  # validate every variant before the first run starts
        data = config.model_dump()
        data["feedback"] = feedback
        data["estimators"]["viso_ot"] = config.estimators.viso_ot or feedback == "viso_ot"
        configs[feedback] = validate_config(data)
    rows, traces = [], {}
    for feedback, cfg in configs.items():
        run_dir = out_dir / feedback
        run_dir.mkdir(parents=True, exist_ok=True)
        metrics = run_scenario(cfg, run_dir, progress=progress, plots=False)
        rows.append(summary_row(feedback, metrics))
        traces[feedback] = pd.read_parquet(run_dir / TIMESERIES_FILE)
    table = pd.DataFrame(rows)
    write_atomic(out_dir / "comparison.csv", table.to_csv(index=False))
    write_atomic(out_dir / "comparison.md", table.to_markdown(index=False, floatfmt=".3f"))
    _plot(out_dir / "comparison.png", config, traces)
    return table


def _plot(path: Path, config: ScenarioConfig, traces: dict[str, pd.DataFrame]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, plan) = plt.subplots(1, 2, figsize=(14, 5.5), width_ratios=[1.6, 1])
    for feedback, frame in traces.items():
        colour = COLOURS.get(feedback)
        top.plot(frame["time"], frame["offtracking_truth"], color=colour, lw=1.2, label=feedback)
        plan.plot(frame["follow_x"], frame["follow_y"], color=colour, lw=1.0, label=f"follow point, {feedback}")
    first = next(iter(traces.values()))
    plan.plot(first["kingpin_x"], first["kingpin_y"], color="tab:purple", lw=0.8, ls="--", label="kingpin (none)")
    for band in (0.10, 0.15):
        top.axhline(band, color="tab:red", lw=0.5, ls=":")
        top.axhline(-band, color="tab:red", lw=0.5, ls=":")
    top.axhline(0.0, color="k", lw=0.5)
    top.set_xlabel("time [s]")
    top.set_ylabel("true off-tracking e_tr [m]")
    top.set_title(
        f"{config.name}: μ = {config.surface.base_mu:.2f}, camber {config.camber.percent:g} % "
        f"{config.camber.direction}, {config.speed.cornering_kmh:g} km/h, {config.vehicle}"
    )
    top.legend(title="feedback")
    plan.set_aspect("equal")
    plan.set_xlabel("X [m]")
    plan.set_ylabel("Y [m]")
    plan.legend(fontsize=7)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)


def comparison_rows_as_text(table: pd.DataFrame) -> list[list[str]]:
    """Table cells formatted for a console table."""
    out = []
    for _, row in table.iterrows():
        cells = []
        for value in row.to_numpy():
            if isinstance(value, float | np.floating):
                cells.append("—" if not np.isfinite(value) else f"{value:.3f}")
            else:
                cells.append(str(value))
        out.append(cells)
    return out
