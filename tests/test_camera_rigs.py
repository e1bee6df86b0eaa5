"""The camera section as a list of rigs: the one-camera form unchanged, the defaults of longer combinations, each
rig's seed and the refusals naming the field."""

from __future__ import annotations

import pytest

from scenarios.camera.build import rig_from_config, rig_seed, rig_settings, rigs_from_config
from scenarios.camera_schema import CameraConfig, StereoRigConfig, rig_configs
from scenarios.config import ConfigError, load_scenario
from sensor.camera import StereoRig
from vehicle_model.errors import InputError

CAMERA = {"estimators.viso_ot": True}


def test_the_one_camera_form_dumps_and_resolves_as_the_section_itself() -> None:
    config = load_scenario("roundabout-3", {**CAMERA, "camera.baseline": 0.7, "camera.psi_c2v_deg": 270.0})
    assert "rigs" not in config.camera.model_dump()  # written as it was read
    (rig,) = rig_configs(config.camera, config.vehicle_params())
    assert {name: getattr(rig, name) for name in StereoRigConfig.model_fields} == {
        name: getattr(config.camera, name) for name in StereoRigConfig.model_fields
    }
    assert rig.unit == 1
    # the rig of rig 0 is the one camera's, field for field (unit 1)
    assert rig_from_config(config) == rig_from_config(config.camera)
    assert rig_from_config(config).unit == 1 and rig_from_config(config).baseline == 0.7


def test_rig_zero_draws_with_the_runs_seed_and_the_others_apart() -> None:
    assert rig_seed(7, 0) == 7
    assert len({rig_seed(7, 1), rig_seed(7, 2), rig_seed(8, 1), 7}) == 4
    assert rig_seed(7, 1) == rig_seed(7, 1)  # reproducible


def test_a_longer_combination_has_side_rigs_on_units_that_tow_and_a_rear_rig_on_the_last() -> None:
    config = load_scenario("roundabout-3", {**CAMERA, "vehicle": "au-a-double"})
    rigs = rig_configs(config.camera, config.vehicle_params())
    assert [(r.unit, r.facing, r.psi_c2v_deg) for r in rigs] == [
        (1, "left", 270.0),
        (2, "left", 270.0),
        (3, "rear", 180.0),
    ]
    assert rigs[0].lateral == pytest.approx(1.25) and rigs[2].lateral == 0.0  # the 2.5 m unit's left edge
    # the lead trailer's side rig midway between the tractor's rear (1.75 m behind the kingpin) and the dolly's
    # front (12.0 + 2.2 m behind it), not beside the unit it tows; the rear rig at its unit's rear
    assert rigs[0].station == pytest.approx(-0.5 * (1.75 + 14.2)) and rigs[2].station is None
    assert [r.unit for r in rigs_from_config(config)] == [1, 2, 3]


def test_a_rig_sets_its_own_fields_over_the_sections() -> None:
    rigs = [{"unit": 1}, {"unit": 2, "facing": "right", "baseline": 1.0, "flex": {"vibration_rms_deg": [0.01] * 3}}]
    settings = {**CAMERA, "vehicle": "au-b-double", "camera.width": 640, "camera.rigs": rigs}
    config = load_scenario("roundabout-3", settings)
    first, second = rig_settings(config, 0), rig_settings(config, 1)
    assert (first.width, first.baseline, first.psi_c2v_deg) == (640, 0.5, 180.0)
    assert (second.width, second.baseline, second.psi_c2v_deg, second.lateral) == (640, 1.0, 90.0, -1.25)
    assert second.flex.vibration_rms_deg == (0.01, 0.01, 0.01) and first.flex.vibration_rms_deg == (0.0, 0.0, 0.0)
    assert rig_from_config(config, 1) == StereoRig.from_degrees(
        hfov_deg=100.0, psi_c2v_deg=90.0, width=640, height=391, baseline=1.0, lateral=-1.25, unit=2, station=-6.075
    )  # a side rig on the last unit: midway between the lead trailer's rear (1.15 m behind it) and its own (11.0 m)
    dumped = config.camera.model_dump(mode="json")["rigs"]
    assert dumped[1]["baseline"] == 1.0 and "width" not in dumped[1]  # only what the rig sets
    with pytest.raises(InputError, match="rig_index = 2"):
        rig_settings(config, 2)


@pytest.mark.parametrize(
    ("rigs", "message"),
    [
        ([{"unit": 1}, {"unit": 4}], r"^camera\.rigs\[1\]\.unit = 4: a towed unit of 'au-b-double', 1 to 2$"),
        ([{"unit": 1}, {"unit": 1, "facing": "left"}], r"^camera\.rigs\[1\]\.unit = 1: unit 1 has a rig already"),
        ([{"unit": 2}], r"^camera\.rigs: no rig on towed unit 1"),
        ([{"unit": 1}, {"unit": 2, "baseline": 0.01}], r"^camera\.rigs\[1\]\.baseline = 0\.01 m gives"),
    ],
)
def test_rigs_the_combination_cannot_carry_are_refused_in_one_line(rigs: list, message: str) -> None:
    with pytest.raises(InputError, match=message) as info:
        load_scenario("roundabout-3", {**CAMERA, "vehicle": "au-b-double", "camera.rigs": rigs})
    assert "\n" not in str(info.value)


def test_a_run_wide_field_in_a_rig_is_refused_naming_it() -> None:
    with pytest.raises(ConfigError, match=r"camera\.rigs\[0\]\.world"):
        load_scenario("roundabout-3", {**CAMERA, "camera.rigs": [{"unit": 1, "world": "airfield"}]})
    with pytest.raises(ConfigError, match=r"camera\.rigs\[0\]\.unit = 0"):
        load_scenario("roundabout-3", {**CAMERA, "camera.rigs": [{"unit": 0}]})
    assert CameraConfig().rigs is None


def test_every_unit_steered_on_its_own_camera_and_a_unit_without_a_rig_refused() -> None:
    steered = {"vehicle.units[1].axles[2].steerable": True, "vehicle.units[2].axles[2].steerable": True}
    config = load_scenario("roundabout-3", {"vehicle": "au-b-double", **steered, "feedback": "viso_ot_fused"})
    assert config.uses_camera and config.rear_feedback is None  # the rear trailer on its own fused camera too
    mixed = {"feedback": "viso_ot", "rear_feedback": ["zero_slip"], "camera.rigs": [{"unit": 1}]}
    load_scenario("roundabout-3", {"vehicle": "au-b-double", **steered, **mixed})  # unit 2 on zero-slip: no rig needed
    with pytest.raises(ConfigError, match=r"rear_feedback\[0\] = 'viso_ot' steers towed unit 2 on its camera"):
        load_scenario("roundabout-3", {"vehicle": "au-b-double", **steered, **mixed, "rear_feedback": ["viso_ot"]})
