"""Every output of a run or a comparison agrees with the others and says what is surprising.

* One verdict: a failed roundabout test is a flag of ``metrics.json``'s verdict, so the summary, ``--check`` and
  ``metrics.json`` say the same thing.
* Every JSON offtrack writes parses with a strict parser (no bare ``NaN``): a ``compare`` of two short runs, one of
  them made to end ``diverged``, and a ``report`` of one of its runs are parsed file by file with ``parse_constant``
  raising.
* ``compare`` exits 3 when a run did not complete, gives its radii as missing with a reason, shows each estimator's
  error and the camera's conditions, and says when a steered run is worse than the unsteered one.
* Every RMS a table or the summary shows names its window (all ticks, or after warm-up).
* A study's terminal table shows the columns its declaration names; field-loop's shows one row per cell with its
  conditions and acceptance, as its ``table.md``.
* The zero-slip scrub note appears only where its condition holds.
* Input errors begin with one form, ``error:``.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from rich.console import Console
from test_field_loop_study import _synthetic_table
from test_roundabout_reason import FAILED
from typer.testing import CliRunner

import scenarios.studies.compare as compare_module
from scenarios.cli import app
from scenarios.config import load_scenario
from scenarios.run.camera_conditions import camera_conditions
from scenarios.run.json_output import NULL_REASONS_KEY, loads_strict, strict_json
from scenarios.run.notes import scrub_note
from scenarios.run.results import config_yaml
from scenarios.run.summary import run_summary
from scenarios.run.verdicts import ROUNDABOUT_FLAG, missed_checks, run_verdict, with_roundabout_test
from scenarios.studies.compare import unsteered_comparison
from scenarios.studies.registry import STUDIES
from scenarios.studies.section4 import FIELD_CONDITIONS
from scenarios.studies.summary import HEADERS, summary_table

ROOT = Path(__file__).resolve().parents[1]


def _text(renderables: list, width: int = 200) -> str:
    console = Console(record=True, width=width, color_system=None)
    for renderable in renderables:
        console.print(renderable)
    return console.export_text()


# ------------------------------------------------------------------------------------------------ one verdict


def test_a_failed_roundabout_test_is_a_flag_of_the_one_verdict() -> None:
    unsteered = run_verdict("none", {"rms": 2.0, "max_abs": 2.5}, {}, None)
    assert unsteered["held"] is True  # asked nothing of the steering ...
    verdict = with_roundabout_test(unsteered, FAILED)
    assert verdict["held"] is False and [f["flag"] for f in verdict["flags"]] == [ROUNDABOUT_FLAG]  # ... but the test
    assert with_roundabout_test(verdict, FAILED) == verdict  # merged once
    metrics = {
        "scenario": "roundabout-test",
        "status": "completed",
        "feedback": "none",
        "offtracking": {"truth": {"rms": 2.3, "max_abs": 2.6}, "estimators": {}},
        "roundabout_test": FAILED,
        "verdict": verdict,
    }
    text = _text(run_summary(metrics, Path("x")))
    assert "not held: 1 miss(es)" in text and "nothing to hold" not in text
    assert not any(line.startswith("held:") for line in text.splitlines())
    missed = missed_checks(metrics)  # what --check prints and exits 4 on
    assert len(missed) == 1 and missed[0].startswith(ROUNDABOUT_FLAG)
    passed = {**FAILED, "pass": True, "inner_radius_min": 5.4, "inner_margin": 0.1}
    held = {**metrics, "roundabout_test": passed, "verdict": with_roundabout_test(unsteered, passed)}
    assert "held: roundabout test passed" in _text(run_summary(held, Path("x"))) and missed_checks(held) == []
    old = {**metrics, "verdict": unsteered}  # a metrics.json written before the test was a flag: the same verdict
    assert "not held: 1 miss(es)" in _text(run_summary(old, Path("x"))) and missed_checks(old) == missed


# ----------------------------------------------------------------------------------------------- strict JSON


def test_strict_json_writes_null_with_its_reason() -> None:
    text = strict_json({"a": {"rms": float("nan"), "ok": 1.5}, "b": [np.float64(np.inf), 2]})
    data = loads_strict(text)
    assert data["a"] == {"rms": None, "ok": 1.5} and data["b"] == [None, 2]
    assert set(data[NULL_REASONS_KEY]) == {"/a/rms", "/b/0"}
    assert data[NULL_REASONS_KEY]["/a/rms"].startswith("not a number")
    assert data[NULL_REASONS_KEY]["/b/0"].startswith("+infinite")
    with pytest.raises(ValueError, match="bare NaN"):
        loads_strict('{"x": NaN}')
    assert NULL_REASONS_KEY not in loads_strict(strict_json({"a": 1.0}))


def test_config_yaml_keeps_section_and_degree_signs() -> None:
    text = config_yaml(load_scenario("roundabout-test"))
    assert "§7.6.1" in text and "360°" in text and "\\xA7" not in text and "\\xB0" not in text


@pytest.fixture(scope="module")
def compared(tmp_path_factory: pytest.TempPathFactory) -> tuple[object, Path]:
    """``compare`` of an unsteered and a zero-slip-fed run of 3 s; the zero-slip run is told it diverged."""
    out = tmp_path_factory.mktemp("compare") / "cmp"
    real = compare_module.run_scenario

    def diverging(config, run_dir, **kwargs):
        metrics = real(config, run_dir, **kwargs)
        if config.feedback == "zero_slip":
            metrics = {**metrics, "status": "diverged", "message": "the simulation diverged at t = 2.000 s (a test)"}
        return metrics

    monkeypatch = pytest.MonkeyPatch()
    monkeypatch.setattr(compare_module, "run_scenario", diverging)
    try:
        args = ["compare", "roundabout-test", "--duration", "3", "--feedbacks", "none,zero_slip", "--out", str(out)]
        result = CliRunner().invoke(app, args, env={"COLUMNS": "200"}, prog_name="offtrack")
    finally:
        monkeypatch.undo()
    rebuilt = CliRunner().invoke(app, ["report", str(out / "zero_slip"), "--no-plots"], prog_name="offtrack")
    assert rebuilt.exit_code == 0, rebuilt.output  # metrics.json written a second time, by another command
    return result, out


def test_every_json_written_parses_strictly(compared) -> None:
    _, out = compared
    written = sorted(out.rglob("*.json"))
    assert len(written) >= 4  # two cases' records and two runs' metrics
    for path in written:
        loads_strict(path.read_text())  # a bare NaN or Infinity raises
    record = json.loads(next(p for p in written if p.parent.name == "cases" and "zero_slip" in p.name).read_text())
    assert record["row"]["inner_radius_min_m"] is None  # the diverged run's radius: null, and why
    assert record[NULL_REASONS_KEY]["/row/inner_radius_min_m"].startswith("not a number")
    assert record["row"]["reason"].startswith("diverged: the simulation diverged")


def test_compare_exits_3_on_a_run_that_did_not_complete(compared) -> None:
    result, out = compared
    assert result.exit_code == 3, result.output
    assert "run zero_slip diverged: diverged: the simulation diverged at t = 2.000 s" in result.stderr
    table = pd.read_csv(out / "comparison.csv")
    diverged = table[table["feedback"] == "zero_slip"].iloc[0]
    assert math.isnan(diverged["inner_radius_min_m"]) and diverged["reason"].startswith("diverged: the simulation")
    assert "zero_slip_rms_error_m" in table.columns  # the estimators' errors
    assert set(table["camera_conditions"]) == {"none rendered"}


def test_a_steered_run_worse_than_the_unsteered_one_is_said() -> None:
    table = pd.DataFrame(
        {
            "feedback": ["none", "zero_slip", "truth"],
            "status": ["completed"] * 3,
            "true_offtracking_rms_m": [0.146, 0.380, 0.020],
            "zero_slip_rms_error_m": [0.40, 0.41, 0.40],
        }
    )
    difference, notes = unsteered_comparison(table)
    assert difference == pytest.approx([0.0, 0.234, -0.126])
    assert len(notes) == 1 and notes[0].startswith("zero_slip-fed steering is worse than not steering")
    assert "0.380 m RMS after warm-up against 0.146 m unsteered" in notes[0] and "0.410 m RMS" in notes[0]
    assert unsteered_comparison(table[table["feedback"] != "none"])[1] == []  # nothing to compare with


def test_the_camera_conditions_name_each_field_part() -> None:
    assert camera_conditions(load_scenario("roundabout-3").camera) == "ideal"
    field = camera_conditions(load_scenario("roundabout-3", dict(FIELD_CONDITIONS)).camera)
    assert field.startswith("field (") and all(w in field for w in ("lens", "low sun", "estimated calibration"))


# ------------------------------------------------------------------------------------------- RMS windows


def test_every_rms_names_its_window() -> None:
    for column, header in HEADERS.items():
        if "RMS" in header:
            assert "after warm-up" in header or "all ticks" in header, column
    metrics = {
        "scenario": "s",
        "status": "completed",
        "feedback": "none",
        "offtracking": {
            "truth": {"rms": 2.334, "max_abs": 3.0, "defined_fraction": 0.9},
            "truth_after_warmup": {"rms": 2.426, "max_abs": 3.0},
            "estimators": {"zero_slip": {"rms_error": 0.3, "max_abs_error": 0.4, "valid_fraction": 1.0}},
        },
        "verdict": {"held": True, "flags": []},
    }
    lines = _text(run_summary(metrics, Path("x"))).splitlines()
    assert any("truth" in line and "all ticks" in line and "2.334" in line for line in lines)
    assert any("truth" in line and "after warm-up" in line and "2.426" in line for line in lines)
    assert any("zero_slip error" in line and "all ticks" in line for line in lines)


# ---------------------------------------------------------------------------------------- study terminals


def test_paper_section3_shows_the_camera_columns_not_the_repeated_truth() -> None:
    columns = STUDIES["paper-section3"].columns
    assert {"viso_ot_rms_error_m", "mean_matches", "mean_inliers"} <= set(columns)
    row = {"sweep": "baseline", "camera": "rear", "baseline": 0.5, "status": "completed"}
    row.update(true_offtracking_rms_after_warmup_m=3.503, viso_ot_rms_error_m=0.02, mean_matches=380.0)
    row.update(mean_inliers=300.0, inlier_percent=79.0)
    table = pd.DataFrame([row, {**row, "baseline": 1.5}])
    text = _text([summary_table(table, 200, columns=columns)])
    assert "3.503" not in text and "380" in text and "VISO-OT" in text and "inliers" in text


def test_field_loop_terminal_is_one_row_per_cell_with_conditions_and_acceptance() -> None:
    study = STUDIES["field-loop"]
    table = _synthetic_table()
    table.loc[table["seed"] == 0, "conditions"] = "field"
    rows, note = study.terminal_rows(table)
    passed = int((rows["acceptance"] == "pass").sum())
    assert note == f"{passed} of {len(rows)} cells pass" and len(rows) == table["seed"].nunique()
    text = _text([summary_table(rows, 250, columns=study.columns, rows="cells")])
    assert "conditions" in text and "field" in text and "ideal" in text and "cell" in text
    assert text.count("pass") >= passed and "held: yes" not in text


# ------------------------------------------------------------------------------------------------ notes


def test_the_scrub_note_only_where_its_condition_holds() -> None:
    params = load_scenario("roundabout-test", {"vehicle": "au-b-double"}).vehicle_params()
    metrics = {
        "offtracking": {
            "estimators": {"zero_slip": {"rms_error": 0.30}},
            "units": {"3": {"estimators": {"zero_slip": {"rms_error": 0.33}}}},
        }
    }
    note = scrub_note(metrics, params, mu=0.8, speed_kmh=5.0)
    assert note is not None and "unit 2 0.300 m RMS, unit 3 0.330 m RMS" in note and "scrub" in note
    assert "the chain carries it" in note  # three units
    assert scrub_note(metrics, params, mu=0.1, speed_kmh=5.0) is None  # ice: sliding, not scrub
    assert scrub_note(metrics, params, mu=0.8, speed_kmh=15.0) is None  # speed: the lateral acceleration
    small = {"offtracking": {"estimators": {"zero_slip": {"rms_error": 0.05}}}}
    assert scrub_note(small, params, mu=0.8, speed_kmh=5.0) is None


# ------------------------------------------------------------------------------------------------ errors


@pytest.mark.parametrize(
    "args",
    [
        ["run", "no-such-scenario"],
        ["run", "roundabout-test", "--mu", "5"],
        ["study", "no-such-study"],
        ["report", "/nonexistent/run"],
        ["compare", "roundabout-test", "--feedbacks", "bogus"],
        ["run", "roundabout-test", "--no-such-option"],
    ],
)
def test_every_input_error_begins_with_one_form(args: list[str]) -> None:
    result = CliRunner().invoke(app, args, prog_name="offtrack")
    assert result.exit_code == 2
    assert result.stderr.lstrip().startswith("error: "), result.stderr


def test_no_message_is_written_with_a_capital_error_prefix() -> None:
    pattern = re.compile(r"""["']Error: """)
    offenders = [
        str(path.relative_to(ROOT))
        for package in ("scenarios", "sensor", "controller", "vehicle_model")
        for path in (ROOT / package).rglob("*.py")
        if pattern.search(path.read_text(encoding="utf-8"))
    ]
    assert offenders == []


def test_every_declared_study_column_has_a_header_with_its_unit() -> None:
    for name, study in STUDIES.items():
        for column in study.columns:
            assert column == "status" or column in HEADERS, (name, column)
