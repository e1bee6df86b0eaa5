"""``offtrack assess``: every manoeuvre of an assessment run on the sweep runner, its records and files.

* The reference combination (unsteered, dry): five cases, each measure once; the turning circle's radii are the
  roundabout-test run's own ``metrics.json`` figures (to the bit), its verdict the known one (the trailer cuts
  0.136 m inside 5.30 m); the low-speed swept path is wider than the tractor's own and the trailer's own swept
  width; the measures the model cannot support are reported without a value and say why; a figure per valued measure.
* Every option it cannot run is refused in one line before any case runs (tests inject each).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from scenarios.config import load_scenario
from scenarios.studies.pbs_assessment import (
    MANOEUVRES,
    assessment_cases,
    run_assessment,
    side_by_side_feedbacks,
)
from vehicle_model.errors import InputError

B_DOUBLE = Path(__file__).parent / "data" / "combinations" / "b-double.yaml"


STEERED_B_DOUBLE = str(B_DOUBLE.parents[1] / "vehicles" / "b-double-steered.yaml")
"""The B-double test layout with the rear two axles of each trailer steerable."""


@pytest.fixture(scope="module")
def reference(
    tmp_path_factory: pytest.TempPathFactory, roundabout_test_run: Path
) -> tuple[Path, pd.DataFrame, pd.DataFrame]:
    """The reference combination's assessment. Its turning circle is ``roundabout-test`` with the scenario's defaults
    (the same configuration; the run's series is the one of the session's shared run to the bit): that run is the
    session's shared one, copied into the case's directory, and the rest of the case (its records) as always."""
    import scenarios.studies.pbs_assessment as assessment

    real_run, defaults, shared = assessment.run_scenario, load_scenario("roundabout-test"), []

    def run_scenario(config, run_dir: Path, **options):
        if config != defaults:
            return real_run(config, run_dir, **options)
        shutil.copytree(roundabout_test_run, run_dir, dirs_exist_ok=True)
        shared.append(run_dir.name)
        return json.loads((run_dir / "metrics.json").read_text())

    out = tmp_path_factory.mktemp("assess")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(assessment, "run_scenario", run_scenario)
        table = run_assessment("reference", out, run_plots=False)  # the measures do not use the runs' own figures
    assert shared == [table.set_index("manoeuvre").loc["turning_circle", "run"]]
    return out, table, pd.read_csv(out / "assessment.csv")


def test_every_manoeuvre_runs_once_and_gives_its_measures(reference) -> None:
    out, table, records = reference
    assert list(table["manoeuvre"]) == [m.key for m in MANOEUVRES]
    assert (table["status"] == "completed").all()
    measures = list(records["measure"])
    assert len(measures) == len(set(measures))  # one feedback, one surface: each measure once
    for measure in (
        "low speed swept path",
        "tail swing",
        "frontal swing",
        "steer tyre friction demand",
        "turning circle: inner radius",
        "rearward amplification",
        "high-speed transient off-tracking",
        "yaw damping coefficient",
        "high-speed steady off-tracking",
    ):
        assert measure in measures and pd.notna(records.set_index("measure").loc[measure, "value"]), measure
    not_assessed = records[
        records["measure"].isin(["static rollover threshold", "tracking ability on a straight path"])
    ]
    assert len(not_assessed) == 2 and not_assessed["value"].isna().all()
    assert not_assessed["note"].str.startswith("not assessed").all()
    assert (out / "assessment.md").read_text().count("| none |") == 1
    assert json.loads((out / "assessment.json").read_text())["vehicle"] == "reference"
    assert (out / "measure-rearward-amplification.png").stat().st_size > 5_000
    assert not list(out.glob("*/plan_view.png"))  # the runs' own figures were switched off


def test_the_levels_template_names_exactly_the_standards_the_assessment_measures(reference) -> None:
    from scenarios.assess.user_levels import ASSESSED, standard_key
    from scenarios.yaml_input import load_yaml

    _, _, records = reference
    measured = {standard_key(m) for m in records["measure"]} - {None}
    template = load_yaml((Path(__file__).parents[1] / "docs" / "pbs_levels_template.yaml").read_text(), "template")
    assert measured == set(ASSESSED) == set(template["standards"])


def test_the_turning_circle_is_the_roundabout_tests_own_verdict(reference) -> None:
    out, table, records = reference
    run = table.set_index("manoeuvre").loc["turning_circle", "run"]
    test = json.loads((out / run / "metrics.json").read_text())["roundabout_test"]
    by_measure = records.set_index("measure")
    assert by_measure.loc["turning circle: inner radius", "value"] == test["inner_radius_min"]
    assert by_measure.loc["turning circle: outer radius", "value"] == test["outer_radius_max"]
    assert by_measure.loc["turning circle: inner radius", "level"] == "fail"
    assert by_measure.loc["turning circle: inner radius", "margin"] == pytest.approx(-0.136, abs=0.002)
    assert by_measure.loc["turning circle: outer radius", "level"] == "pass"


def test_the_low_speed_swept_path_is_wider_than_each_units_own(reference) -> None:
    _, _, records = reference
    row = records.set_index("measure").loc["low speed swept path"]
    per_unit = dict(part.split(" ") for part in row["note"].split("per unit: ")[1].split(";")[0].split(", "))
    assert row["value"] >= max(float(v) for v in per_unit.values()) - 1e-9
    assert row["value"] > 2.6  # wider than the tractor's body


@pytest.mark.parametrize(
    ("vehicle", "feedbacks", "surfaces", "message"),
    [
        ("reference", ("truth",), ("dry",), "--feedback truth: 'reference' has no steerable axle"),
        ("lst", ("gps",), ("dry",), "--feedback gps: must be one of"),
        ("B-DOUBLE", ("viso_ot_fused",), ("dry",), "the camera estimators take a tractor and one semi-trailer"),
        ("lst", ("none",), ("tarmac",), "low_speed_turn: "),
        ("no-such-vehicle", ("none",), ("dry",), "COMBINATION no-such-vehicle: "),
        ("lst", (), ("dry",), "at least one --feedback"),
    ],
)
def test_an_assessment_it_cannot_run_is_refused_in_one_line(
    vehicle: str, feedbacks: tuple[str, ...], surfaces: tuple[str, ...], message: str
) -> None:
    with pytest.raises(InputError) as caught:
        assessment_cases(STEERED_B_DOUBLE if vehicle == "B-DOUBLE" else vehicle, feedbacks, surfaces)
    text = str(caught.value)
    assert message in text and "\n" not in text


def test_side_by_side_compares_every_feedback_the_combination_takes() -> None:
    assert side_by_side_feedbacks("lst") == ("none", "truth", "zero_slip", "viso_ot_fused")
    with pytest.raises(InputError, match="--side-by-side: 'reference' has no steerable axle"):
        side_by_side_feedbacks("reference")
    steered = STEERED_B_DOUBLE
    assert side_by_side_feedbacks(steered) == ("none", "truth", "zero_slip")
    cases = assessment_cases(steered, ("truth",), ("ice",))
    overrides = dict(cases[0].overrides)
    assert overrides["feedback"] == "truth" and overrides["rear_feedback"] == ("truth",)
    assert overrides["surface.preset"] == "ice" and len(cases) == len(MANOEUVRES)


def test_the_command_refuses_before_any_work_with_exit_code_2(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from test_faults import offtrack_in_process

    # through main() in this process (the exit code 2 a process gets from main(): test_faults.py)
    for args in (("--feedback", "truth"), ("--side-by-side",), ("--surface", "tarmac")):
        command = ("assess", "reference", *args, "--out", str(tmp_path / "a"))
        result = offtrack_in_process(monkeypatch, capsys, *command)
        assert result.returncode == 2, result.stderr
        assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
        assert not (tmp_path / "a").exists()  # refused before the output directory was made
