"""The closing summary of a run for the terminal: off-tracking of the truth and every estimator, the verdicts."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rich.markup import escape
from rich.table import Table


def run_summary(metrics: dict[str, Any], run_dir: Path) -> list[Any]:
    """Rich renderables, in order: the off-tracking table, what "valid" means, the camera, the roundabout
    verdict and the timing. Units in headers are escaped so that ``[m]`` survives rich's markup."""
    out: list[Any] = []
    table = Table(title=escape(f"{metrics['scenario']} — {metrics['status']} — {run_dir}"))
    table.add_column("off-tracking")
    table.add_column(escape("RMS [m]"), justify="right")
    table.add_column(escape("max |·| [m]"), justify="right")
    table.add_column("valid", justify="right")
    truth = metrics["offtracking"]["truth"]
    defined = truth.get("defined_fraction", truth["valid_fraction"])
    table.add_row("truth", f"{truth['rms']:.3f}", f"{truth['max_abs']:.3f}", f"(defined on {defined:.0%} of ticks)")
    for name, err in metrics["offtracking"]["estimators"].items():
        table.add_row(
            f"{name} error", f"{err['rms_error']:.3f}", f"{err['max_abs_error']:.3f}", f"{err['valid_fraction']:.0%}"
        )
    out.append(table)
    out.append("valid: share of the ticks with a truth on which the estimator had an estimate")
    camera = metrics.get("camera")
    if camera:
        out.append(
            f"camera: {camera['valid_frames']} of {camera['frames']} frames gave an accepted motion"
            + (f"; {escape(camera['message'])}" if camera.get("message") else "")
        )
    test = metrics.get("roundabout_test")
    if test:
        verdict = "[green]PASS[/]" if test["pass"] else "[red]FAIL[/]"
        out.append(
            f"roundabout test {verdict}: outer radius max {test['outer_radius_max']:.3f} m (limit 12.50), "
            f"inner radius min {test['inner_radius_min']:.3f} m (limit 5.30)"
        )
    verdict = metrics.get("verdict")
    if verdict is not None:
        if verdict["held"]:
            out.append(
                "[green]held[/]: "
                + (
                    "off-tracking within target on a trusted estimate"
                    if metrics["feedback"] != "none"
                    else "nothing to hold (unsteered)"
                )
            )
        for flag in verdict["flags"]:
            out.append(f"[red]{flag['flag']}[/]: {escape(flag['reason'])}")
    wall = metrics.get("wall_time_s")
    wall_text = f"{wall:.1f} s" if isinstance(wall, int | float) else "an unknown"
    out.append(f"simulated {metrics['simulated_s']:.1f} s in {wall_text} wall time")
    return out
