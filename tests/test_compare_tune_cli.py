"""``offtrack compare`` (a short run of two feedbacks, its table fitted to 80 columns) and ``offtrack tune``'s outputs
(the trials, the comparison and the gains a run loads), the latter from a constructed result: a real tuning takes
minutes."""

from __future__ import annotations

import shlex
from pathlib import Path

import pandas as pd
import pytest
import yaml
from cli_runner import invoke as invoke_offtrack

import scenarios.envs.tuning as tuning
from controller.path_following_config import PathFollowingGains
from scenarios.config import load_scenario, parse_assignment, validate_config
from scenarios.envs.tuning import TuningResult
from scenarios.envs.tuning_report import set_options, write_tuning

NARROW = {"COLUMNS": "80"}


def invoke(*args: str):
    return invoke_offtrack(list(args), env=NARROW, prog_name="offtrack")


def test_compare_prints_a_table_within_80_columns(tmp_path: Path) -> None:
    out = tmp_path / "cmp"
    result = invoke("compare", "roundabout-test", "--duration", "3", "--feedbacks", "none,truth", "--out", str(out))
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert max(len(line) for line in lines) <= 80, result.stdout
    assert "None" not in result.stdout
    assert any("none" in line and "completed" in line for line in lines)
    assert any("truth" in line and "completed" in line for line in lines)
    assert len(pd.read_csv(out / "comparison.csv")) == 2


def test_compare_refuses_a_negative_duration_in_one_line(tmp_path: Path) -> None:
    result = invoke("compare", "roundabout-test", "--duration", "-1", "--feedbacks", "truth", "--out", str(tmp_path))
    assert result.exit_code == 2
    assert len(result.stderr.strip().splitlines()) == 1 and "duration" in result.stderr, result.stderr


def _result() -> TuningResult:
    figures = {"cost": 0.01, "rms_offtracking": 0.02, "max_offtracking": 0.05, "saturated_fraction": 0.1}
    return TuningResult(
        designed=PathFollowingGains(kp=0.286, ki=0.0745, kd=0.0),
        tuned=PathFollowingGains(kp=0.41234567891, ki=0.0512345678, kd=0.00312345678),
        train_cost_designed=0.02,
        train_cost_tuned=0.015,
        held_out=[
            {
                "condition": "snow (μ 0.25), 5 % adverse camber, laden",
                "designed": {**figures, "status": "completed"},
                "tuned": {**figures, "cost": 0.009, "status": "completed"},
            }
        ],
        trials=2,
        trial_rows=[
            {"trial": 0, "kp": 0.286, "ki": 0.0745, "kd": 0.001, "train_cost": 0.02, "state": "complete"},
            {"trial": 1, "kp": 0.4123, "ki": 0.0512, "kd": 0.0031, "train_cost": 0.015, "state": "complete"},
        ],
        evaluations=8,
        wall_s=1.0,
    )


def test_tuning_outputs_give_a_run_the_tuned_gains(tmp_path: Path) -> None:
    result = _result()
    base = load_scenario("roundabout-3", {"feedback": "truth", "vehicle": "lst"})
    paths = write_tuning(result, tmp_path, base)
    trials = pd.read_csv(paths["trials"])
    assert list(trials["trial"]) == [0, 1] and "kp [rad/m]" in trials.columns
    assert set(pd.read_csv(paths["comparison"])["gains"]) == {"designed", "tuned"}
    loaded = load_scenario(str(paths["gains"]))  # what `offtrack run DIR/tuned_gains.yaml` runs
    (tuned,) = result.tuned
    assert (loaded.controller.kp, loaded.controller.ki, loaded.controller.kd) == (tuned.kp, tuned.ki, tuned.kd)
    gains = loaded.controller.path_following(loaded.rates.control_hz).gains
    assert gains == tuned
    assert loaded.path == base.path and loaded.feedback == "truth"


def test_the_printed_set_line_parses_to_the_tuned_gains() -> None:
    (tuned,) = _result().tuned
    words = shlex.split(set_options(tuned))
    assert words[::2] == ["--set"] * 3
    overrides = dict(parse_assignment(item) for item in words[1::2])
    config = load_scenario("roundabout-3", overrides)
    assert (config.controller.kp, config.controller.ki, config.controller.kd) == (tuned.kp, tuned.ki, tuned.kd)


def test_tune_cli_writes_its_outputs_and_fits_80_columns(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls = {}

    def fake(**kwargs):
        calls.update(kwargs)
        return _result()

    monkeypatch.setattr(tuning, "tune_gains", fake)
    out = tmp_path / "tune"
    result = invoke("tune", "--trials", "2", "--draws", "1", "--out", str(out))
    assert result.exit_code == 0, result.output
    assert calls["env_kwargs"]["scenario"] == "roundabout-3" and calls["n_trials"] == 2
    set_line = next(line for line in result.stdout.splitlines() if line.startswith("apply the tuned gains: "))
    assert set_line.removeprefix("apply the tuned gains: ") == set_options(_result().tuned)
    table_lines = [line for line in result.stdout.splitlines() if line != set_line]
    assert max(len(line) for line in table_lines) <= 80, result.stdout
    assert "rad/m²" in result.stdout and "None" not in result.stdout
    config = validate_config(yaml.safe_load((out / "tuned_gains.yaml").read_text()))
    assert config.controller.kp == _result().tuned[0].kp
    assert {p.name for p in out.iterdir()} >= {"trials.csv", "comparison.csv", "comparison.md", "tuned_gains.yaml"}
    as_json = invoke("tune", "--trials", "2", "--json")
    assert as_json.exit_code == 0 and '"tuned"' in as_json.stdout


def test_tune_refuses_an_unknown_scenario_before_tuning(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tuning, "tune_gains", lambda **_: pytest.fail("tuned an unknown scenario"))
    result = invoke("tune", "--scenario", "no-such-road")
    assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1, result.stderr


def test_held_out_table_fits_80_columns_with_a_failed_run() -> None:
    from rich.console import Console

    from scenarios.envs.tuning_report import held_out_table

    result = _result()
    row = result.held_out[0]
    result.held_out.append({**row, "condition": "μ 0.3, 4 % inward camber, unladen, 20 km/h, right"})
    result.held_out[1]["tuned"] = {**row["tuned"], "status": "diverged", "cost": None}
    console = Console(width=80, record=True)
    console.print(held_out_table(result))
    text = console.export_text()
    assert max(len(line) for line in text.splitlines()) <= 80 and "diverged" in text and "None" not in text


def test_compare_table_says_pass_or_fail_and_fits_80_columns() -> None:
    from rich.console import Console

    from scenarios.run.summary import MISSING
    from scenarios.studies.compare import display_table
    from scenarios.studies.summary import summary_table

    row = {
        "status": "completed",
        "true_offtracking_rms_m": 0.012,
        "true_offtracking_max_m": None,  # a number the run did not produce
        "max_trailer_steer_deg": 12.3,
        "saturated_fraction": 0.01,
        "outer_radius_max_m": 12.1,
        "inner_radius_min_m": 5.4,
    }
    verdicts = {"none": False, "zero_slip": True, "viso_ot_fused": True, "truth": True}
    table = pd.DataFrame([{"feedback": f, **row, "roundabout_pass": v} for f, v in verdicts.items()])
    console = Console(width=80, record=True)
    console.print(summary_table(display_table(table), 80, files=("a.md", "a.csv"), rows="runs", missing=MISSING))
    text = console.export_text()
    assert max(len(line) for line in text.splitlines()) <= 80 and "None" not in text
    lines = text.splitlines()
    assert any("none" in line and "FAIL" in line for line in lines)
    assert any("truth" in line and "PASS" in line for line in lines)
