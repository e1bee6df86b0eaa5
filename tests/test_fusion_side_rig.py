"""A run's fused filter takes the side rig's settings for a camera that looks across its motion, and only there.

A run's ``fusion`` section (:class:`~scenarios.configuration.sections.FusionConfig`) gives a side rig the states of
the odometry's error along its optical axis (eq (3') of :mod:`sensor.fusion_model`) and the kinematics they are
found against (``side_rig``); a rear rig's filter is the section's alone. The steady turn of
``tests/test_unit_fusion.py`` with the field tractor–semi-trailer: the rear rig's estimates are the same, to the bit,
with and without the side settings; the side rig's filter carries the two extra states and the error state.
"""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.configuration.sections import FusionConfig
from sensor.camera import StereoRig
from tests.test_unit_fusion import drive
from vehicle_model.presets import VEHICLE_PRESETS

TICKS = 300  # 18 m: past the 12 m follow point
NONE_GIVEN = dict.fromkeys(
    ("vo_axial_flow", "vo_axial_scale", "vo_axial_scale_walk", "kinematic_rear_point", "kinematic_error_model")
)


@pytest.fixture(scope="module")
def field():
    return VEHICLE_PRESETS["field"]()


def test_the_side_settings_apply_to_a_camera_looking_across_its_motion_only() -> None:
    config = FusionConfig()
    assert config.for_camera((-1.0, 0.0)) is config  # rear-facing
    assert config.for_camera((0.0, 1.0)).vo_axial_flow == config.side_rig.vo_axial_flow > 0.0  # left-facing
    assert config.for_camera((0.0, -1.0)).kinematic_error_model == "state"  # right-facing
    assert FusionConfig(side_rig=NONE_GIVEN).for_camera((0.0, 1.0)).vo_axial_flow == 0.0  # none given


def test_setting_one_side_rig_field_keeps_the_others_defaults() -> None:
    """``--set fusion.side_rig.vo_axial_flow=0.1`` changes that one setting; ``null`` gives the section's own."""
    from scenarios.config import load_scenario

    defaults = load_scenario("roundabout-3").fusion.side_rig
    one = load_scenario("roundabout-3", {"fusion.side_rig.vo_axial_flow": 0.1}).fusion.side_rig
    assert one.vo_axial_flow == 0.1 and defaults.vo_axial_flow != 0.1
    assert one.model_dump(exclude={"vo_axial_flow"}) == defaults.model_dump(exclude={"vo_axial_flow"})
    dropped = load_scenario("roundabout-3", {"fusion.side_rig.kinematic_error_model": None}).fusion
    assert dropped.side_rig.kinematic_error_model is None and dropped.side_rig.vo_axial_scale == defaults.vo_axial_scale
    assert dropped.for_camera((0.0, 1.0)).kinematic_error_model == dropped.kinematic_error_model


def test_a_tractor_semi_rear_run_is_unchanged_by_the_side_settings(field) -> None:
    rear = StereoRig.from_degrees(psi_c2v_deg=180.0)
    with_side = drive(field, 1, rear, fused=True, ticks=TICKS, noise=FusionConfig())
    without = drive(field, 1, rear, fused=True, ticks=TICKS, noise=FusionConfig(side_rig=NONE_GIVEN))
    assert np.isfinite(with_side[0]).sum() > TICKS // 4  # estimates to compare
    for a, b in zip(with_side[:3], without[:3], strict=True):
        assert np.array_equal(a, b, equal_nan=True)
    assert with_side[3].state.size == 7


def test_a_side_rig_takes_the_axial_states(field) -> None:
    side = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275)
    est, _, ref, fused = drive(field, 1, side, fused=True, ticks=TICKS, noise=FusionConfig())
    assert fused.state.size == 10  # the seven, ε_k, s_z and s_f
    late = np.isfinite(est) & np.isfinite(ref)
    assert late.any()
    # exact motions, but the side settings' speed-compensated rear point expects the tractor's rear tyres to slip,
    # which this kinematic turn's do not: within 0.1 m
    assert np.max(np.abs(est[late] - ref[late])) < 0.1
