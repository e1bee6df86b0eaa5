"""The closing summary of a run for the terminal: off-tracking of the truth and every estimator, the verdicts.

The metrics may come from a run that did not finish (``offtrack report`` after a kill) or from ``metrics.json``
itself, where a quantity that could not be computed is null: every number is shown through :func:`number`, which
writes such a value as ``–`` instead of failing.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from rich.markup import escape
from rich.table import Table

from .verdicts import ROUNDABOUT_FLAG, inner_limit_reason, with_roundabout_test

MISSING = "–"
"""How a number the run did not produce (None, not a number) is shown."""

UNPHYSICAL_END = ("diverged",)
"""Statuses whose last recorded states left the model's valid region, so that extremes over them are not
measurements."""

ALL_TICKS = "all ticks"
"""The window of an RMS over every tick on which the truth is defined."""
AFTER_WARMUP = "after warm-up"
"""The window of an RMS over the ticks once one more trailer length has been driven (the figures' window)."""


SWEPT_WORDS = {
    "radial": "radially about the turn centre, as the PBS low speed swept path",
    "lateral": "across the reference path",
}
"""How the summary says which swept-path width a run measured (``metrics.json["swept_path"]["definition"]``)."""


def number(value: Any, spec: str = ".3f", unit: str = "") -> str:
    """``value`` formatted with ``spec`` (and `` unit``), or :data:`MISSING` if it is None or not a real number.

    NaN is shown as ``nan``: the quantity exists but had no samples (e.g. the truth before it was defined).
    """
    if isinstance(value, bool) or not isinstance(value, int | float):
        return MISSING
    text = f"{value:{spec}}"
    return f"{text} {unit}" if unit and math.isfinite(value) else text


def held_words(metrics: dict[str, Any]) -> str:
    """What a run that held was asked to hold, in words: its steering's target on a trusted estimate (a steered
    run), the roundabout test (a run on it), or nothing (an unsteered run on any other manoeuvre)."""
    steered = any(f not in (None, "none") for f in (metrics.get("feedback"), *(metrics.get("rear_feedback") or ())))
    asked = ["off-tracking within target on a trusted estimate"] if steered else []
    if metrics.get("roundabout_test"):
        asked.append("roundabout test passed")
    return "; ".join(asked) if asked else "nothing to hold (unsteered)"


def run_summary(metrics: dict[str, Any], run_dir: Path) -> list[Any]:
    """Rich renderables, in order: the off-tracking table, what its "ticks" column means, the camera, the roundabout
    verdict, the swept-path width and the timing. Units in headers are escaped so that ``[m]`` survives rich's
    markup."""
    out: list[Any] = []
    table = Table(title=escape(f"{metrics.get('scenario')} — {metrics.get('status')} — {run_dir}"))
    table.add_column("off-tracking")
    table.add_column("window")
    table.add_column(escape("RMS [m]"), justify="right")
    table.add_column(escape("max |·| [m]"), justify="right")
    table.add_column("ticks", justify="right")
    offtracking = metrics.get("offtracking") or {}
    truth = offtracking.get("truth") or {}
    settled = offtracking.get("truth_after_warmup") or {}
    defined = f"{number(truth.get('defined_fraction', truth.get('valid_fraction')), '.0%')} defined"
    table.add_row("truth", ALL_TICKS, number(truth.get("rms")), number(truth.get("max_abs")), defined)
    if settled:
        table.add_row("truth", AFTER_WARMUP, number(settled.get("rms")), number(settled.get("max_abs")), "")
    for unit, own in (offtracking.get("units") or {}).items():  # each further unit's, against its coupling's path
        unit_defined = f"{number(own.get('defined_fraction'), '.0%')} defined"
        table.add_row(f"unit {unit} truth", ALL_TICKS, number(own.get("rms")), number(own.get("max_abs")), unit_defined)
        if "rms_after_warmup" in own:
            after = (number(own.get("rms_after_warmup")), number(own.get("max_abs_after_warmup")))
            table.add_row(f"unit {unit} truth", AFTER_WARMUP, *after, "")
    if combination := offtracking.get("combination"):  # the last unit's rear against the steer axle's path
        table.add_row(
            f"unit {combination.get('unit')} rear vs steer axle path",
            ALL_TICKS,
            number(combination.get("rms")),
            number(combination.get("max_abs")),
            f"{number(combination.get('defined_fraction'), '.0%')} defined",
        )
    errors = {f"{name} error": err for name, err in (offtracking.get("estimators") or {}).items()}
    for unit, own in (offtracking.get("units") or {}).items():
        errors.update({f"unit {unit} {name} error": err for name, err in (own.get("estimators") or {}).items()})
    for label, err in errors.items():
        table.add_row(
            label,
            ALL_TICKS,
            number(err.get("rms_error")),
            number(err.get("max_abs_error")),
            f"{number(err.get('valid_fraction'), '.0%')} valid",
        )
    out.append(table)
    out.append(
        f"window: {ALL_TICKS}, every tick on which the truth is defined (once a trailer length has been driven); "
        f"{AFTER_WARMUP}, once one more trailer length has been driven (the window of offtracking.png's legend and "
        "of the verdict's target). ticks: an estimator is valid on the share of the truth's ticks on which it had "
        "an estimate"
    )
    camera = metrics.get("camera")
    if camera:
        out.append(
            f"camera: {number(camera.get('valid_frames'), 'd')} of {number(camera.get('frames'), 'd')} frames gave an "
            "accepted motion" + (f"; {escape(camera['message'])}" if camera.get("message") else "")
        )
    steering = {axle: m for axle, m in (metrics.get("trailer_steering") or {}).items() if m.get("max_abs_steer_deg")}
    if steering:
        out.append(
            "trailer steer: "
            + "; ".join(
                f"{axle} up to {number(m.get('max_abs_steer_deg'), '.1f')}°, at its lock "
                f"{number(m.get('saturated_fraction'), '.0%')} of the time"
                for axle, m in steering.items()
            )
        )
    reach = metrics.get("steering_reach")
    if reach and reach.get("share_of_path", 0.0) > 0.0:
        out.append(
            f"beyond the steering's reach on {number(reach.get('share_of_path'), '.0%')} of the path after warm-up "
            f"({number(reach.get('distance_m'), '.1f')} m): holding the follow point there needs an axle past its lock"
        )
    test = metrics.get("roundabout_test")
    if test:
        verdict = "[green]PASS[/]" if test.get("pass") else "[red]FAIL[/]"
        reason = inner_limit_reason(test)
        out.append(
            f"roundabout test {verdict}: outer radius max {number(test.get('outer_radius_max'), unit='m')} "
            f"(limit 12.50), inner radius min {number(test.get('inner_radius_min'), unit='m')} (limit 5.30)"
            + (f": {escape(reason)}" if reason else "")
            + (
                f" (the run {metrics.get('status')}: these radii include its last, unphysical states)"
                if metrics.get("status") in UNPHYSICAL_END
                else ""
            )
        )
    swept = metrics.get("swept_path")
    if swept:
        how = SWEPT_WORDS.get(swept.get("definition"), "")
        units = ", ".join(
            f"{unit} {number(m.get('width_m'), '.2f')}" for unit, m in (swept.get("per_unit") or {}).items()
        )
        out.append(
            f"swept-path width {number(swept.get('width_m'), '.2f', 'm')}"
            + (f" ({how})" if how else "")
            + (f"; each unit's own: {units}" if units else "")
        )
    if road := metrics.get("road_columns"):  # what ran instead of the scenario's speed and surface
        spans = [
            f"{'μ' if k == 'mu' else 'speed'} {v[0]:.3g}–{v[1]:.3g}{' km/h' if k != 'mu' else ''}"
            for k, v in road.items()
        ]
        out.append(f"from the road file's columns (they win over the scenario's speed and surface): {', '.join(spans)}")
    verdict = metrics.get("verdict")
    if verdict is not None:
        verdict = with_roundabout_test(verdict, test)  # a metrics.json from before the test was one of its flags
        if verdict.get("held"):
            out.append(f"[green]held[/]: {held_words(metrics)}")
        else:
            out.append(f"[red]not held[/]: {len(verdict.get('flags', []))} miss(es), each below with its reason")
        for flag in verdict.get("flags", []):
            reason = "the roundabout test above" if flag["flag"] == ROUNDABOUT_FLAG else flag["reason"]
            out.append(f"[red]{flag['flag']}[/]: {escape(reason)}")
    for note in metrics.get("notes") or ():
        out.append(f"[yellow]note[/]: {escape(str(note.get('text')))}")
    wall = metrics.get("wall_time_s")
    wall_text = f"{number(wall, '.1f', 's')}" if number(wall) != MISSING else "an unknown"
    out.append(f"simulated {number(metrics.get('simulated_s'), '.1f', 's')} in {wall_text} wall time")
    return out
