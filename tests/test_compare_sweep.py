"""``compare_feedback`` on the sweep runner: one recorded case per feedback, the same table serially and on local
workers, progress told during the runs (in this process) or as each ends (on workers)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from scenarios.config import load_scenario
from scenarios.studies.compare import compare_cases, compare_feedback
from scenarios.studies.records import CASES_DIR, read_record
from vehicle_model.errors import InputError

FEEDBACKS = ("none", "truth")


@pytest.fixture(scope="module")
def config():
    return load_scenario("roundabout-3", {"duration_s": 3.0, "vehicle": "lst"})


def test_every_feedback_is_one_case_of_the_same_configuration(config) -> None:
    cases = compare_cases(config, ("truth", "none", "truth"))
    assert [dict(c.labels)["feedback"] for c in cases] == ["truth", "none"]  # repeated once, in order
    for case in cases:
        data = dict(case.overrides)["config"]
        assert data["feedback"] == dict(case.labels)["feedback"]
        assert {k: v for k, v in data.items() if k != "feedback"} == {
            k: v for k, v in config.model_dump().items() if k != "feedback"
        }
    with pytest.raises(InputError, match="feedbacks \\['nope'\\]"):
        compare_cases(config, ("truth", "nope"))


def test_serial_and_parallel_comparisons_write_the_same_table(config, tmp_path: Path) -> None:
    told: list[tuple[str, float, float]] = []
    serial = compare_feedback(config, tmp_path / "serial", FEEDBACKS, progress=lambda *a: told.append(a))
    assert list(serial["feedback"]) == list(FEEDBACKS) and set(serial["status"]) == {"completed"}
    assert told[-1][0] == "truth" and told[-1][2] == pytest.approx(1.0)
    assert max(t for _, t, _ in told) > 2.0  # during the runs: their simulated time
    for feedback in FEEDBACKS:
        record = read_record(tmp_path / "serial", f"feedback-{feedback}")
        assert record is not None and record.ok
    assert (tmp_path / "serial" / "comparison.png").is_file()
    ended: list[tuple[str, float, float]] = []
    parallel = compare_feedback(
        config, tmp_path / "parallel", FEEDBACKS, progress=lambda *a: ended.append(a), workers=2
    )
    numbers = serial.select_dtypes("number").columns
    pd.testing.assert_frame_equal(serial[numbers], parallel[numbers])
    assert pd.read_csv(tmp_path / "serial" / "comparison.csv").equals(
        pd.read_csv(tmp_path / "parallel" / "comparison.csv")
    )
    assert sorted(e[2] for e in ended) == [0.5, 1.0]
    assert not (tmp_path / "parallel" / "table.csv").exists()  # only the comparison's own files
    assert len(list((tmp_path / "parallel" / CASES_DIR).glob("*.json"))) == len(FEEDBACKS)
