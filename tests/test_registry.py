"""The estimator registry: names the recorded columns can carry, the ``estimators`` section checked against it, the
per-unit choices taken from it (no run: configurations only)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from pydantic import BaseModel, ConfigDict, Field

from scenarios.config import ConfigError, load_scenario, validate_config
from scenarios.estimator_settings import estimator_settings
from scenarios.registry import (
    EstimatorEntry,
    check_estimator_name,
    estimator_entries,
    feedback_sources,
    register_estimator,
    source_colour,
    unit_feedback_sources,
    unregister_estimator,
)
from scenarios.unit_feedback import REAR_FEEDBACK

ROOT = Path(__file__).resolve().parents[1]
COMBINATIONS = ROOT / "tests" / "data" / "combinations"


def _build(context: Any) -> Any:
    raise AssertionError("no run builds it here")


@pytest.mark.parametrize(
    ("name", "rule"),
    [
        ("2fast", "identifier"),
        ("zero-slip", "identifier"),
        ("gnss_é", "identifier"),
        ("GNSS", "lowercase"),
        ("_private", "underscore"),
        ("none", "'none'"),
        ("truth_delayed", "start with 'truth'"),
        ("truthy", "start with 'truth'"),
        ("gnss_std", "'_std'"),
        ("gnss3", "digit"),
        ("truth3", "start with 'truth'"),
    ],
)
def test_a_name_the_columns_cannot_carry_is_refused_naming_the_rule(name: str, rule: str) -> None:
    with pytest.raises(ValueError, match=f"estimator name {name!r} must .*{rule}"):
        check_estimator_name(name)
    with pytest.raises(ValueError, match=rule):
        EstimatorEntry(name, "refused", _build)


def test_the_names_the_grammar_takes_pass() -> None:
    for name in ("truth", "zero_slip", "viso_ot_fused", "gnss_rtk", "v2x_fused"):
        check_estimator_name(name)


def test_a_declaration_refuses_an_import_string_and_per_unit_without_its_builder() -> None:
    with pytest.raises(ValueError, match="callable"):
        EstimatorEntry("gnss", "a string is no builder", "scenarios.loop.estimators:zero_slip")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="build_unit"):
        EstimatorEntry("gnss", "per unit, but how", _build, per_unit=True)


class GnssSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    noise_m: float = Field(0.02, ge=0.0, le=1.0)


@pytest.fixture
def gnss() -> Iterator[EstimatorEntry]:
    entry = EstimatorEntry(
        "gnss", "a GNSS receiver on each unit (a test)", _build, colour="#123456", settings=GnssSettings,
        per_unit=True, build_unit=_build,
    )  # fmt: skip
    register_estimator(entry)
    try:
        yield entry
    finally:
        unregister_estimator(entry.name)


def test_a_registered_estimator_gets_a_switch_settings_a_colour_and_per_unit_feedback(gnss: EstimatorEntry) -> None:
    assert feedback_sources()[-1] == "gnss" and source_colour("gnss") == "#123456"
    assert unit_feedback_sources() == ("none", "truth", "zero_slip", "viso_ot", "viso_ot_fused", "gnss")
    assert load_scenario("roundabout-3").enabled_estimators() == ("zero_slip", "truth")  # off unless turned on
    config = load_scenario("roundabout-3", {"estimators.gnss": True})
    assert config.enabled_estimators() == ("zero_slip", "truth", "gnss")
    assert estimator_settings(config, "gnss") == GnssSettings()
    config = load_scenario("roundabout-3", {"estimators.gnss": {"noise_m": 0.1}})
    assert "gnss" in config.enabled_estimators() and estimator_settings(config, "gnss").noise_m == 0.1
    # fed back, it is switched on and its settings kept
    config = load_scenario("roundabout-3", {"vehicle": "lst", "feedback": "gnss", "estimators.gnss": {"noise_m": 0.1}})
    assert "gnss" in config.enabled_estimators() and estimator_settings(config, "gnss").noise_m == 0.1
    # a unit behind the first may be steered on it
    b_double = yaml.safe_load((COMBINATIONS / "b-double.yaml").read_text(encoding="utf-8"))
    b_double["units"][2]["axles"][1]["steerable"] = True
    config = validate_config({"vehicle": {"name": "b-double", **b_double}, "rear_feedback": ["gnss"]})
    assert config.rear_feedback == ("gnss",)


def test_the_section_refuses_in_one_line_naming_the_field_and_the_choices(gnss: EstimatorEntry) -> None:
    cases = [
        ({"estimators.gnns": True}, r"estimators: 'gnns' is not a registered estimator .*did you mean 'gnss'\?.*gnss"),
        ({"estimators.gnss": "yes"}, "estimators: gnss = 'yes': must be true or false or a mapping of its settings"),
        ({"estimators.gnss": {"noise_m": 5.0}}, "estimators: gnss.noise_m: Input should be less than or equal to 1"),
        ({"estimators.gnss": {"nosie_m": 0.1}}, "estimators: gnss.nosie_m: Extra inputs are not permitted"),
        ({"estimators.truth": True}, "'truth' is not a registered estimator"),  # it always runs: no switch
    ]
    for overrides, message in cases:
        with pytest.raises(ConfigError, match=message) as refused:
            load_scenario("roundabout-3", overrides)
        assert len(str(refused.value).strip().splitlines()) == 2  # the heading and one line


def test_the_built_in_switches_load_as_before() -> None:
    old_form = {"zero_slip": False, "viso_ot": True, "viso_ot_fused": False, "zero_slip_variant": "steer_angle"}
    config = load_scenario("roundabout-3", {"estimators": old_form})
    defaults = {"zero_slip_rear_point": "axle_mean", "zero_slip_grade": "none"}  # later fields, at their defaults
    assert config.estimators.model_dump() == {**old_form, **defaults}
    assert config.enabled_estimators() == ("viso_ot", "truth")
    assert load_scenario("roundabout-3", {"estimators.viso_ot_fused": True}).enabled_estimators() == (
        "zero_slip", "viso_ot", "viso_ot_fused", "truth"
    )  # fmt: skip
    assert REAR_FEEDBACK == ("none", "truth", "zero_slip", "viso_ot", "viso_ot_fused")  # on each unit's own rig
    assert [e.name for e in estimator_entries() if e.switch is None] == ["truth"]


def test_reading_the_names_imports_neither_the_loop_nor_numpy() -> None:
    code = (
        "import sys; from scenarios.registry import feedback_sources, estimator_entries; feedback_sources(); "
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'numpy', 'OpenGL', 'cv2', 'sensor', 'controller'}), "
        "sorted(m for m in sys.modules if m.startswith('scenarios.')))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert done.stdout.split("] ")[0] == "["
    assert "'scenarios.loop.builtin_estimators'" in done.stdout and "'scenarios.loop.estimators'" not in done.stdout
