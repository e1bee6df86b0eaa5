"""The files of an assessment (``offtrack assess``): ``assessment.md``, ``.csv``, ``.json`` and a figure per measure.

``assessment.md`` opens with the combination's specification (:mod:`scenarios.catalogue.vehicle_spec`), says once
whether the values are graded and with whose levels (:mod:`scenarios.assess.user_levels`), gives a table per
surface (a row per measure, a column per feedback, each cell the value and its grade with the clause of the level
met), compares each steered column with the unsteered one at speed, lists the standards a yaw-plane model cannot
assess with the reason, and gives the notes of each measure once for what every column shares and then per column,
each labelled with its surface and feedback.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vehicle_model.parameters import VehicleParams

from ..assess.high_speed import MEASURES, unassessable_records
from ..assess.levels import NO_LEVELS
from ..assess.user_levels import ASSESSED, NOT_ASSESSED, UserLevels, grade_record, standard_key
from ..catalogue.vehicle_spec import specification_lines, vehicle_specification
from ..config import ControllerConfig
from ..loop.ends import RunStatus
from ..registry import NO_FEEDBACK
from ..run.results import read_metrics

__all__ = [
    "AT_SPEED",
    "assessment_records",
    "column_notes",
    "steering_at_speed",
    "strict_records",
    "write_assessment",
]

AT_SPEED = ("rearward_amplification", "high_speed_transient_offtracking", "yaw_damping_coefficient")
"""The high-speed measures each steered column is compared on with the unsteered one (:func:`steering_at_speed`)."""
NOTE_SEPARATOR = "; "
"""Between the parts of a record's note."""


def _finite(value: Any) -> bool:
    try:
        return value is not None and math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def strict_records(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """``records`` with every value that is not a finite number given as None and a ``value_reason`` saying why,
    so that the JSON written holds no ``NaN`` (strict parsers reject it)."""
    out = []
    for record in records:
        record = dict(record)
        for key in ("value", "margin", "margin_level_1"):
            value = record.get(key)
            if isinstance(value, float) and not math.isfinite(value):
                record[key] = None
                if key == "value":
                    record["value_reason"] = f"no finite value: {record.get('note') or 'the run gave none'}"
        out.append(record)
    return out


def _json_ready(value: Any) -> Any:
    """A value of a records frame as strict JSON takes it: NaN → None, numpy scalars → Python's."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def assessment_records(
    table: pd.DataFrame, levels: UserLevels | None = None, length: float | None = None
) -> pd.DataFrame:
    """One row per record of every case that gave records, with its case's labels and its grade, and the
    not-assessed measures.

    Parameters
    ----------
    table
        One row per case (``manoeuvre``, ``feedback``, ``surface``, ``status``, ``run``, ``records`` as JSON).
    levels
        The user's levels (:func:`scenarios.assess.user_levels.load_levels`); None: no levels given.
    length
        The combination's overall length [m], for limits given by length band.
    """
    rows = []
    for case in table.to_dict("records"):
        for record in json.loads(case.get("records") or "[]"):
            record = grade_record(record, levels, length)
            record = {**record, "measure": str(record["measure"]).replace("_", " ")}
            rows.append({k: case[k] for k in ("manoeuvre", "feedback", "surface", "status", "run")} | record)
    for surface in dict.fromkeys(table["surface"]):
        for feedback in dict.fromkeys(table["feedback"]):
            for record in unassessable_records():
                labels = {"manoeuvre": "—", "feedback": feedback, "surface": surface, "status": "—", "run": ""}
                rows.append(labels | record | {"threshold_source": "not assessed", "grade": "not assessed"})
    return pd.DataFrame(rows)


def _number(value: Any) -> str:
    return f"{float(value):.3f}" if _finite(value) else "—"


def _cell(r: pd.Series, graded: bool) -> str:
    """One table cell: the value, why there is none, and its grade."""
    text = _number(r["value"])
    if text == "—" and r["status"] not in ("—", RunStatus.COMPLETED):
        text += f" (run {str(r['status']).replace('_', ' ')})"
    level = r.get("level")
    if level is None or (isinstance(level, float) and math.isnan(level)):
        return text
    if level in ("pass", "fail"):  # the turning circle
        return f"{text} ({level}, margin {_number(r['margin'])})"
    if graded and isinstance(r.get("grade"), str):
        margin = f", margin {_number(r['margin'])}" if _finite(r.get("margin")) else ""
        return f"{text}: {r['grade']}{margin}"
    return text


def _labels(surfaces: list[str], feedbacks: list[str]) -> dict[tuple[str, str], str]:
    """How a note names its column: ``surface, feedback`` (only the one that varies, when the other does not)."""
    out = {}
    for s in surfaces:
        for f in feedbacks:
            parts = ([s] if len(surfaces) > 1 else []) + ([f] if len(feedbacks) > 1 else [])
            out[(s, f)] = ", ".join(parts) or "the one column"
    return out


def column_notes(rows: pd.DataFrame, labels: dict[tuple[str, str], str]) -> list[str]:
    """The notes of one measure as Markdown list items: the parts every column shares once, then each column's own
    parts labelled with its surface and feedback.

    Parameters
    ----------
    rows
        The measure's records (``surface``, ``feedback``, ``note``).
    labels
        Each column's label by ``(surface, feedback)`` (:func:`_labels`).
    """
    cells = [
        (labels[(r["surface"], r["feedback"])], [p for p in str(r["note"] or "").split(NOTE_SEPARATOR) if p])
        for r in rows.to_dict("records")
    ]
    shared = [p for p in cells[0][1] if all(p in parts for _, parts in cells)] if cells else []
    lines = [f"  - every column: {NOTE_SEPARATOR.join(shared)}"] if shared and len(cells) > 1 else []
    if len(cells) == 1 and shared:
        return [f"  - {cells[0][0]}: {NOTE_SEPARATOR.join(shared)}"]
    for label, parts in cells:
        own = [p for p in parts if p not in shared]
        if own:
            lines.append(f"  - {label}: {NOTE_SEPARATOR.join(own)}")
    return lines


def _why_none(rows: pd.DataFrame, feedback: str) -> str:
    """Why ``feedback``'s record in ``rows`` (indexed by feedback) has no value: the first clause of its note."""
    return str(rows.loc[feedback, "note"] or "").split(":")[0].replace("_", " ").strip()


def _compared(measure: str, rows: pd.DataFrame, steered: list[str]) -> tuple[str, dict[str, str]]:
    """One row of the steering comparison (``rows``: the measure's records by feedback, the unsteered among them)
    and what each steered column does to the measure, in words."""
    better = MEASURES[str(standard_key(measure))].better
    base = rows.loc[NO_FEEDBACK, "value"]
    base_cell = _number(base) if _finite(base) else f"— ({_why_none(rows, NO_FEEDBACK)})"
    cells, said = [], {}
    for f in steered:
        value = rows.loc[f, "value"] if f in rows.index else None
        if not _finite(value):
            reason = _why_none(rows, f) if f in rows.index else "not run"
            cells.append(f"— ({reason})")
            said[f] = f"gives no {measure} ({reason})"
        elif not _finite(base):
            cells.append(f"{float(value):.3f} (nothing to compare)")
            said[f] = f"gives a {measure} where the unsteered run gave none ({_why_none(rows, NO_FEEDBACK)})"
        else:
            change = float(value) - float(base)
            worse = change > 0.0 if better == "lower" else change < 0.0
            word = "same" if change == 0.0 else ("worse" if worse else "better")
            relative = f"{100.0 * change / abs(float(base)):+.0f} %, " if float(base) != 0.0 else ""
            cells.append(f"{float(value):.3f} ({relative}{word})")
            if word != "same":
                said[f] = f"{'raises' if change > 0 else 'lowers'} the {measure} ({word})"
    arrow = "lower is better" if better == "lower" else "higher is better"
    return f"| {measure} ({arrow}) | {base_cell} | " + " | ".join(cells) + " |", said


def steering_at_speed(records: pd.DataFrame) -> list[str]:
    """Markdown comparing each steered column with the unsteered one on the high-speed measures (:data:`AT_SPEED`),
    per surface: the values, the change and whether it is better or worse, then in words what steering does there."""
    feedbacks = list(dict.fromkeys(records["feedback"]))
    steered = [f for f in feedbacks if f != NO_FEEDBACK]
    if not steered:
        return []
    lines = ["## Steering against unsteered at speed", ""]
    if NO_FEEDBACK not in feedbacks:
        return [*lines, "No unsteered column to compare with: add `--feedback none` (or `--side-by-side`).", ""]
    crossover = ControllerConfig().high_speed_crossover_kmh
    fade = (
        "The trailer steering follows the path at every speed (the high-speed fade is off)."
        if crossover is None
        else f"Path following fades out between {crossover[0]:g} and {crossover[1]:g} km/h "
        "(`controller.high_speed_crossover_kmh`, docs/controller_design.md): at 88 km/h a steered column runs "
        "unsteered unless its cases turn the fade off."
    )
    lines += [
        f"{fade} Here each steered column against the unsteered one in the 88 km/h manoeuvres; a change is worse "
        "when it moves the measure the way the standard does not want (rearward amplification and transient "
        "off-tracking up, yaw damping down).",
        "",
    ]
    names = [MEASURES[k].measure for k in AT_SPEED]
    for surface in dict.fromkeys(records["surface"]):
        part = records[(records["surface"] == surface) & (records["measure"].isin(names))]
        if part.empty:
            continue
        lines += [f"### {surface}", "", "| measure | unsteered | " + " | ".join(steered) + " |"]
        lines.append("|---|---|" + "---|" * len(steered))
        verdicts: dict[str, list[str]] = {f: [] for f in steered}
        for measure in names:
            rows = part[part["measure"] == measure].set_index("feedback")
            if NO_FEEDBACK not in rows.index:
                continue
            line, said = _compared(measure, rows, steered)
            lines.append(line)
            for f, words in said.items():
                verdicts[f].append(words)
        lines.append("")
        for f in steered:
            if verdicts[f]:
                lines.append(f"- {surface}, steered on {f}, against unsteered: {'; '.join(verdicts[f])}.")
        lines.append("")
    return lines


def _levels_statement(levels: UserLevels | None, records: pd.DataFrame) -> list[str]:
    if levels is None:
        return [
            f"**{NO_LEVELS.capitalize()}** (`offtrack assess ... --levels FILE.yaml`): the PBS values are not graded. "
            "offtrack holds no PBS threshold: the rules' tables of levels could not be read here and none is "
            "written from memory. Fill docs/pbs_levels_template.yaml in from your copy of the rules to grade them "
            "(docs/pbs.md).",
            "",
        ]
    measured = [m for m in dict.fromkeys(records["measure"]) if standard_key(m) is not None]
    missing = [m for m in measured if levels.standard(str(standard_key(m))) is None]
    lines = [
        f"Graded with the levels of `{levels.source}`, quoted from: {levels.document}. Each graded cell gives the "
        "best level the value meets and that level's clause as the file cites it (or, when no level is met, the "
        "least demanding level's limit and clause), and the margin to that limit.",
    ]
    if missing:
        lines.append(f"The file gives no limit for: {', '.join(missing)} (not graded).")
    return [*lines, ""]


def _not_assessed() -> list[str]:
    lines = ["## What a yaw-plane model cannot assess", ""]
    lines += [
        "The model moves each unit in the road plane only (no roll, pitch or bounce; both tyres of an axle carry "
        "one load; a drive-force demand rather than an engine), so these standards are not assessed:",
        "",
    ]
    lines += [f"- **{key.replace('_', ' ')}**: {reason}." for key, reason in NOT_ASSESSED.items()]
    return [*lines, ""]


def write_assessment(
    table: pd.DataFrame,
    out_dir: Path,
    vehicle: str,
    plot_format: str = "png",
    *,
    params: VehicleParams | None = None,
    kinds: tuple[str, ...] | None = None,
    levels: UserLevels | None = None,
) -> Path:
    """Write ``assessment.json``, ``assessment.csv``, ``assessment.md`` and a figure per measure into ``out_dir``.

    Parameters
    ----------
    table
        One row per finished case (:func:`assessment_records`).
    out_dir
        Where to write.
    vehicle
        The combination's name.
    plot_format
        ``png``, ``svg`` or ``pdf``.
    params, kinds
        The combination and its units' kinds, for the specification the assessment opens with (none without).
    levels
        The user's levels; None: the values are not graded and the assessment says so once.

    Returns
    -------
    pathlib.Path
        ``assessment.md``.
    """
    spec = None if params is None else vehicle_specification(params, kinds)
    records = assessment_records(table, levels, None if spec is None else spec.overall_length)
    as_dicts = [{k: _json_ready(v) for k, v in r.items()} for r in records.to_dict("records")]
    document = {"vehicle": vehicle, "levels": None if levels is None else levels.source, "records": as_dicts}
    (out_dir / "assessment.json").write_text(json.dumps(document, indent=2, allow_nan=False) + "\n")
    records.to_csv(out_dir / "assessment.csv", index=False)
    feedbacks = list(dict.fromkeys(records["feedback"]))
    surfaces = list(dict.fromkeys(records["surface"]))
    lines = [f"# Assessment of {vehicle}", ""]
    if spec is not None:
        lines += ["## The combination", "", *specification_lines(spec)]
    lines += [
        "Each cell: the measured value, then its grade (`pass`/`fail` and the margin for the UK/EU turning circle, "
        "97/27/EC Annex I §7.6.1 and UK C&U reg. 13A); a run that did not complete its manoeuvre (lost control, "
        "diverged) gives no value and says so. Measured by `offtrack assess`; each case's run directory holds its "
        "time series, metrics and plots.",
        "",
        *_levels_statement(levels, records),
    ]
    not_assessed = set(records.loc[records["manoeuvre"] == "—", "measure"])
    graded = levels is not None
    for surface in surfaces:
        part = records[(records["surface"] == surface) & ~records["measure"].isin(not_assessed)]
        lines += [f"## Surface: {surface}", "", "| measure | unit | " + " | ".join(feedbacks) + " |"]
        lines.append("|---|---|" + "---|" * len(feedbacks))
        for measure in dict.fromkeys(part["measure"]):
            rows = part[part["measure"] == measure]
            cells = []
            for feedback in feedbacks:
                match = rows[rows["feedback"] == feedback]
                cells.append("" if match.empty else _cell(match.iloc[0], graded))
            lines.append(f"| {measure} | {rows.iloc[0]['unit']} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += steering_at_speed(records)
    lines += _not_assessed()
    lines += run_notes_section(table, out_dir)
    lines += ["## Notes", "", "Each measure's notes: first what every column shares, then each column's own.", ""]
    labels = _labels(surfaces, feedbacks)
    measured = records[~records["measure"].isin(not_assessed)]
    for measure in dict.fromkeys(measured["measure"]):
        rows = measured[measured["measure"] == measure]
        key = standard_key(measure)
        definition = f": {ASSESSED[key].definition}" if key is not None else ""
        lines += [f"- **{measure}**{definition}", *column_notes(rows, labels)]
    lines.append("")
    path = out_dir / "assessment.md"
    path.write_text("\n".join(lines))
    length = None if spec is None else spec.overall_length
    _measure_figures(records[~records["measure"].isin(not_assessed)], out_dir, plot_format, levels, length)
    return path


NEGATIVE_MEANS = {
    "frontal_swing": "below 0: the corner stays inside the path it is measured against (no swing out)",
    "frontal_swing_max_of_difference": "below 0: the towed unit's front corner stays inside the prime mover's",
    "frontal_swing_difference_of_maxima": "below 0: the towed unit's front corner stays inside the prime mover's",
    "tail_swing": "below 0: the rear corner moves inward, not out",
}
"""What a negative value of a measure means, said on its figure when a bar goes below zero."""


def measure_figure(rows: pd.DataFrame, surfaces: list[str], levels: UserLevels | None, length: float | None) -> Any:
    """The bar chart of one measure (the caller saves and closes it): its value per feedback, a bar per surface.

    Every bar carries its value (``gid`` ``value``); a case without a value gets an empty hatched bar and the reason
    (``gid`` ``no-value``) instead of vanishing; the user's level limits are drawn and labelled with their clauses
    (``gid`` ``limit:<level>``), and a turning circle's pass or fail is written on its bar; a negative bar is
    explained (:data:`NEGATIVE_MEANS`).
    """
    import matplotlib.pyplot as plt

    measure = str(rows.iloc[0]["measure"])
    feedbacks = list(dict.fromkeys(rows["feedback"]))
    fig, ax = plt.subplots(figsize=(2.6 + 1.4 * len(feedbacks) * max(1, len(surfaces)) ** 0.5, 3.6))
    width = 0.8 / len(surfaces)
    values_all = pd.to_numeric(rows["value"], errors="coerce")
    scale = float(np.nanmax(np.abs(values_all))) if values_all.notna().any() else 1.0
    labelled: set[str] = set()
    for i, surface in enumerate(surfaces):
        x = np.arange(len(feedbacks)) + (i - (len(surfaces) - 1) / 2) * width
        for xi, feedback in zip(x, feedbacks, strict=True):
            match = rows[(rows["feedback"] == feedback) & (rows["surface"] == surface)]
            if match.empty:
                continue
            row = match.iloc[0]
            value = pd.to_numeric(pd.Series([row["value"]]), errors="coerce").iloc[0]
            if pd.isna(value):
                ax.bar(xi, 0.05 * scale, width, fill=False, hatch="//", edgecolor="0.5", gid="no-value")
                status = str(row.get("status", "")).replace("_", " ")
                why = f"no value: run {status}" if status not in ("", "—", RunStatus.COMPLETED) else "no value"
                ax.annotate(
                    why,
                    (xi, 0.05 * scale),
                    xytext=(0, 3),
                    textcoords="offset points",
                    ha="center",
                    va="bottom",
                    fontsize=7,
                    rotation=90,
                    gid="no-value",
                )
                continue
            ax.bar(xi, float(value), width, color=f"C{i}", label=None if surface in labelled else surface)
            labelled.add(surface)
            level = row.get("level")
            text = f"{float(value):.3f}"
            if level in ("pass", "fail"):
                text += f"\n{str(level).upper()}"
            elif isinstance(level, (int, np.integer)) or (isinstance(level, float) and not math.isnan(level)):
                text += f"\nlevel {int(level)}"
            elif level == "none":
                text += "\nno level"
            ax.annotate(
                text,
                (xi, float(value)),
                xytext=(0, 2 if value >= 0 else -2),
                textcoords="offset points",
                ha="center",
                va="bottom" if value >= 0 else "top",
                fontsize=7,
                gid="value",
            )
    key = standard_key(measure)
    standard = None if levels is None or key is None else levels.standard(key)
    if standard is not None:
        for threshold in standard.applicable(length):
            ax.axhline(
                threshold.limit,
                color="0.3",
                lw=0.8,
                ls=("-", "--", "-.", ":")[(threshold.level - 1) % 4],
                label=f"level {threshold.level} limit ({threshold.clause})",
                gid=f"limit:{threshold.level}",
            )
    if values_all.notna().any() and float(np.nanmin(values_all)) < 0.0:
        ax.axhline(0.0, color="k", lw=0.6)
        ax.text(
            0.01,
            0.01,
            NEGATIVE_MEANS.get(key or "", "below 0: the measure's sense reversed"),
            transform=ax.transAxes,
            fontsize=7,
            va="bottom",
            ha="left",
            gid="negative",
        )
    ax.set_xticks(np.arange(len(feedbacks)), feedbacks)
    unit = rows.iloc[0]["unit"]
    ax.set_ylabel(f"{measure} [{unit}]" if unit != "-" else measure)
    ax.set_title(measure if standard is not None or levels is None else f"{measure} (no level limit given)")
    ax.margins(y=0.25)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, title="surface / limits" if standard is not None else "surface")
    fig.tight_layout()
    return fig


def run_notes_section(table: pd.DataFrame, out_dir: Path) -> list[str]:
    """``## What the runs said``: the notes each case's run wrote (``metrics.json["notes"]``,
    :mod:`scenarios.run.notes`: e.g. why a zero-slip estimate is off where fixed axle groups scrub), labelled by
    case; nothing when no run wrote one."""
    lines = []
    for case in table.to_dict("records"):
        metrics = read_metrics(Path(out_dir) / str(case.get("run", ""))) or {}
        for note in metrics.get("notes") or ():
            label = f"{case['manoeuvre']}, {case['surface']}, {case['feedback']}"
            lines.append(f"- {label.replace('_', ' ')}: {note.get('text')}")
    if not lines:
        return []
    return ["## What the runs said", "", *lines, ""]


def _measure_figures(
    records: pd.DataFrame,
    out_dir: Path,
    plot_format: str,
    levels: UserLevels | None = None,
    length: float | None = None,
) -> None:
    """One bar chart per measure (:func:`measure_figure`), ``measure-<name>.<format>``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    surfaces = list(dict.fromkeys(records["surface"]))
    for measure in dict.fromkeys(records["measure"]):
        rows = records[records["measure"] == measure]
        fig = measure_figure(rows, surfaces, levels, length)
        name = "".join(c if c.isalnum() else "-" for c in measure).strip("-")
        fig.savefig(out_dir / f"measure-{name}.{plot_format}", dpi=110)
        plt.close(fig)
