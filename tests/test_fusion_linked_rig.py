"""A linked rig's filter takes ``fusion.linked_rig``'s settings, and only a linked rig's.

A linked rig (:mod:`sensor.fusion_linked_rig`) is a camera that looks along its unit on a towed unit whose front
coupling rides on another towed unit: a B-double's rear trailer, an A-double's dolly and rear trailer, a
truck–dolly–semi's semi-trailer. A tractor–semi-trailer's rear camera and every side rig do not take it. The steady
turn without slip of ``tests/test_unit_fusion.py`` (exact motions and signals): the linked settings left unset, or set
to the section's own values, give the section's filter to the bit; set otherwise they change the B-double's rear
filter and leave a tractor–semi-trailer's rear filter as it was, to the bit.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from scenarios.config import ConfigError, load_scenario
from scenarios.configuration.sections import FusionConfig
from sensor.camera import StereoRig
from sensor.fusion import FusedVisoOt
from sensor.fusion_model import BPSI
from tests.test_unit_fusion import drive
from vehicle_model.presets import VEHICLE_PRESETS

PAIR = {"scrub_bias_release": 0.0, "vo_yaw_bias_walk": 4e-5}  # both differ from a run's section (0.7, 2e-5)
REAR, LEFT = 180.0, 270.0  # the camera's yaw on its unit [°]: looking back along it, or across it


def _filter(preset: str, unit: int, psi_c2v: float, noise: FusionConfig) -> FusedVisoOt:
    params = VEHICLE_PRESETS[preset]()
    lateral = 0.0 if psi_c2v == REAR else 1.275
    rig = StereoRig.from_degrees(psi_c2v_deg=psi_c2v, lateral=lateral, unit=unit, station=-4.0)
    return FusedVisoOt(params, rig.camera_in_trailer("left", params), noise, unit=unit)


@pytest.mark.parametrize(
    ("preset", "unit", "psi_c2v", "linked"),
    [
        ("au-b-double-steered", 2, REAR, True),  # the rear trailer, on the lead trailer's fifth wheel
        ("au-b-double", 2, REAR, True),
        ("au-a-double", 3, REAR, True),  # the rear trailer, on the dolly
        ("au-a-double", 2, REAR, True),  # the dolly, on the lead trailer's hitch
        ("nordic-truck-dolly-semi", 2, REAR, True),  # the semi-trailer, on the dolly
        ("lst", 1, REAR, False),  # a tractor–semi-trailer's rear camera
        ("au-b-double-steered", 1, REAR, False),  # the lead trailer rides on the tractor
        ("au-b-double-steered", 1, LEFT, False),  # the lead's side rig
        ("au-b-double-steered", 2, LEFT, False),  # a side rig on the rear trailer: the side rig's settings
        ("au-a-double", 3, LEFT, False),
    ],
)
def test_a_linked_rig_takes_the_linked_settings_and_no_other_camera_does(preset, unit, psi_c2v, linked) -> None:
    section = FusionConfig(linked_rig=PAIR)
    noise = _filter(preset, unit, psi_c2v, section).noise
    if linked:
        assert (noise.scrub_bias_release, noise.vo_yaw_bias_walk) == (0.0, 4e-5)
        assert noise.model_dump(exclude={"scrub_bias_release", "vo_yaw_bias_walk"}) == section.model_dump(
            exclude={"scrub_bias_release", "vo_yaw_bias_walk"}
        )
    else:
        assert (noise.scrub_bias_release, noise.vo_yaw_bias_walk) == (0.7, 2e-5)  # the section's
    side = psi_c2v == LEFT
    assert (noise.vo_axial_scale == section.side_rig.vo_axial_scale) is side  # a side rig keeps the side rig's
    if not side and not linked:
        assert noise is section  # the section itself, untouched


def test_the_decision_is_by_the_unit_and_the_axis() -> None:
    section = FusionConfig(linked_rig={"scrub_bias_release": 0.2})
    assert section.for_camera((-1.0, 0.0), 2).scrub_bias_release == 0.2  # looking back along unit 2
    assert section.for_camera((1.0, 0.3), 3).scrub_bias_release == 0.2  # forward, a little across: still along
    assert section.for_camera((-1.0, 0.0)).scrub_bias_release == 0.7  # unit 1 unless told
    assert section.for_camera((0.3, -1.0), 2).scrub_bias_release == 0.7  # across: a side rig
    default = FusionConfig()
    assert default.for_camera((-1.0, 0.0), 2) is default  # nothing given: the section, the same object


@pytest.fixture(scope="module")
def b_double():
    return VEHICLE_PRESETS["au-b-double"]()


def test_the_b_doubles_rear_filter_is_unchanged_by_default_and_changed_by_each_setting(b_double) -> None:
    """This 20 m turn puts the unsteered rear trailer's axles past their scrub onset (``D`` ≈ 0.9 at the end)."""
    rear = StereoRig(unit=2)
    runs = {
        name: drive(b_double, 2, rear, fused=True, noise=FusionConfig(linked_rig=linked))
        for name, linked in (
            ("default", {}),
            ("own", {"scrub_bias_release": 0.7, "vo_yaw_bias_walk": 2e-5}),  # the section's values, given again
            ("walk", {"vo_yaw_bias_walk": 4e-5}),
            ("release", {"scrub_bias_release": 0.0}),
        )
    }
    default, own = runs["default"], runs["own"]
    assert np.isfinite(default[0]).sum() > 150  # estimates to compare
    for a, b in zip(default[:3], own[:3], strict=True):
        assert np.array_equal(a, b, equal_nan=True)
    assert np.array_equal(default[3].state, own[3].state) and np.array_equal(default[3].covariance, own[3].covariance)
    assert default[3].scrub_demand > 0.5  # (K6) acts: the release takes β_ψ out of the frames' motions
    variance = {name: run[3].covariance[BPSI, BPSI] for name, run in runs.items()}
    # a faster walk leaves β_ψ less known after the same path (+2.7 % here; the frames take most of it back)
    assert variance["walk"] > 1.01 * variance["default"]
    # with no release every frame's motion keeps carrying β_ψ, so it stays observed while the axles scrub (−74 %)
    assert variance["release"] < 0.5 * variance["default"]
    assert np.nanmean(runs["release"][1]) < np.nanmean(default[1])  # and the off-tracking's std with it


def test_a_tractor_semi_trailers_rear_filter_is_unchanged_by_the_setting() -> None:
    field = VEHICLE_PRESETS["field"]()
    rear = StereoRig.from_degrees(psi_c2v_deg=REAR)
    with_linked = drive(field, 1, rear, fused=True, ticks=300, noise=FusionConfig(linked_rig=PAIR))
    without = drive(field, 1, rear, fused=True, ticks=300, noise=FusionConfig())
    assert np.isfinite(without[0]).sum() > 75
    for a, b in zip(with_linked[:3], without[:3], strict=True):
        assert np.array_equal(a, b, equal_nan=True)


def test_a_run_parses_the_section_and_refuses_a_bad_value_naming_it() -> None:
    config = load_scenario("roundabout-3", {f"fusion.linked_rig.{name}": value for name, value in PAIR.items()})
    assert config.fusion.linked_rig.scrub_bias_release == 0.0 and config.fusion.linked_rig.vo_yaw_bias_walk == 4e-5
    assert config.fusion.scrub_bias_release == 0.7  # the section's own is untouched
    assert load_scenario("roundabout-3").fusion.linked_rig.given() == {}  # none by default
    for name, bad in (("scrub_bias_release", 1.5), ("scrub_bias_release", -0.1), ("vo_yaw_bias_walk", 2e-3)):
        with pytest.raises(ConfigError, match=re.escape(f"fusion.linked_rig.{name} = {bad:g}")):
            load_scenario("roundabout-3", {f"fusion.linked_rig.{name}": bad})
