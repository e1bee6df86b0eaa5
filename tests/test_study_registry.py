"""The study registry: one record per study, read by the study runner and the command line."""

import pickle

import pytest

from scenarios.studies import definitions
from scenarios.studies.cases import run_case
from scenarios.studies.registry import STUDIES, Study, vehicle_studies


def test_every_study_is_one_record_named_by_its_key() -> None:
    assert list(STUDIES) == [
        "paper-section3",
        "estimators-under-slip",
        "paper-section4",
        "field-loop",
        "field-bias",
        "unit-steering",
        "controller-limits",
        "off-highway",
        "off-highway-roughness",
    ]
    for name, study in STUDIES.items():
        assert isinstance(study, Study) and study.name == name and study.summary
        assert pickle.loads(pickle.dumps(study.run_case)) is study.run_case  # a worker can import it
    assert definitions.STUDIES is STUDIES  # the command line reads the same registry


def test_only_the_vehicle_studies_take_a_vehicle() -> None:
    assert set(vehicle_studies()) == {
        "unit-steering",
        "estimators-under-slip",
        "field-loop",
        "controller-limits",
        "off-highway",
    }
    with pytest.raises(ValueError, match="paper-section3 takes no vehicle"):
        STUDIES["paper-section3"].case_specs(False, "au-b-double")


def test_a_study_without_its_own_runner_runs_the_plain_case() -> None:
    assert STUDIES["paper-section3"].run_case is run_case
    assert STUDIES["field-bias"].run_case is not run_case


def test_the_field_bias_summary_says_what_it_compares() -> None:
    summary = STUDIES["field-bias"].summary
    assert "before" in summary and "after" in summary and "fixes" not in summary
