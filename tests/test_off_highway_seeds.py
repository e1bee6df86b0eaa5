"""The off-highway study over several seeds (``offtrack study off-highway --seeds``): the option's parsing and
refusals, the default cases unchanged, every seed's cases, the cells pooled over seeds from made-up rows, and the
command's path through the sweep with the run function replaced by one that makes up rows (nothing is simulated)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pandas as pd
import pytest

from scenarios.studies.definitions import check_study_seeds, run_study, study_cases
from scenarios.studies.field_loop import TARGET_MAX_M, TARGET_RMS_M, field_signals
from scenarios.studies.off_highway import (
    CELL_LABELS,
    DEFAULT_CELLS,
    FEEDBACKS,
    SEED,
    cell_table,
    off_highway_case,
    off_highway_cases,
    off_highway_cells,
    off_highway_terminal_rows,
)
from scenarios.studies.off_highway_seeds import (
    SEED_COLUMNS,
    pooled_verdict,
    seed_table,
    seeds_note,
    terminal_rows_over_seeds,
)
from scenarios.studies.registry import STUDIES
from scenarios.studies.seeds import MAX_SEEDS, parse_seeds, seeds_text
from tests.cli_runner import invoke
from vehicle_model.errors import InputError

# ------------------------------------------------------------------------------------------- the option


@pytest.mark.parametrize(
    ("text", "seeds"),
    [("0-7", tuple(range(8))), ("0,1,5", (0, 1, 5)), ("3", (3,)), (" 5 , 0-2 ", (5, 0, 1, 2)), ("9-9", (9,))],
)
def test_seeds_are_ranges_and_single_seeds_in_the_order_given(text: str, seeds: tuple[int, ...]) -> None:
    assert parse_seeds(text) == seeds
    assert parse_seeds(seeds_text(seeds)) == seeds  # written back compactly, read back the same
    assert seeds_text((0, 1, 2, 3, 5, 7, 8)) == "0-3,5,7-8"


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("", "is not a seed or a range"),
        ("-1", "is not a seed or a range"),
        ("1.5", "is not a seed or a range"),
        ("a", "is not a seed or a range"),
        ("0,,1", "is not a seed or a range"),
        ("0-2-4", "is not a seed or a range"),
        ("7-0", "ends below its start"),
        ("0,1,0", "seed 0 named more than once"),
        ("0-3,2", "seed 2 named more than once"),
        (f"0-{MAX_SEEDS}", f"more than {MAX_SEEDS} seeds"),
        ("4294967296", "is above 4294967295"),
    ],
)
def test_a_bad_seed_spec_is_refused_in_one_line_naming_the_option(text: str, why: str) -> None:
    with pytest.raises(InputError) as refused:
        parse_seeds(text)
    message = str(refused.value)
    assert message.startswith("--seeds ") and why in message and "\n" not in message
    assert "non-negative integers" in message and f"at most {MAX_SEEDS} seeds" in message


def test_only_a_study_that_takes_seeds_takes_the_option() -> None:
    assert [name for name, study in STUDIES.items() if study.takes_seeds] == ["off-highway"]
    assert check_study_seeds("off-highway", None) is None and check_study_seeds("off-highway", "0-2") == (0, 1, 2)
    with pytest.raises(InputError, match=r"^--seeds 0-3: field-loop takes no --seeds .*off-highway takes one$"):
        study_cases("field-loop", seeds="0-3")
    with pytest.raises(InputError, match=r"^--seeds '0-x'"):
        study_cases("off-highway", seeds="0-x")
    with pytest.raises(ValueError, match="takes no seeds"):
        STUDIES["paper-section3"].case_specs(seeds=(0, 1))


def test_the_command_refuses_bad_seeds_before_any_work(tmp_path: Path) -> None:
    for args, why in (
        (["off-highway", "--seeds", "3-1"], "--seeds '3-1': the range '3-1' ends below its start"),
        (["field-loop", "--seeds", "0,1"], "--seeds 0,1: field-loop takes no --seeds"),
    ):
        out = tmp_path / args[0]
        result = invoke(["study", *args, "--out", str(out)], env={"COLUMNS": "300"})
        assert result.exit_code == 2, result.output  # bad input (README, "Exit codes")
        assert why in result.output and not out.exists()


# ------------------------------------------------------------------------------------------- the cases


def _spec(case) -> tuple:
    return case.scenario, case.overrides, case.labels


def test_without_seeds_the_cases_are_the_studys_own_at_its_seed() -> None:
    for full in (False, True):
        own = [_spec(c) for c in off_highway_cases(full)]
        # the cases as the study built them before it took seeds: each cell's feedbacks at SEED
        built = [_spec(off_highway_case(*cell, f, full)) for cell in off_highway_cells(full) for f in FEEDBACKS]
        assert own == built
        assert [_spec(c) for c in STUDIES["off-highway"].case_specs(full)] == own
        assert [_spec(c) for c in study_cases("off-highway", full)] == own
        assert [_spec(c) for c in off_highway_cases(full, seeds=(SEED,))] == own  # --seeds 0 is the default
    assert {dict(c.labels)["seed"] for c in off_highway_cases()} == {SEED} == {0}


def test_n_seeds_give_n_times_the_cases_each_drawn_from_its_seed() -> None:
    seeds = (0, 3, 5)
    cases = study_cases("off-highway", seeds="0,3,5")
    own = off_highway_cases()
    assert len(cases) == len(seeds) * len(own) == 24 and len({c.name for c in cases}) == 24
    for k, seed in enumerate(seeds):  # every cell of a seed before the next seed's
        block = cases[k * len(own) : (k + 1) * len(own)]
        assert [tuple(dict(c.labels)[x] for x in CELL_LABELS[:4]) for c in block[::4]] == list(DEFAULT_CELLS)
        for case, base in zip(block, own, strict=True):
            labels, overrides = dict(case.labels), dict(case.overrides)
            assert labels["seed"] == seed and overrides["seed"] == seed and f"seed-{seed}_" in case.name
            assert {k: v for k, v in labels.items() if k != "seed"} == {
                k: v for k, v in dict(base.labels).items() if k != "seed"
            }
            signals = {k: v for k, v in overrides.items() if k.startswith("signals.")}
            assert signals == (dict(field_signals(seed)) if labels["conditions"] == "field" else {})
            # nothing else differs from the study's own case of that cell and feedback
            rest = {k: v for k, v in overrides.items() if k != "seed" and not k.startswith("signals.")}
            assert rest == {
                k: v for k, v in dict(base.overrides).items() if k != "seed" and not k.startswith("signals.")
            }
    # the seeds draw different biases: seed 3's field signals are not seed 0's
    assert dict(field_signals(3)) != dict(field_signals(0))
    # the whole grid, with a vehicle, through the registry
    full = STUDIES["off-highway"].case_specs(True, "lst", seeds=(1, 2))
    assert len(full) == 2 * 96 and {dict(c.overrides)["vehicle"] for c in full} == {"lst"}


# ------------------------------------------------------------------------------------------- pooling


def _rows(maxima: dict[int, float], truth_max: float = 0.09) -> pd.DataFrame:
    """Made-up rows of the default subset's two cells at each seed of ``maxima``: the field cell's fused-fed max
    at that seed, the ideal cell's 0.10 m; every RMS within its target."""
    rows = []
    true = {"zero_slip": (0.03, 0.12), "truth": (0.02, truth_max), "none": (0.3, 0.5)}
    for seed, field_max in maxima.items():
        for conditions in ("field", "ideal"):
            for feedback in FEEDBACKS:
                row = {"scenario": "gravel-yard", "surface": "wet_clay", "roughness": "rough"}
                row |= {"conditions": conditions, "seed": seed, "feedback": feedback, "status": "completed"}
                fused_max = field_max if conditions == "field" else 0.10
                rms_, max_ = (0.05 + 0.001 * seed, fused_max) if feedback == "viso_ot_fused" else true[feedback]
                row |= {"true_offtracking_rms_after_warmup_m": rms_, "true_offtracking_max_after_warmup_m": max_}
                if feedback == "viso_ot_fused":
                    row |= {"viso_ot_fused_rms_error_m": 0.03 + 0.01 * seed, "viso_ot_fused_max_abs_error_m": 0.1}
                rows.append(row)
    return pd.DataFrame(rows)


def test_a_cell_failing_at_one_seed_of_three_held_in_two() -> None:
    table = _rows({0: 0.121, 1: 0.1502, 2: 0.123})
    pooled = seed_table(table)
    assert list(pooled.columns[4:]) == list(SEED_COLUMNS) and list(pooled["conditions"]) == ["field", "ideal"]
    field, ideal = pooled.iloc[0], pooled.iloc[1]
    # the per-seed verdicts are the cell table's
    one = cell_table(table)
    assert one.loc[one["seed"] == 1, "cell_verdict"].tolist() == [f"fail: max 0.150 > {TARGET_MAX_M:.2f} m", "pass"]
    assert field["pooled_verdict"] == f"held in 2 of 3 seeds (seed 1 fail: max 0.150 > {TARGET_MAX_M:.2f} m)"
    assert (field["seeds"], field["seeds_run"], field["seeds_pass"], field["seeds_fail"]) == ("0-2", 3, 2, 1)
    assert field["seeds_na"] == 0 and field["seeds_missing"] == 0
    assert field["fail_share"] == pytest.approx(1 / 3, abs=1e-12)
    assert field["fused_fed_true_max_worst_m"] == 0.1502 and field["fused_fed_true_max_median_m"] == 0.123
    assert field["fused_fed_true_rms_worst_m"] == pytest.approx(0.052, abs=1e-12)
    assert field["fused_fed_true_rms_median_m"] == pytest.approx(0.051, abs=1e-12)
    assert field["fused_rms_error_worst_m"] == pytest.approx(0.05, abs=1e-12)
    assert field["fused_max_abs_error_worst_m"] == 0.1
    assert ideal["pooled_verdict"] == "held in 3 of 3 seeds" and ideal["fail_share"] == 0.0
    assert seeds_note(table) == "over seeds 0-2: 1 of 2 judged cells held in every seed (seeds.md)"
    assert seeds_note(_rows({4: 0.1})) == ""  # one seed: nothing pooled
    # the terminal: the study's own note, and the pooled one after it over more than one seed
    terminal = STUDIES["off-highway"].terminal_rows
    assert terminal is terminal_rows_over_seeds
    one = _rows({4: 0.1})
    assert (
        terminal(one)[1] == off_highway_terminal_rows(one)[1] == "2 of 2 cells the truth-fed loop holds pass (2 cells)"
    )
    rows, note = terminal(table)
    assert len(rows) == 6 and note == (
        "5 of 6 cells the truth-fed loop holds pass (6 cells); over seeds 0-2: 1 of 2 judged cells held in every "
        "seed (seeds.md)"
    )


def test_a_failed_or_missing_case_is_never_counted_as_a_pass_and_is_said() -> None:
    table = _rows({0: 0.12, 1: 0.12, 2: 0.12, 3: 0.12})
    at = (table["conditions"] == "field") & (table["feedback"] == "viso_ot_fused")
    table.loc[at & (table["seed"] == 1), "status"] = "failed"  # the case ran and failed
    table.loc[at & (table["seed"] == 1), "true_offtracking_max_after_warmup_m"] = math.nan
    table = table[~(at & (table["seed"] == 2))]  # the case never ran
    table = table[~((table["conditions"] == "field") & (table["seed"] == 3) & (table["feedback"] == "truth"))]
    field = seed_table(table.reset_index(drop=True)).iloc[0]
    assert field["pooled_verdict"] == (
        "held in 1 of 4 seeds (seed 1 missing: fused-fed case failed; seed 2 missing: no fused-fed case; "
        "seed 3 missing: no truth-fed case)"
    )
    assert (field["seeds_pass"], field["seeds_fail"], field["seeds_missing"]) == (1, 0, 3)
    assert field["fail_share"] == 0.0  # of the one seed judged
    assert field["fused_fed_true_max_median_m"] == 0.12  # seeds 0 and 3 ran their fused case
    # a seed with no case of the cell at all
    gone = _rows({0: 0.12, 1: 0.12})
    gone = gone[~((gone["conditions"] == "ideal") & (gone["seed"] == 1))]
    ideal = seed_table(gone.reset_index(drop=True)).iloc[1]
    assert ideal["pooled_verdict"] == "held in 1 of 2 seeds (seed 1 missing: no fused-fed case, no truth-fed case)"


def test_where_the_truth_fed_loop_misses_every_seed_the_cell_is_not_judged() -> None:
    table = _rows({0: 0.1, 1: 0.1}, truth_max=TARGET_MAX_M + 0.02)
    pooled = seed_table(table)
    assert all(pooled["pooled_verdict"].str.startswith("n/a in every seed (seed 0 n/a: truth-fed"))
    assert list(pooled["seeds_na"]) == [2, 2] and all(pooled["fail_share"].isna())
    assert seeds_note(table) == "over seeds 0-1: 0 of 0 judged cells held in every seed (seeds.md)"
    assert pooled_verdict({0: "pass", 1: "n/a: truth-fed 0.020 / 0.170 m"}) == (
        "held in 1 of 2 seeds (seed 1 n/a: truth-fed 0.020 / 0.170 m)"
    )
    assert pooled_verdict({4: "pass"}) == "held in 1 of 1 seed"
    assert TARGET_RMS_M > 0.06  # the made-up RMS figures are within it


# ------------------------------------------------------------------------------------------- the command


def made_up_case(spec, out_dir: Path) -> dict:
    """A row for an off-highway case without running it: the field cell's fused-fed max over the limit at seed 1."""
    labels = dict(spec.labels)
    fused = labels["feedback"] == "viso_ot_fused"
    over = fused and labels["conditions"] == "field" and labels["seed"] == 1
    return {
        **labels,
        "status": "completed",
        "true_offtracking_rms_after_warmup_m": 0.05 if fused else 0.02,
        "true_offtracking_max_after_warmup_m": 0.1502 if over else (0.12 if fused else 0.06),
    }


def test_the_command_over_two_seeds_writes_the_pooled_table(tmp_path: Path, monkeypatch) -> None:
    study = dataclasses.replace(STUDIES["off-highway"], run_case=made_up_case)
    monkeypatch.setitem(STUDIES, "off-highway", study)
    out = tmp_path / "oh"
    result = invoke(["study", "off-highway", "--seeds", "0,1", "--out", str(out)], env={"COLUMNS": "400"})
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())  # the title as one line, however the terminal wrapped it
    assert "16 cases" in said and "over seeds 0-1: 1 of 2 judged cells held in every seed (seeds.md)" in said
    pooled = pd.read_csv(out / "seeds.csv")
    assert list(pooled["pooled_verdict"]) == [
        f"held in 1 of 2 seeds (seed 1 fail: max 0.150 > {TARGET_MAX_M:.2f} m)",
        "held in 2 of 2 seeds",
    ]
    assert (out / "seeds.md").read_text().startswith("## Over seeds")
    assert (out / "table.md").read_text().startswith("## Over seeds") and len(pd.read_csv(out / "cells.csv")) == 4
    # the same directory run again at the study's own seed: one cell per cell, no pooled table left behind
    again = invoke(["study", "off-highway", "--out", str(out)], env={"COLUMNS": "400"})
    assert again.exit_code == 0, again.output
    assert "8 cases" in again.output and "over seeds" not in again.output
    assert not (out / "seeds.md").exists() and not (out / "seeds.csv").exists()
    assert (out / "table.md").read_text().startswith("## Cells")


def test_run_study_takes_the_seeds_as_integers_and_runs_only_new_seeds_again(tmp_path: Path, monkeypatch) -> None:
    ran: list[str] = []

    def counted(spec, out_dir: Path) -> dict:
        ran.append(spec.name)
        return made_up_case(spec, out_dir)

    monkeypatch.setitem(STUDIES, "off-highway", dataclasses.replace(STUDIES["off-highway"], run_case=counted))
    table = run_study("off-highway", tmp_path, seeds=(2, 7))
    assert sorted(set(table["seed"])) == [2, 7] and len(table) == len(ran) == 16
    assert seed_table(table)["seeds"].tolist() == ["2,7", "2,7"]
    ran.clear()
    table = run_study("off-highway", tmp_path, seeds="2,7,9")  # the same directory, one seed more
    assert len(table) == 24 and len(ran) == 8 and all("_seed-9_" in name for name in ran)
    assert seed_table(table)["seeds"].tolist() == ["2,7,9", "2,7,9"]


def test_a_case_that_failed_is_said_failed_in_the_pooled_table_the_command_writes(tmp_path: Path, monkeypatch) -> None:
    def failing(spec, out_dir: Path) -> dict:
        labels = dict(spec.labels)
        if labels["feedback"] == "viso_ot_fused" and labels["conditions"] == "field" and labels["seed"] == 1:
            raise RuntimeError("the renderer stopped")  # the case runs and fails: its row is recorded as failed
        return made_up_case(spec, out_dir)

    monkeypatch.setitem(STUDIES, "off-highway", dataclasses.replace(STUDIES["off-highway"], run_case=failing))
    out = tmp_path / "oh"
    table = run_study("off-highway", out, seeds=(0, 1))
    assert (table["status"] == "failed").sum() == 1
    pooled = pd.read_csv(out / "seeds.csv")
    # failed, not "no fused-fed case" (never run): the pooled table reads every case, the figures the others
    assert list(pooled["pooled_verdict"]) == [
        "held in 1 of 2 seeds (seed 1 missing: fused-fed case failed)",
        "held in 2 of 2 seeds",
    ]
    assert "fused-fed case failed" in (out / "table.md").read_text()
    cells = pd.read_csv(out / "cells.csv")
    assert len(cells) == 4  # the failed case is in no cell row
