"""The study ``controller-limits``: the path-following controller where its axles run out of reach.

Each cell is a manoeuvre × surface × vehicle; each runs unsteered and with the controller fed by the true
off-tracking and by the zero-slip estimate. Every cell is driven as a driver who knows the surface would: the
speed profile capped at :data:`FRICTION_SHARE` of the road's friction (``speed.friction_share``,
:mod:`controller.friction_speed`; less for a combination of :data:`VEHICLE_FRICTION_SHARE`), which leaves a profile
the road allows untouched. A row holds the true
off-tracking after warm-up (RMS, max), the share of the path beyond the steering's reach
(:func:`scenarios.run.metrics.steering_reach`) and the axles' time at lock, for the first towed unit and as
``unit<k>_…`` for every steered unit behind it (:mod:`scenarios.studies.controller_limits_units`).
The check of the study (docs/controller_design.md §3.5): on every cell and every steered unit the truth-fed loop's RMS
and max are no more than the zero-slip-fed loop's and the unsteered loop's (:func:`truth_fed_check`).

The default subset is the paper's 11.5 m field figure-of-eight, wet, the LST; ``full`` adds the field roundabout
and the UK roundabout test on dry, wet and ice, each on the LST and on the steered B-double (:data:`VEHICLES`: both
trailers steered, each on its own estimate of its own off-tracking; ``vehicle`` drives the cells on one other
combination instead), and on every cell the optimal reference (``offtrack optimal``,
:mod:`scenarios.studies.optimal_reference`: the NLP's steer replayed as a run, several CPU-minutes per cell). A
cell's check then also holds the PID's gap to it: the truth-fed PID's true RMS after warm-up over the optimum's
open-loop replay's, the same ticks and window (:func:`optimal_gap`).

With ``camera`` every cell also runs on the fused VISO-OT estimate under the field-loop study's field conditions
(:mod:`scenarios.studies.controller_limits_camera`: a rendered camera, minutes per case): its row adds the fused
estimate's error, the share within 2σ and the raw camera's error, and ``controller_limits.json`` the check over the
group of camera cells (coverage within the field-loop study's band, the fused RMS never more than the raw camera's,
:func:`~scenarios.studies.controller_limits_camera.camera_check`), for all of them and for each manoeuvre.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from ..config import load_scenario
from ..loop.ends import RunStatus
from ..run.metrics import after_warmup
from ..run.results import TIMESERIES_FILE
from ..run.runner import run_scenario
from .controller_limits_camera import CAMERA_COLUMNS, CAMERA_FEEDBACK, camera_check, camera_columns, camera_overrides
from .controller_limits_units import (
    UNIT_CAMERA_KEYS,
    at_lock_share,
    further_camera_columns,
    further_steered_units,
    further_unit_row,
    outswing_inputs,
    unit_prefixes,
)
from .optimal_reference import run_optimal_reference
from .records import CaseSpec
from .unit_steering import study_vehicle
from .workers import worker_models

__all__ = [
    "B_DOUBLE",
    "CAMERA_FEEDBACK",
    "FEEDBACKS",
    "FRICTION_SHARE",
    "VEHICLES",
    "VEHICLE_FRICTION_SHARE",
    "camera_group_checks",
    "controller_limits_cases",
    "controller_limits_figures",
    "largest_outswing",
    "optimal_gap",
    "run_controller_limits_case",
    "truth_fed_check",
]

STUDY = "controller-limits"
FEEDBACKS = ("none", "truth", "zero_slip")
"""The steering of each cell: unsteered, fed by the true off-tracking, fed by the zero-slip estimate."""
FRICTION_SHARE = 0.6
"""The share of the road's friction each cell's driver plans its speed with (``speed.friction_share``): the share the
traction and brake limits use (:func:`controller.speed.traction_limit`)."""
OPTIMAL = "optimal"
"""The label of a cell's optimal reference (``full`` only): the NLP's steer over the truth-fed PID's run."""
REFERENCE_HOLDS = 0.10
"""[m] The RMS the optimal reference must reach for the PID's gap to it to be checked (the design's target RMS)."""
GAP_LIMIT = 2.0
"""The largest ratio of the truth-fed PID's RMS to the reference's where the reference holds :data:`REFERENCE_HOLDS`."""
OUTSWING_SPAN = 2.5
"""[m] Half the path length over which :func:`largest_outswing` takes the kingpin path's curvature."""
STRAIGHT_CURVATURE = 0.02
"""[1/m] Below this curvature (a 50 m radius) the path counts as straight or between turns: no outside to swing to."""
SUBSET = (("field-figure-eight", "wet", "lst"),)
"""The default subset's cells: (scenario, surface, vehicle)."""
FULL_SCENARIOS = ("field-figure-eight", "field-roundabout-left", "roundabout-test")
FULL_SURFACES = ("dry", "wet", "ice")
B_DOUBLE = "au-b-double-steered"
"""The steered B-double of the whole study: the rear two axles of each trailer steerable, both trailers steered on
the cell's feedback (each on its own estimate of its own off-tracking, ``rear_feedback`` following ``feedback``)."""
VEHICLES = ("lst", B_DOUBLE)
"""The combinations of the whole study's cells (``full``), the LST's cells first."""
VEHICLE_FRICTION_SHARE = {B_DOUBLE: 0.4}
"""The most of the road's friction a combination's driver plans with where :data:`FRICTION_SHARE` is more: at 0.6
of ice's friction the B-double's tractor, its steer axle at lock, leaves the 11.5 m field loops whatever the trailers
do (docs/studies.md, the controller-limits section). On dry and wet roads the share leaves those manoeuvres'
profiles as they are."""


def controller_limits_cases(
    full: bool = False,
    vehicle: str | None = None,
    *,
    cells: Sequence[tuple[str, str, str]] | None = None,
    optimal: bool | None = None,
    friction_share: float | None = FRICTION_SHARE,
    camera: bool = False,
) -> list[CaseSpec]:
    """The cases: every cell × :data:`FEEDBACKS` (feedback fastest), with ``camera`` the cell's fused camera case
    (:data:`~scenarios.studies.controller_limits_camera.CAMERA_FEEDBACK`) and with ``optimal`` the cell's optimal
    reference (:data:`OPTIMAL`).

    Parameters
    ----------
    full
        The whole study's cells instead of the default subset (:data:`SUBSET`): :data:`FULL_SCENARIOS` ×
        :data:`FULL_SURFACES` × :data:`VEHICLES`.
    vehicle
        Drive the cells (the default subset's, or with ``full`` every scenario and surface) on this combination
        alone: a preset's name or a combination file with a steerable towed unit
        (:func:`~scenarios.studies.unit_steering.study_vehicle`); the label is its name.
    cells
        Other cells, (scenario, surface, vehicle) each, instead of either (e.g.
        ``benchmarks/controller_limits_field.py``'s field manoeuvres).
    optimal
        Add each cell's optimal reference; default: with ``full`` only.
    friction_share
        ``speed.friction_share`` of every case, at most :data:`VEHICLE_FRICTION_SHARE` of a combination listed
        there; ``None``: the scenarios' speed profiles as they are.
    camera
        Add each cell's fused camera case under field conditions
        (:func:`~scenarios.studies.controller_limits_camera.camera_overrides`); rendered, so off by default.
    """
    values: dict[str, Any] = {}
    if vehicle is not None:
        resolved = study_vehicle(vehicle, STUDY)
        values[resolved.name] = resolved.value
        vehicles: tuple[str, ...] = (resolved.name,)
        subset = [(s, surface, resolved.name) for s, surface, _ in SUBSET]
    else:
        vehicles, subset = VEHICLES, list(SUBSET)
    if cells is None:
        cells = (
            [(s, surface, v) for v in vehicles for s in FULL_SCENARIOS for surface in FULL_SURFACES] if full else subset
        )
    if optimal is None:
        optimal = full
    cases = []
    feedbacks = (*FEEDBACKS, *((CAMERA_FEEDBACK,) if camera else ()), *((OPTIMAL,) if optimal else ()))
    for scenario, surface, vehicle_label in cells:
        for feedback in feedbacks:
            overrides: tuple[tuple[str, Any], ...] = (
                ("vehicle", values.get(vehicle_label, vehicle_label)),
                ("surface.preset", surface),
                ("feedback", "truth" if feedback == OPTIMAL else feedback),
                ("estimators.zero_slip", True),
            )
            if friction_share is not None:
                share = min(friction_share, VEHICLE_FRICTION_SHARE.get(vehicle_label, friction_share))
                overrides += (("speed.friction_share", share),)
            if feedback == CAMERA_FEEDBACK:
                overrides += camera_overrides()
            labels = (("scenario", scenario), ("surface", surface), ("vehicle", vehicle_label), ("feedback", feedback))
            cases.append(CaseSpec(STUDY, scenario, overrides, labels))
    return cases


def run_controller_limits_case(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """Run one case into ``out_dir/<case name>/`` and return its row (labels, status and the figures above; the
    optimal reference's row holds its replay's off-tracking and the NLP's own, a camera case's the fused and raw
    camera's errors, :data:`~scenarios.studies.controller_limits_camera.CAMERA_COLUMNS`)."""
    config = load_scenario(spec.scenario, dict(spec.overrides))
    run_dir = out_dir / spec.name
    run_dir.mkdir(parents=True, exist_ok=True)
    if dict(spec.labels)["feedback"] == OPTIMAL:
        metrics = run_optimal_reference(config, run_dir)
    else:
        metrics = run_scenario(config, run_dir, plots=False, model=worker_models().model(config.vehicle_params()))
    row: dict[str, Any] = {**dict(spec.labels), "status": metrics["status"]}
    if metrics["status"] in (RunStatus.INTERRUPTED, RunStatus.FAILED):
        row.update({k: metrics.get(k) for k in ("stop_signal", "message", "stop_time")})
        return row
    params = config.vehicle_params()
    units = further_steered_units(params)
    settled = metrics["offtracking"]["truth_after_warmup"]
    recorded = _recorded(run_dir, units)
    reach = metrics.get("steering_reach") or {}
    steering = metrics.get("trailer_steering") or {}
    row.update(
        {
            "true_offtracking_rms_after_warmup_m": settled["rms"],
            "true_offtracking_max_after_warmup_m": settled["max_abs"],
            "largest_outswing_after_warmup_m": largest_outswing(recorded, params.follow_point_offset),
            "beyond_reach_share": reach.get("share_of_path", 0.0),
            "at_lock_share": at_lock_share(steering, params),
        }
    )
    warm = after_warmup(recorded, params.follow_point_offset)
    for unit in units:  # every steered unit behind the first, on its own coupling's path
        e, x, y, own = outswing_inputs(recorded, unit, warm)
        outswing = _outswing(e, x, y, own, params.follow_point_offset_of(unit - 1), OUTSWING_SPAN)
        row.update(further_unit_row(metrics, recorded, params, unit, warm, outswing))
    if dict(spec.labels)["feedback"] == CAMERA_FEEDBACK:
        row.update(camera_columns(metrics))
        row.update(further_camera_columns(metrics, units))
    reference = metrics.get("optimal_reference")
    if reference is not None:
        row.update(
            {
                "optimal_status": reference["status"],
                "optimal_nlp_rms_m": reference["nlp_offtracking_rms"],
                "pid_nodes_rms_m": reference.get("pid_nodes_offtracking_rms"),
                "optimal_cost_m2": reference["cost"],
                "pid_cost_m2": reference["pid_cost"],
                "optimal_replay_rms_m": (reference.get("replay_open_loop_after_warmup") or {}).get("rms"),
                "pid_over_replay_rms_ratio": reference.get("pid_over_replay_rms_ratio"),
            }
        )
        for unit in units:  # each further steered unit's optimum and the PID's on the same nodes
            row[f"unit{unit}_optimal_nlp_rms_m"] = reference.get(f"unit{unit}_nlp_offtracking_rms")
            row[f"unit{unit}_pid_nodes_rms_m"] = reference.get(f"unit{unit}_pid_nodes_offtracking_rms")
    return row


def _recorded(run_dir: Path, units: Sequence[int] = ()) -> dict[str, np.ndarray]:
    """The columns :func:`largest_outswing` needs from a run directory's time series, and those of each further
    unit in ``units`` (its truth, its coupling's path and, where it was steered, its reach flag)."""
    wanted = ["offtracking_truth", "kingpin_x", "kingpin_y"]
    for unit in units:
        wanted += [f"offtracking_truth{unit}", f"coupling{unit}_x", f"coupling{unit}_y", f"unit{unit}_beyond_reach"]
    present = set(pq.ParquetDataset(run_dir / TIMESERIES_FILE).schema.names)
    names = [name for name in wanted if name in present]
    frame = pd.read_parquet(run_dir / TIMESERIES_FILE, columns=names)
    return {name: frame[name].to_numpy(dtype=float) for name in names}


def largest_outswing(columns: dict[str, np.ndarray], follow_point_offset: float, span: float = OUTSWING_SPAN) -> float:
    """The follow point's largest true off-tracking to the outside of the turn after warm-up [m] (0 if never out).

    The turn's side is the sign of the kingpin path's curvature beside the follow point (``follow_point_offset``
    behind the kingpin along the path), its heading change over ``span`` [m] of the path either side; off-tracking
    is positive to the left, so outside is ``e·κ > 0`` (as the controller's reach freeze and outswing bound,
    docs/controller_design.md §3.5). Samples on a path straighter than
    :data:`STRAIGHT_CURVATURE` are not in a turn and not counted.

    Parameters
    ----------
    columns
        ``offtracking_truth``, ``kingpin_x``, ``kingpin_y`` of a run.
    follow_point_offset
        [m] The follow point's distance behind the kingpin (also the warm-up,
        :func:`scenarios.run.metrics.after_warmup`).
    span
        [m] Half the length of path over which the curvature is taken.
    """
    settled = after_warmup(columns, follow_point_offset)
    x, y, e = columns["kingpin_x"], columns["kingpin_y"], columns["offtracking_truth"]
    return _outswing(e, x, y, settled, follow_point_offset, span)


def _outswing(
    e: np.ndarray, x: np.ndarray, y: np.ndarray, settled: np.ndarray, follow_point_offset: float, span: float
) -> float:
    """:func:`largest_outswing` of off-tracking ``e`` against the front coupling's path ``(x, y)`` over the samples
    ``settled``."""
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
    moving = np.concatenate([[True], np.diff(travelled) > 1e-6])
    s, xm, ym = travelled[moving], x[moving], y[moving]
    if s.size < 3 or not settled.any():
        return 0.0
    heading = np.unwrap(np.arctan2(np.gradient(ym, s), np.gradient(xm, s)))
    behind = travelled - follow_point_offset  # the path beside the follow point, a trailer's length back
    kappa = (np.interp(behind + span, s, heading) - np.interp(behind - span, s, heading)) / (2.0 * span)
    turning = settled & (np.abs(kappa) > STRAIGHT_CURVATURE)
    out = e[turning] * np.sign(kappa[turning])
    return float(max(np.nanmax(out), 0.0)) if out.size else 0.0


def _rows(table: pd.DataFrame, cell: tuple[str, str, str]) -> pd.DataFrame:
    """The rows of one cell (scenario, surface, vehicle)."""
    return table[(table["scenario"] == cell[0]) & (table["surface"] == cell[1]) & (table["vehicle"] == cell[2])]


def controller_limits_figures(table: pd.DataFrame, out_dir: Path) -> None:
    """``controller_limits.png``: the true off-tracking after warm-up (RMS and max) of each cell by steering, and
    ``controller_limits.json``: each cell's check (truth-fed RMS and max ≤ zero-slip-fed and ≤ unsteered,
    :func:`truth_fed_check`; with its camera case's :data:`~scenarios.studies.controller_limits_camera.CAMERA_COLUMNS`),
    or for a cell with a loop that did not complete ``held`` ``None`` and each such feedback's status
    (``not_completed``: the check is not taken on part of a run), then the camera cells' group checks
    (:func:`camera_group_checks`), if the table has camera cases."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    done = table[table["status"] == RunStatus.COMPLETED] if "status" in table else table
    if done.empty:
        return
    cells = list(dict.fromkeys(zip(done["scenario"], done["surface"], done["vehicle"], strict=True)))
    bars = [  # a bar group per cell and steered unit: the first towed unit, then each further one the cell has
        (cell, prefix)
        for cell in cells
        for prefix in unit_prefixes(done.columns)
        if not prefix or _rows(done, cell)[prefix + "true_offtracking_rms_after_warmup_m"].notna().any()
    ]
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.5 + 0.3 * len(bars)), sharey=True)
    checks = []
    labels = (
        ("true_offtracking_rms_after_warmup_m", "RMS after warm-up"),
        ("true_offtracking_max_after_warmup_m", "max after warm-up"),
    )
    for ax, (column, title) in zip(axes, labels, strict=True):
        feedbacks = [f for f in (*FEEDBACKS, CAMERA_FEEDBACK, OPTIMAL) if f in set(done["feedback"])]
        for i, feedback in enumerate(feedbacks):
            values = []
            for cell, prefix in bars:
                match = _rows(done, cell)
                match = match[match["feedback"] == feedback][prefix + column]
                values.append(float(match.iloc[0]) if len(match) else float("nan"))
            width = 0.8 / len(feedbacks)
            ax.barh(
                [k + width * (i - (len(feedbacks) - 1) / 2) for k in range(len(bars))],
                values,
                height=width,
                label=feedback,
            )
        ax.set_xscale("log")
        ax.set_xlabel(f"true off-tracking, {title} [m]")
    axes[0].set_yticks(
        range(len(bars)), [f"{s}, {surface}, {v}" + (f", {p[:-1]}" if p else "") for (s, surface, v), p in bars]
    )
    axes[1].legend(title="steering", loc="lower right")
    fig.tight_layout()
    fig.savefig(out_dir / "controller_limits.png", dpi=120)
    plt.close(fig)
    every = list(dict.fromkeys(zip(table["scenario"], table["surface"], table["vehicle"], strict=True)))
    for cell in every:
        rows = {r["feedback"]: dict(r) for _, r in _rows(done, cell).iterrows()}
        check = truth_fed_check(rows)
        if check is not None:
            fused = {k: _plain(rows[CAMERA_FEEDBACK].get(k)) for k in CAMERA_COLUMNS} if CAMERA_FEEDBACK in rows else {}
            checks.append({"cell": list(cell), **check, **(optimal_gap(rows) or {}), **fused})
        elif "status" in table:  # a loop that did not complete (e.g. the unsteered combination jackknifed): said
            ended = {str(r["feedback"]): str(r["status"]) for _, r in _rows(table, cell).iterrows()}
            stopped = {f: v for f, v in ended.items() if v != RunStatus.COMPLETED and f in FEEDBACKS}
            if stopped:
                checks.append({"cell": list(cell), "held": None, "not_completed": stopped})
    checks += camera_group_checks(done)
    (out_dir / "controller_limits.json").write_text(json.dumps(checks, indent=1), encoding="utf-8")


def _plain(value: Any) -> Any:
    """A table's value as JSON writes it (NaN as ``null``)."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    try:
        number = float(value)
    except (TypeError, ValueError):
        return value
    return number if np.isfinite(number) else None


def camera_group_checks(table: pd.DataFrame) -> list[dict[str, Any]]:
    """The camera cells' checks (:func:`~scenarios.studies.controller_limits_camera.camera_check`): over all of
    them (``camera_group`` ``all``) and over each manoeuvre's (``camera_group`` the scenario), each with
    ``camera_group`` first, on the first towed unit's figures; then, for each further steered unit with camera
    figures (``unit<k>_…``), the same groups over its cells on its own rig's figures (``camera_group``
    ``unit <k>: all``, ``unit <k>: <scenario>``); empty without camera cases.

    Parameters
    ----------
    table
        The study's rows that did not fail.
    """
    if "feedback" not in table:
        return []
    camera = table[table["feedback"] == CAMERA_FEEDBACK]
    if camera.empty:
        return []
    out = []
    for prefix in unit_prefixes(camera.columns):
        if prefix:  # a further unit: its own rig's figures under the first unit's names, on the cells that have them
            own = [prefix + key for key in UNIT_CAMERA_KEYS]
            if not set(own) <= set(camera.columns):
                continue
            unit = camera.drop(columns=[k for k in UNIT_CAMERA_KEYS if k in camera.columns])
            unit = unit.rename(columns=dict(zip(own, UNIT_CAMERA_KEYS, strict=True)))
            unit = unit[unit[UNIT_CAMERA_KEYS[0]].notna()]
        else:
            unit = camera
        label = f"unit {prefix[4:-1]}: " if prefix else ""
        groups = {"all": unit, **{str(s): part for s, part in unit.groupby("scenario", sort=False)}}
        for name, part in groups.items():
            check = camera_check(part.to_dict("records"))
            if check is not None:
                out.append({"camera_group": label + name, **{k: _plain(v) for k, v in check.items()}})
    return out


def truth_fed_check(rows: dict[str, dict[str, Any]], tolerance: float = 0.0) -> dict[str, Any] | None:
    """The study's check on one cell: on every steered unit the truth-fed loop's RMS and max after warm-up are no more
    than the zero-slip-fed and the unsteered loop's (``tolerance`` [m] more allowed).

    Parameters
    ----------
    rows
        The cell's rows by feedback (``none``, ``truth``, ``zero_slip``); a combination's rows hold each further
        steered unit's figures as ``unit<k>_…`` (:mod:`scenarios.studies.controller_limits_units`).
    tolerance
        Allowance [m] on each comparison.

    Returns
    -------
    dict or None
        The truth-fed RMS and max, each comparison's result (the first towed unit's unprefixed, unit ``k``'s as
        ``unit<k>_…``; a figure missing from a row fails its comparison), ``not_within`` (the comparisons that
        failed) and ``held`` (all of them); ``None`` when a feedback's row is missing.
    """
    if not set(FEEDBACKS) <= rows.keys():
        return None
    out: dict[str, Any] = {}
    for prefix in unit_prefixes(k for row in rows.values() for k in row):
        rms = prefix + "true_offtracking_rms_after_warmup_m"
        if prefix and not any(np.isfinite(_figure(rows[f], rms)) for f in FEEDBACKS):
            continue  # a table's column of another vehicle's unit: not this cell's
        for figure in ("true_offtracking_rms_after_warmup_m", "true_offtracking_max_after_warmup_m"):
            column = prefix + figure
            truth = _figure(rows["truth"], column)
            out[column] = truth
            for other in ("zero_slip", "none"):
                within = truth <= _figure(rows[other], column) + tolerance  # False for a NaN on either side
                out[f"{prefix}{figure.split('_after')[0]}_within_{other}"] = bool(within)
    failed = [k for k, v in out.items() if "_within_" in k and not v]
    out["not_within"] = failed
    out["held"] = not failed
    return out


def _figure(row: dict[str, Any], column: str) -> float:
    """A row's figure as a float, NaN where the row has none."""
    value = row.get(column)
    try:
        return float(value) if value is not None else float("nan")
    except (TypeError, ValueError):
        return float("nan")


def optimal_gap(rows: dict[str, dict[str, Any]]) -> dict[str, Any] | None:
    """The truth-fed PID's gap to the cell's optimal reference, both replayed, after warm-up.

    The optimum's figure is its open-loop replay's true RMS after warm-up (``optimal_replay_rms_m``,
    :mod:`scenarios.studies.optimal_replay`: the schedule and the PID run's tractor inputs through the simulator,
    every tick, from the replay's own kingpin path), the PID's its run's on the same ticks and window; the gap is
    their ratio as ``optimal.json`` holds it (``pid_over_replay_rms_ratio``). Rows without the replay's figures
    (written before it) fall back on the NLP's nodes (``pid_nodes_rms_m`` over ``optimal_nlp_rms_m``), and rows
    without those on the co-simulation's replay run. Beside it: ``nodes_rms_ratio`` (the nodes' ratio, where the
    row has it) and ``replay_rms_ratio`` (the truth-fed RMS after warm-up over the co-simulation replay run's, the
    tractor's driver reacting to the schedule; a diagnostic).

    Parameters
    ----------
    rows
        The cell's rows by feedback (``truth`` and :data:`OPTIMAL` used).

    Returns
    -------
    dict or None
        ``pid_gap_rms_ratio``, ``reference_holds`` (the optimum's RMS ≤ :data:`REFERENCE_HOLDS` and no more than
        the PID's: a reference worse than the PID is none), ``gap_within_limit`` (the ratio ≤ :data:`GAP_LIMIT`,
        or ``None`` where the reference does not hold), ``replay_rms_ratio`` and ``nodes_rms_ratio``; the first
        three as ``unit<k>_…`` for each further steered unit whose figures the reference's row holds (on the NLP's
        nodes: the replay follows the first towed unit only); ``None`` without both rows.
    """
    if not {"truth", OPTIMAL} <= rows.keys():
        return None
    column = "true_offtracking_rms_after_warmup_m"
    optimum = rows[OPTIMAL]
    replay = float(rows["truth"][column]) / float(optimum[column]) if float(optimum[column]) > 0 else float("inf")
    nodes_pid, nodes_reference = _figure(optimum, "pid_nodes_rms_m"), _figure(optimum, "optimal_nlp_rms_m")
    nodes = nodes_pid / nodes_reference if nodes_reference > 0 else float("nan")
    replayed, replayed_ratio = _figure(optimum, "optimal_replay_rms_m"), _figure(optimum, "pid_over_replay_rms_ratio")
    if np.isfinite(replayed) and np.isfinite(replayed_ratio):
        ratio, reference = replayed_ratio, replayed
    elif np.isfinite(nodes_pid) and np.isfinite(nodes_reference):
        ratio, reference = (nodes if nodes_reference > 0 else float("inf")), nodes_reference
    else:
        ratio, reference = replay, float(optimum[column])
    holds = bool(reference <= REFERENCE_HOLDS and ratio >= 1.0)
    out: dict[str, Any] = {
        "pid_gap_rms_ratio": ratio,
        "reference_holds": holds,
        "gap_within_limit": ratio <= GAP_LIMIT if holds else None,
        "replay_rms_ratio": replay,
        "nodes_rms_ratio": nodes,
    }
    for prefix in unit_prefixes(k.replace("optimal_nlp_rms_m", "true_offtracking_rms_after_warmup_m") for k in optimum)[
        1:
    ]:
        unit_pid, unit_reference = (
            _figure(optimum, f"{prefix}pid_nodes_rms_m"),
            _figure(optimum, f"{prefix}optimal_nlp_rms_m"),
        )
        if np.isfinite(unit_pid) and np.isfinite(unit_reference):  # a further steered unit, by the same measure
            unit_ratio = unit_pid / unit_reference if unit_reference > 0 else float("inf")
            unit_holds = bool(unit_reference <= REFERENCE_HOLDS and unit_ratio >= 1.0)
            out[f"{prefix}pid_gap_rms_ratio"] = unit_ratio
            out[f"{prefix}reference_holds"] = unit_holds
            out[f"{prefix}gap_within_limit"] = unit_ratio <= GAP_LIMIT if unit_holds else None
    return out
