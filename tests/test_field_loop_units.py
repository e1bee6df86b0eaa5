"""The field-loop study on a combination: each steered unit in the rows, the verdict's flag names, the figures and
``table.md``.

Synthetic tables and metrics only (no simulation): a B-double's cells whose rear trailer (unit 3) has figures unlike
its lead trailer's, so a unit shown with another unit's figures is caught.
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest

from scenarios.studies.field_loop import FEEDBACKS, cell_table, metrics_columns, pooled_coverage
from scenarios.studies.field_loop_units import further_units_of, unit_view, verdict_flag_names
from scenarios.studies.figures_field_loop import coverage_axes, field_loop_figures, unit_panels

LEAD = {"viso_ot_fused": 0.136, "zero_slip": 0.023, "truth": 0.001}
"""The lead trailer's true RMS per feedback [m] (a biased fused estimate: fails)."""

REAR = {"viso_ot_fused": 0.016, "zero_slip": 0.028, "truth": 0.002}
"""The rear trailer's (unit 3) true RMS per feedback [m] (passes apart from its coverage)."""


def _b_double_table() -> pd.DataFrame:
    rows = []
    for seed, conditions in enumerate(("field", "ideal")):
        cell = {"scenario": "roundabout-3", "surface": "dry", "camber": 0.0, "conditions": conditions}
        cell.update(alignment="aligned", seed=seed)
        for feedback in FEEDBACKS:
            row = {**cell, "feedback": feedback, "status": "completed", "verdict_held": True, "verdict_flags": ""}
            row.update(true_offtracking_rms_after_warmup_m=LEAD[feedback], true_offtracking_max_after_warmup_m=0.2)
            row.update(unit3_true_rms_m=REAR[feedback], unit3_true_max_m=0.04, fallback_s=0.0, unit3_fallback_s=0.0)
            row.update(zero_slip_rms_error_m=0.016, unit3_zero_slip_rms_error_m=0.025)
            if feedback == "viso_ot_fused":
                row.update(fused_rms_error_m=0.135, fused_mean_error_m=-0.131, fused_within_2sigma=0.0)
                row.update(viso_ot_rms_error_m=0.141)
                row.update(unit3_fused_rms_error_m=0.015, unit3_fused_mean_error_m=-0.002)
                row.update(unit3_fused_within_2sigma=0.90 + 0.02 * seed, unit3_viso_ot_rms_error_m=0.048)
                row.update(verdict_held=False, verdict_flags="offtracking_above_target;unit 3: std_too_wide")
            rows.append(row)
    return pd.DataFrame(rows)


def test_the_verdicts_flags_are_named_with_their_unit() -> None:
    reason = "true off-tracking after warm-up 0.283 m RMS"
    metrics = {
        "verdict": {
            "held": False,
            "flags": [
                {"flag": "offtracking_above_target", "reason": "true off-tracking after warm-up 0.214 m RMS"},
                {"flag": "offtracking_above_target", "reason": f"unit 3: {reason}"},
            ],
        },
        "offtracking": {
            "units": {
                "3": {"verdict": {"held": False, "flags": [{"flag": "offtracking_above_target", "reason": reason}]}}
            }
        },
    }
    assert verdict_flag_names(metrics) == ["offtracking_above_target", "unit 3: offtracking_above_target"]
    assert metrics_columns(metrics)["verdict_flags"] == "offtracking_above_target;unit 3: offtracking_above_target"
    assert verdict_flag_names({"verdict": {"held": True, "flags": []}}) == [] and verdict_flag_names({}) == []


def test_a_units_view_holds_its_own_figures_and_none_of_the_lead_trailers() -> None:
    table = _b_double_table()
    cells = cell_table(table)
    assert further_units_of(table) == [3] and further_units_of(cells) == [3]  # cell columns are found too
    rear = unit_view(cells, 3, ("scenario", "seed"))
    assert rear["viso_ot_fused_true_rms_m"].tolist() == [REAR["viso_ot_fused"]] * 2
    assert rear["viso_ot_rms_error_m"].tolist() == [0.048] * 2 and rear["verdict"].tolist() == ["std_too_wide"] * 2
    assert "fused_within_2sigma" not in rear and "conditions" not in rear  # no lead column stands in for the unit's
    assert cells["unit3_acceptance"].tolist() == ["pass"] * 2
    assert [p for p, _ in unit_panels(cells)] == ["unit 2: ", "unit 3: "]
    assert [p for p, _ in unit_panels(cells.drop(columns=[c for c in cells if "unit3" in c]))] == [""]
    pooled = pooled_coverage(cells).set_index("group")
    assert pooled.loc["unit 3: all", "mean"] == pytest.approx(0.91, abs=1e-12)
    assert pooled.loc["unit 2: all", "mean"] == 0.0


def test_every_unit_has_its_panels_and_its_table_of_cells(tmp_path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = _b_double_table()
    fig = coverage_axes(cell_table(table), plt)
    try:
        assert [ax.get_ylabel().split(":")[0] for ax in fig.axes] == ["unit 2", "unit 3"]
        values = [[t.get_text() for t in ax.texts if t.get_gid() == "coverage:value"] for ax in fig.axes]
        assert values == [["0 %", "0 %"], ["90 %", "92 %"]]
    finally:
        plt.close(fig)
    field_loop_figures(table, tmp_path)
    text = (tmp_path / "table.md").read_text()
    unit3 = text[text.index("### unit 3") : text.index("Fused errors within 2σ")]
    row = "| roundabout-3 | dry | 0 | field | aligned | 0 | 0.016 / 0.040 | 0.028 / 0.040 | 0.002 / 0.040 |"
    assert row + " 0.015 / -0.002 | 0.048 | 90 | 0.0 | std_too_wide | pass |" in unit3
    assert "### unit 2" in text and "| unit 3: field, aligned | 1 | 90.0 |" in text
    for name in ("field_loop_offtracking.png", "field_loop_coverage.png", "field_loop_errors.png"):
        assert (tmp_path / name).stat().st_size > 0


def test_a_unit_the_run_does_not_steer_is_judged_on_its_coverage_alone() -> None:
    from scenarios.studies.field_loop_units import unit_columns

    units = {"3": {"rms_after_warmup": 0.3}, "4": {"rms_after_warmup": 0.02}}  # an A-double's dolly, rear trailer
    row = unit_columns({"offtracking": {"units": units}, "rear_feedback": ["none", "viso_ot_fused"]})
    assert (row["unit3_steered"], row["unit4_steered"]) == (0.0, 1.0)
    assert math.isnan(unit_columns({"offtracking": {"units": units}})["unit3_steered"])  # not said
    table = _b_double_table()
    table["unit3_true_rms_m"] = 0.3  # far beyond the target under every feedback
    steered = cell_table(table)
    assert steered["unit3_acceptance"].str.startswith("RMS 0.300 > 0.10 m").all()
    table["unit3_steered"] = 0.0
    unsteered = cell_table(table)
    assert (
        unsteered["unit3_acceptance"].tolist() == ["pass"] * 2
        and unsteered["unit3_verdict"].tolist() == ["not steered"] * 2
    )
    assert [p for p, _ in unit_panels(unsteered)] == ["unit 2: ", "unit 3, not steered: "]
    table["unit3_fused_within_2sigma"] = 0.5
    assert cell_table(table)["unit3_acceptance"].tolist() == ["coverage 50 % outside 85–98 %"] * 2
