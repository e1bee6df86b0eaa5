"""The user's PBS levels (scenarios/assess/user_levels.py) and the assessment written with them.

* The template in the docs lists exactly the standards the assessment measures, each with its unit and direction and
  empty thresholds, and is the program's own template text; it loads as a valid file that grades nothing.
* Every fault of a levels file is refused in one line naming the field (each injected here): an unknown standard, one
  a yaw-plane model cannot assess (with the reason), a unit or direction not the standard's, a limit that is not a
  finite number, out of range or without its clause, a level that is not 1–4, overlapping length bands, levels that
  are not monotone, a missing document, an unknown field; and ``offtrack assess --levels`` exits 2 before any work.
* Grading with the example file (made-up limits, not PBS values): each value just inside and just outside a limit
  gets the right level and margin, in the file's unit (mm) and by the combination's length band, and cites the
  clause of the level met.
* ``assessment.md`` from synthetic case rows (no simulation): it opens with the combination's specification (axle
  loads summing to its weight), says "no levels given" once when none are, never "threshold not verified", states
  the turning circle's result in its note without contradicting the cell, labels each note with its column,
  compares steering with unsteered at speed, and lists what a yaw-plane model cannot assess; ``offtrack list
  --vehicle FILE`` prints the axle-group loads.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pandas as pd
import pytest

from scenarios.assess.levels import NO_LEVELS
from scenarios.assess.user_levels import (
    ASSESSED,
    NOT_ASSESSED,
    grade_record,
    load_levels,
    parse_levels,
    template_text,
)
from scenarios.catalogue.vehicle_spec import vehicle_specification
from scenarios.studies.assessment_report import write_assessment
from scenarios.studies.pbs_assessment import _turning_circle_records
from scenarios.yaml_input import load_yaml
from vehicle_model.errors import InputError
from vehicle_model.parameters import GRAVITY
from vehicle_model.presets import vehicle_preset

REPO = Path(__file__).resolve().parents[1]
TEMPLATE = REPO / "docs" / "pbs_levels_template.yaml"
EXAMPLE = Path(__file__).parent / "data" / "pbs_levels_example.yaml"
"""Made-up limits that exercise the grading: NOT PBS values."""


@pytest.fixture(scope="module")
def example():
    return load_levels(EXAMPLE)


def _example_data() -> dict:
    return load_yaml(EXAMPLE.read_bytes(), "example")


# ------------------------------------------------------------------------------------------------- the template


def test_the_template_lists_exactly_the_standards_assessed_with_empty_thresholds() -> None:
    text = TEMPLATE.read_text()
    assert text == template_text()  # the docs' copy is the program's
    data = load_yaml(text, "template")
    assert set(data["standards"]) == set(ASSESSED)
    assert not set(data["standards"]) & set(NOT_ASSESSED)
    for key, spec in data["standards"].items():
        assert spec["unit"] == ASSESSED[key].unit
        assert spec["direction"] == ("maximum" if ASSESSED[key].better == "lower" else "minimum")
        assert set(spec["levels"]) == {1, 2, 3, 4}
        assert all(level["limit"] is None for level in spec["levels"].values())
    assert parse_levels(data, "template").standards == {}  # valid, and grades nothing


# --------------------------------------------------------------------------------------------------- the checks


def _set(path: str, value):
    def mutate(data: dict) -> None:
        *parents, last = path.split(".")
        node = data
        for part in parents:
            node = node[int(part) if part.isdigit() else part]
        node[int(last) if last.isdigit() else last] = value

    return mutate


def _drop_document(data: dict) -> None:
    del data["document"]


def _add(key: str, spec):
    def mutate(data: dict) -> None:
        data["standards"][key] = spec

    return mutate


@pytest.mark.parametrize(
    ("mutate", "expected"),
    [
        (_add("tail_swnig", {}), "standards.tail_swnig: not a standard the assessment measures; did you mean"),
        (_add("static_rollover_threshold", {}), "standards.static_rollover_threshold: not assessed by offtrack: "),
        (_set("standards.tail_swing.unit", "in"), "standards.tail_swing.unit: 'in'; the tail_swing is given in m or"),
        (_set("standards.rearward_amplification.unit", "m"), "standards.rearward_amplification.unit: 'm'"),
        (_set("standards.yaw_damping_coefficient.direction", "maximum"), "yaw_damping_coefficient.direction: "),
        (_set("standards.tail_swing.direction", "minimum"), "give maximum"),
        (_set("standards.tail_swing.levels.2.limit", 50), "levels.2.limit: 50 is more demanding than level 1's 100 mm"),
        (_set("standards.yaw_damping_coefficient.levels.2.limit", 0.4), "a minimum must not rise"),
        (_set("standards.tail_swing.levels.1.limit", float("nan")), "levels.1.limit: nan is not a finite number"),
        (_set("standards.tail_swing.levels.1.limit", "0.1"), "levels.1.limit: '0.1' is not a finite number"),
        (_set("standards.yaw_damping_coefficient.levels.1.limit", 1.5), "1.5 - is outside [0, 1] -"),
        (_set("standards.tail_swing.levels.1.limit", -100), "-100 mm is outside [0, 5000] mm"),
        (_set("standards.tail_swing.levels.1.clause", " "), "standards.tail_swing.levels.1.clause: give the clause"),
        (_set("standards.tail_swing.levels.5", {"limit": 1, "clause": "x"}), "levels.5: not a level"),
        (_set("standards.tail_swing.levels.1.lmit", 1), "standards.tail_swing.levels.1.lmit: not a field"),
        (_set("standards.tail_swing.colour", 1), "standards.tail_swing.colour: not a field"),
        (_set("standards.low_speed_swept_path.levels.1.1.min_length_m", 19.0), "length bands overlap at 19 m"),
        (_set("standards.low_speed_swept_path.levels.1.0.max_length_m", -1.0), "min_length_m: 0 m must be ≥ 0"),
        (_drop_document, "document: give the rules' title and version"),
        (_set("standards", ["tail_swing"]), "standards: give a mapping"),
    ],
)
def test_a_faulty_levels_file_is_refused_in_one_line_naming_the_field(mutate, expected: str) -> None:
    data = copy.deepcopy(_example_data())
    mutate(data)
    with pytest.raises(InputError) as caught:
        parse_levels(data, "levels.yaml")
    text = str(caught.value)
    assert text.startswith("levels.yaml: ") and expected in text and "\n" not in text, text


def test_a_missing_levels_file_is_refused(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"levels file .*nope.yaml does not exist; start from docs/pbs_levels_temp"):
        load_levels(tmp_path / "nope.yaml")


def test_assess_refuses_a_bad_levels_file_with_exit_code_2_before_any_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Through main() in this process (the exit code a process gets from it is tested in test_faults.py).
    from test_faults import offtrack_in_process

    bad = tmp_path / "levels.yaml"
    bad.write_text(EXAMPLE.read_text().replace("direction: minimum", "direction: maximum"))
    command = ("assess", "reference", "--levels", str(bad), "--out", str(tmp_path / "a"))
    result = offtrack_in_process(monkeypatch, capsys, *command)
    assert result.returncode == 2, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "yaw_damping_coefficient.direction" in result.stderr
    assert not (tmp_path / "a").exists()


# -------------------------------------------------------------------------------------------------- the grading


def _record(measure: str, value, unit: str = "m") -> dict:
    return {"measure": measure, "value": value, "unit": unit, "level": None, "margin": None, "note": "x"}


@pytest.mark.parametrize(
    ("measure", "value", "length", "level", "margin", "clause"),
    [
        ("tail_swing", 0.0999, 19.0, 1, 0.0001, "example cl. B1"),  # limits given in mm: 100 and 300
        ("tail_swing", 0.1001, 19.0, 2, 0.1999, "example cl. B2"),
        ("tail_swing", 0.3001, 19.0, "none", -0.0001, "example cl. B2"),
        ("low_speed_swept_path", 6.1, 19.0, 2, 0.5, "example cl. A2"),  # level 1 is 6.0 m below 20 m long
        ("low_speed_swept_path", 6.1, 25.0, 1, 0.2, "example cl. A1 (long)"),  # and 6.3 m from 20 m
        ("low_speed_swept_path", 7.0, 19.0, 4, 0.5, "example cl. A4"),  # level 3 left at null
        ("yaw damping coefficient", 0.31, 19.0, 1, 0.01, "example cl. D1"),  # a minimum
        ("yaw damping coefficient", 0.25, 19.0, 2, 0.05, "example cl. D2"),
        ("yaw damping coefficient", 0.19, 19.0, "none", -0.01, "example cl. D2"),
    ],
)
def test_grading_gives_the_best_level_met_and_cites_its_clause(
    example, measure: str, value: float, length: float, level, margin: float, clause: str
) -> None:
    graded = grade_record(_record(measure, value), example, length)
    assert graded["level"] == level
    assert graded["margin"] == pytest.approx(margin, abs=1e-9)
    if level == 1:
        assert graded["margin_level_1"] == pytest.approx(margin, abs=1e-9)
    else:
        assert graded["margin_level_1"] < 0.0  # short of level 1
    assert clause in graded["grade"] and graded["threshold_source"].endswith(clause)
    assert graded["threshold_source"].startswith("EXAMPLE ONLY")


def test_without_levels_or_without_a_limit_nothing_is_graded(example) -> None:
    assert grade_record(_record("tail_swing", 0.2), None, 19.0)["grade"] == NO_LEVELS
    graded = grade_record(_record("frontal_swing", 0.2), example, 19.0)
    assert graded["level"] is None and "gives no limit" in graded["grade"]
    assert grade_record(_record("yaw damping coefficient", None), example, 19.0)["level"] is None
    turning = _record("turning circle: inner radius", 5.0) | {"level": "fail"}
    assert grade_record(turning, example, 19.0) == turning  # not a PBS standard: its own verdict stays


# ------------------------------------------------------------------------------------------------ the report


def _case(manoeuvre: str, feedback: str, records: list[dict]) -> dict:
    return {
        "manoeuvre": manoeuvre,
        "feedback": feedback,
        "surface": "dry",
        "status": "completed",
        "run": f"{manoeuvre}-{feedback}",
        "records": json.dumps(records),
    }


def _table() -> pd.DataFrame:
    rows = []
    for feedback, tail, ra, zeta, inner in (("none", 0.276, 1.09, 0.47, 4.859), ("truth", 0.038, 1.25, 0.27, 5.79)):
        rows.append(
            _case("low_speed_turn", feedback, [_record("tail_swing", tail) | {"note": f"per unit {tail}; same"}])
        )
        circle = {"roundabout_test": {"outer_radius_max": 12.4, "inner_radius_min": inner, "inner_unit": 2}}
        rows.append(_case("turning_circle", feedback, _turning_circle_records(circle)))
        rows.append(_case("lane_change", feedback, [_record("rearward amplification", ra, "-")]))
        rows.append(_case("pulse_steer", feedback, [_record("yaw damping coefficient", zeta, "-")]))
    return pd.DataFrame(rows)


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory, example) -> dict[str, str]:
    out = {}
    params = vehicle_preset("lst")
    for name, levels in (("plain", None), ("graded", example)):
        where = tmp_path_factory.mktemp(name)
        path = write_assessment(_table(), where, "lst", params=params, kinds=("tractor", "semi_trailer"), levels=levels)
        json.loads((where / "assessment.json").read_text(), parse_constant=lambda c: pytest.fail(c))
        out[name] = path.read_text()
    return out


def test_the_assessment_opens_with_the_combinations_specification(reports) -> None:
    text = reports["plain"]
    assert text.index("## The combination") < text.index("## Surface: dry")
    spec = vehicle_specification(vehicle_preset("lst"))
    assert spec.axle_load_sum == pytest.approx(spec.mass * GRAVITY, rel=1e-9)  # the statics carry the weight
    assert f"mass {spec.mass / 1000:.2f} t" in text and "unit 2 (semi trailer) | main | trailer1, trailer2" in text
    for group in spec.groups:
        assert f"| {group.load / GRAVITY / 1000:.2f} |" in text


def test_without_levels_the_assessment_says_so_once(reports) -> None:
    text = reports["plain"]
    assert text.count(NO_LEVELS) + text.count(NO_LEVELS.capitalize()) == 1
    assert "not verified" not in text and "level 1" not in text


def test_with_levels_each_graded_cell_cites_its_clause(reports) -> None:
    text = reports["graded"]
    assert "| tail swing | m | 0.276: level 2 (example cl. B2), margin 0.024 | 0.038: level 1 (example cl. B1)" in text
    assert "1.250: level 2 (example cl. C2)" in text
    assert NO_LEVELS not in text and "EXAMPLE ONLY" in text


def test_the_turning_circle_note_states_the_result_it_grades(reports) -> None:
    text = reports["plain"]
    assert "| turning circle: inner radius | m | 4.859 (fail, margin -0.441) | 5.790 (pass, margin 0.490) |" in text
    assert "  - none: measured: the innermost point came to 4.859 m (unit 2) (fail, 0.441 m inside)" in text
    assert "  - every column: the test asks that no point of any unit come inside 5.30 m" in text


def test_notes_are_said_once_for_every_column_and_labelled_per_column(reports) -> None:
    text = reports["plain"].split("## Notes")[1]
    assert text.count("same") == 1 and "  - every column: same" in text
    assert "  - none: per unit 0.276" in text and "  - truth: per unit 0.038" in text


def test_steering_is_compared_with_unsteered_at_speed(reports) -> None:
    text = reports["plain"].split("## Steering against unsteered at speed")[1].split("## What a")[0]
    assert "| rearward amplification (lower is better) | 1.090 | 1.250 (+15 %, worse) |" in text
    assert "| yaw damping coefficient (higher is better) | 0.470 | 0.270 (-43 %, worse) |" in text
    assert "steered on truth, against unsteered: raises the rearward amplification (worse); lowers the yaw" in text


def test_the_standards_a_yaw_plane_model_cannot_assess_are_listed_with_the_reason(reports) -> None:
    text = reports["plain"].split("## What a yaw-plane model cannot assess")[1].split("## Notes")[0]
    for key, reason in NOT_ASSESSED.items():
        assert f"- **{key.replace('_', ' ')}**: {reason}." in text
    assert "static rollover threshold" not in reports["plain"].split("## Steering")[0]  # no row of dashes


def test_list_vehicle_prints_the_axle_group_loads(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from test_faults import offtrack_in_process

    vehicle = str(REPO / "tests" / "data" / "vehicles" / "b-double-steered.yaml")
    result = offtrack_in_process(monkeypatch, capsys, "list", "--vehicle", vehicle)  # main() in this process
    assert result.returncode == 0, result.stderr
    assert "b-double-steered: 3 units" in result.stdout and "Axle groups" in result.stdout
    spec_loads = [
        line.split()[-1] for line in result.stdout.splitlines() if line.startswith("unit ") and "main" in line
    ]
    assert len(spec_loads) == 2


def test_a_missing_unsteered_value_is_said_in_its_own_cell_not_the_steered_one() -> None:
    from scenarios.studies.assessment_report import steering_at_speed

    lost = "the run ended lost_control: lost control at t = 8 s"
    records = pd.DataFrame(
        [
            {"surface": "ice", "feedback": "none", "measure": "rearward amplification", "value": None, "note": lost},
            {"surface": "ice", "feedback": "truth", "measure": "rearward amplification", "value": 1.03, "note": "x"},
        ]
    )
    text = "\n".join(steering_at_speed(records))
    assert (
        "| rearward amplification (lower is better) | — (the run ended lost control) | 1.030 (nothing to compare) |"
        in text
    )
    assert "gives a rearward amplification where the unsteered run gave none (the run ended lost control)" in text


def test_a_measure_figure_shows_values_limits_missing_cases_and_what_negative_means() -> None:
    """Tail swing of three cases: each value written on its bar with its level, the example file's limits drawn with
    their clauses, the diverged case kept as a hatched bar with its reason, and the negative bar explained."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from scenarios.assess.user_levels import load_levels
    from scenarios.studies.assessment_report import measure_figure

    levels = load_levels(Path(__file__).parent / "data" / "pbs_levels_example.yaml")
    rows = pd.DataFrame(
        {
            "measure": ["tail swing"] * 3,
            "unit": ["m"] * 3,
            "feedback": ["none", "truth", "zero_slip"],
            "surface": ["dry"] * 3,
            "value": [0.276, -0.05, float("nan")],
            "level": [2, 1, None],
            "status": ["completed", "completed", "diverged"],
        }
    )
    fig = measure_figure(rows, ["dry"], levels, 20.0)
    try:
        ax = fig.axes[0]
        texts = {t.get_text() for t in ax.texts if t.get_gid() == "value"}
        assert texts == {"0.276\nlevel 2", "-0.050\nlevel 1"}
        missing = [t.get_text() for t in ax.texts if t.get_gid() == "no-value"]
        assert missing == ["no value: run diverged"]
        limits = [line for line in ax.get_lines() if str(line.get_gid()).startswith("limit:")]
        standard = levels.standard("tail_swing")
        assert sorted(line.get_ydata()[0] for line in limits) == sorted(t.limit for t in standard.applicable(20.0))
        assert any("cl. B" in t.get_text() for t in ax.get_legend().get_texts())
        assert [t.get_text() for t in ax.texts if t.get_gid() == "negative"] == [
            "below 0: the rear corner moves inward, not out"
        ]
    finally:
        plt.close(fig)


def test_the_assessment_says_what_its_runs_noted(tmp_path) -> None:
    """A case whose run wrote a note (the scrub note of a zero-slip estimate) has it under "What the runs said",
    labelled by its case; an assessment whose runs noted nothing has no such section."""
    table = _table()
    run = tmp_path / str(table.loc[0, "run"])
    run.mkdir()
    text = "the zero-slip estimate is 0.280 m RMS off: the fixed groups scrub"
    (run / "metrics.json").write_text(json.dumps({"notes": [{"note": "scrub", "text": text}]}))
    written = write_assessment(table, tmp_path, "lst").read_text()
    section = written[written.index("## What the runs said") : written.index("## Notes")]
    assert f"- low speed turn, dry, none: {text}" in section and section.count("\n- ") == 1
    quiet = tmp_path / "quiet"
    quiet.mkdir()
    assert "## What the runs said" not in write_assessment(table, quiet, "lst").read_text()
