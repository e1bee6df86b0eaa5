"""``offtrack tune`` on any steered combination: one gain set per steered unit, the designed gains exactly, advice
only where the held-out roads support it.

* a B-double with both trailers steered, tuned on 2 trials of one short draw, gives two gain sets; trial 0 is
  each unit's designed gains exactly (``kd`` 0, which the log-scaled action cannot express), and the
  ``tuned_gains.yaml`` written is a scenario whose run steers each trailer with its own tuned set;
* ``controller.unit_gains`` is refused in one line naming the field when it does not hold one set per steered
  unit, or when given with ``kp``/``ki``/``kd``;
* the advice follows injected held-out results: apply only when the tuned gains are no worse on every condition
  (a run that did not complete counts as worse), else keep the designed gains and name where the tuned lose;
* the training vehicles: a catalogue vehicle with an unladen variant is trained laden and unladen, a file as given.
"""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest
from typer.testing import CliRunner

import scenarios.envs.tuning as tuning
from controller.path_following_config import PathFollowingGains
from scenarios.cli import app
from scenarios.config import ConfigError, load_scenario, parse_assignment
from scenarios.envs.gain_tuning_env import configured_unit_gains
from scenarios.envs.tuning import TuningResult, held_out_conditions, training_vehicles, tune_gains
from scenarios.envs.tuning_report import set_options, write_tuning
from scenarios.loop.trailer_steer import PathFollowingSteer
from scenarios.setup.models import rebuild_setup

B_DOUBLE = str(Path(__file__).parent / "data" / "vehicles" / "b-double-steered.yaml")
SHORT = {"path.turns": 0.05, "path.entry_length": 5.0, "path.exit_length": 2.0}
"""A twentieth of the roundabout, 5 m in and 2 m out: an episode of a few seconds (measured: the held-out rear
trailer's RMS off-tracking 5.5 mm; over a tenth, 10 m in and 5 m out: 4.2 mm)."""
FIGURES = {"rms_offtracking": 0.02, "max_offtracking": 0.05, "saturated_fraction": 0.0, "status": "completed"}


@pytest.fixture(scope="module")
def b_double_tuned() -> TuningResult:
    pytest.importorskip("optuna")
    held_out = {"snow": {"mu": 0.25, "camber_percent": 5.0, "vehicle": B_DOUBLE, "speed_kmh": 15.0}}
    return tune_gains(n_trials=2, train_draws=1, vehicle=B_DOUBLE, env_kwargs={"overrides": SHORT}, held_out=held_out)


def test_a_b_double_is_tuned_with_a_gain_set_per_steered_unit(b_double_tuned: TuningResult) -> None:
    result = b_double_tuned
    assert result.units == (2, 3) and len(result.designed) == len(result.tuned) == 2
    base = load_scenario("roundabout-3", {**SHORT, "vehicle": B_DOUBLE, "feedback": "truth"})
    designed = configured_unit_gains(rebuild_setup(base))
    assert result.designed == designed  # exactly what a run without gains uses, unit by unit
    assert designed[0] != designed[1]  # each unit's own geometry: a shared set would not be the design
    first = result.trial_rows[0]
    assert (first["unit2_kd"], first["unit3_kd"]) == (0.0, 0.0) == (designed[0].kd, designed[1].kd)
    assert (first["unit2_kp"], first["unit3_kp"]) == (designed[0].kp, designed[1].kp)
    assert result.train_cost_tuned <= result.train_cost_designed  # trial 0 is the designed gains
    assert set(result.verdicts()) == {"snow"} and result.further_units() == [3]
    rear = result.held_out[0]["designed"]["unit3_rms_offtracking"]
    assert 0.0 < rear < 0.1  # the rear trailer's own RMS off-tracking [m] is reported, within the road's scale


def test_the_b_double_tuned_gains_file_runs_each_unit_on_its_own_set(
    b_double_tuned: TuningResult, tmp_path: Path
) -> None:
    base = load_scenario("roundabout-3", {**SHORT, "vehicle": B_DOUBLE, "feedback": "truth"})
    paths = write_tuning(b_double_tuned, tmp_path, base)
    loaded = load_scenario(str(paths["gains"]))  # what `offtrack run DIR/tuned_gains.yaml` runs
    steer = PathFollowingSteer.configured(rebuild_setup(loaded))
    assert tuple(ctrl.gains for ctrl, _ in steer.steered) == b_double_tuned.tuned
    assert [ctrl.unit for ctrl, _ in steer.steered] == [1, 2]
    words = shlex.split(set_options(b_double_tuned.tuned))
    config = load_scenario(
        "roundabout-3", {"vehicle": B_DOUBLE, "feedback": "truth", **dict([parse_assignment(words[1])])}
    )
    unit_gains = config.controller.unit_gains
    assert unit_gains is not None
    assert [(g.kp, g.ki, g.kd) for g in unit_gains] == [(g.kp, g.ki, g.kd) for g in b_double_tuned.tuned]


def test_unit_gains_of_the_wrong_length_or_beside_kp_are_refused_in_one_line() -> None:
    one = [{"kp": 0.3, "ki": 0.08, "kd": 0.0}]
    with pytest.raises(ConfigError, match=r"controller\.unit_gains") as wrong_length:
        load_scenario("roundabout-3", {"vehicle": B_DOUBLE, "feedback": "truth", "controller.unit_gains": one})
    assert "steers 2" in str(wrong_length.value)
    with pytest.raises(ConfigError, match=r"controller\.unit_gains"):
        load_scenario("roundabout-3", {"vehicle": B_DOUBLE, "controller.unit_gains": one * 2, "controller.kp": 0.3})


def _result(tuned_costs: list[float | None], tuned: PathFollowingGains | None = None) -> TuningResult:
    designed = PathFollowingGains(kp=0.286, ki=0.0745, kd=0.0)
    rows = [
        {
            "condition": f"road {k}",
            "designed": {**FIGURES, "cost": 0.02},
            "tuned": {**FIGURES, "cost": cost, "status": "completed" if cost is not None else "diverged"},
        }
        for k, cost in enumerate(tuned_costs)
    ]
    gains = PathFollowingGains(kp=0.4, ki=0.05, kd=0.003) if tuned is None else tuned
    return TuningResult(designed, gains, 0.02, 0.015, held_out=rows)


def test_the_advice_follows_the_held_out_results() -> None:
    better = _result([0.01, 0.02])  # better on one, equal on the other: no worse anywhere
    assert better.apply_tuned() and better.verdicts() == {"road 0": "tuned", "road 1": "equal"}
    assert better.advice()[-1].startswith("advice: apply the tuned gains")
    worse = _result([0.01, 0.03, None])  # worse on road 1, failed on road 2
    assert not worse.apply_tuned()
    assert worse.verdicts() == {"road 0": "tuned", "road 1": "designed", "road 2": "designed"}
    assert worse.advice()[-1] == "advice: keep the designed gains (the tuned ones are worse on road 1; road 2)"
    assert "advice: keep the designed gains" in worse.table()
    assert worse.to_dict()["apply_tuned"] is False and worse.to_dict()["advice"] == worse.advice()[-1]
    same = _result([0.02], tuned=PathFollowingGains(kp=0.286, ki=0.0745, kd=0.0))
    assert not same.apply_tuned() and "no trial beat them" in same.advice()[-1]


def test_the_cli_advises_keeping_the_designed_gains_when_the_tuned_lose(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = {}

    def fake(**kwargs):
        calls.update(kwargs)
        return _result([0.01, 0.03])

    monkeypatch.setattr(tuning, "tune_gains", fake)
    result = CliRunner().invoke(app, ["tune", "--trials", "2", "--vehicle", B_DOUBLE])
    assert result.exit_code == 0, result.output
    assert calls["vehicle"] == B_DOUBLE
    lines = result.stdout.splitlines()
    assert not any(line.startswith("apply the tuned gains") for line in lines)
    assert any(line.startswith("advice: keep the designed gains") for line in lines)
    assert any(line.startswith("the tuned gains, not advised: --set") for line in lines)
    assert "road 1: designed gains better" in lines


def test_training_vehicles_are_laden_and_unladen_only_where_the_catalogue_has_both() -> None:
    assert training_vehicles("lst") == ("lst", "lst-unladen") == training_vehicles("lst-unladen")
    assert training_vehicles(B_DOUBLE) == (B_DOUBLE,)
    assert training_vehicles("au-b-double") == ("au-b-double",)
    assert list(held_out_conditions("lst")) == list(tuning.HELD_OUT)
    for label, options in held_out_conditions(B_DOUBLE).items():
        assert "laden" not in label and options["vehicle"] == B_DOUBLE


def test_the_held_out_table_shows_the_rear_unit_and_fits_80_columns() -> None:
    from rich.console import Console

    from scenarios.envs.tuning_report import held_out_table

    result = _result([0.01])
    for which in ("designed", "tuned"):
        result.held_out[0][which]["unit3_rms_offtracking"] = 0.0123
    console = Console(width=80, record=True)
    console.print(held_out_table(result))
    text = console.export_text()
    assert max(len(line) for line in text.splitlines()) <= 80 and "unit 3" in text and "12.3" in text
    assert "RMS e unit 3 [mm]" in result.table()


def test_the_residual_environment_runs_each_unit_on_its_unit_gains() -> None:
    import gymnasium as gym

    from scenarios.envs import register_envs

    register_envs()
    sets = [{"kp": 0.3, "ki": 0.08, "kd": 0.0}, {"kp": 0.2, "ki": 0.05, "kd": 0.01}]
    overrides = {**SHORT, "controller.unit_gains": sets}
    env = gym.make("offtrack/TrailerSteering-v0", vehicle=B_DOUBLE, overrides=overrides, action_mode="residual")
    env.reset(seed=0)
    gains = [ctrl.gains for ctrl in env.unwrapped._controllers]
    assert gains == [PathFollowingGains(**g) for g in sets]
    env.close()
