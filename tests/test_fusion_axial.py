"""The axial states' uncertainty at the fused increments' sensitivity (``vo_axial_effect: posterior``,
:mod:`sensor.fusion_axial`).

The steady turn of ``tests/test_unit_fusion.py`` with the field tractor–semi-trailer and a left side rig, the axial
states of (3') on. Where the zero-slip kinematics carry the lateral motion, an error of the axial states hardly moves
the fused increments, so the std's axial part shrinks (the estimate is the same to the bit: the option changes the
std only); where the camera carries the lateral motion alone (no tractor signals) and overstates its axial motion by
3 %, the std still covers the estimate's error on every tick.
"""

from __future__ import annotations

import numpy as np
import pytest

from sensor.camera import StereoRig
from sensor.fusion import FusionNoise
from sensor.fusion_axial import AxialRegression
from tests.test_unit_fusion import drive
from vehicle_model.presets import VEHICLE_PRESETS

TICKS = 400  # 24 m: past the 12 m follow point
AXIAL = {
    "vo_axial_flow": 0.05,
    "vo_axial_scale": 0.04,
    "vo_axial_scale_walk": 0.001,
    "kinematic_error_model": "state",
}


@pytest.fixture(scope="module")
def runs():
    params = VEHICLE_PRESETS["field"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275)
    out = {}
    for effect in ("camera", "posterior"):
        noise = FusionNoise(vo_axial_effect=effect, **AXIAL)
        out[effect, True] = drive(params, 1, rig, fused=True, ticks=TICKS, noise=noise)
        out[effect, False] = drive(
            params, 1, rig, fused=True, ticks=TICKS, signals=False, noise=noise, axial_scale=1.03
        )
    return out


def test_where_the_kinematics_carry_the_lateral_motion_the_axial_part_of_the_std_shrinks(runs) -> None:
    est_c, std_c, _, _ = runs["camera", True]
    est_p, std_p, _, fused = runs["posterior", True]
    np.testing.assert_array_equal(est_p, est_c)  # the std only
    assert fused._axial_regression is not None
    on = np.isfinite(std_c) & np.isfinite(est_c)
    assert on.sum() > TICKS // 4
    assert np.all(std_p[on] <= std_c[on] + 1e-12)
    late = on & (np.arange(TICKS) > 300)
    assert np.mean(std_p[late]) < 0.8 * np.mean(std_c[late])


def test_where_the_camera_alone_carries_it_the_std_still_covers_an_axial_scale_error(runs) -> None:
    est, std, ref, _ = runs["posterior", False]
    both = np.isfinite(est) & np.isfinite(ref) & (np.arange(TICKS) > 250)
    error = np.abs(est[both] - ref[both])
    assert both.sum() > 100 and np.max(error) > 0.005  # an error to cover
    assert np.all(error <= 2.0 * std[both])


def test_an_increment_the_camera_alone_measures_has_the_cameras_own_sensitivity() -> None:
    """(A1): a covariance in which the increment's lateral error is the axial state's error times the camera's
    axial motion ``a`` (and nothing else) gives the regression ``a`` on the lateral entry and zero elsewhere."""
    a = 0.37
    j = np.array([0.0, a, 0.0, 1.0])  # (Δx, Δy, Δψ, s) as linear functions of s alone, plus independent noise below
    p = 0.04**2 * np.outer(j, j) + np.diag([1e-4, 0.0, 1e-6, 0.0])
    regression = AxialRegression([3]).regression(p)
    np.testing.assert_allclose(regression[:, 0], [0.0, a, 0.0], atol=1e-12)


def test_a_rear_rig_is_the_same_to_the_bit_with_the_option() -> None:
    """A rear rig has no axial states (a run gives them to side rigs only): ``posterior`` changes nothing of it."""
    params = VEHICLE_PRESETS["field"]()
    rear = StereoRig.from_degrees(psi_c2v_deg=180.0)
    runs = [
        drive(params, 1, rear, fused=True, ticks=250, noise=FusionNoise(vo_axial_effect=effect))
        for effect in ("camera", "posterior")
    ]
    assert np.isfinite(runs[0][0]).sum() > 25
    for a, b in zip(runs[0][:3], runs[1][:3], strict=True):
        assert np.array_equal(a, b, equal_nan=True)


def test_the_side_rigs_axial_effect_and_the_scrub_release_are_refused_outside_their_values() -> None:
    """A scenario's ``fusion.side_rig.vo_axial_effect`` other than ``camera``/``posterior`` and a
    ``fusion.scrub_bias_release`` outside [0, 1] are refused in one line naming the field, before any run."""
    from scenarios.config import ConfigError, load_scenario

    with pytest.raises(ConfigError, match=r"fusion\.side_rig\.vo_axial_effect"):
        load_scenario("roundabout-3", {"vehicle": "lst", "fusion": {"side_rig": {"vo_axial_effect": "both"}}})
    with pytest.raises(ConfigError, match=r"fusion\.scrub_bias_release"):
        load_scenario("roundabout-3", {"vehicle": "lst", "fusion": {"scrub_bias_release": 1.5}})
    cfg = load_scenario("roundabout-3", {"vehicle": "lst", "fusion": {"side_rig": {"vo_axial_effect": "posterior"}}})
    assert cfg.fusion.side_rig.vo_axial_effect == "posterior" and cfg.fusion.scrub_bias_release == 0.7
