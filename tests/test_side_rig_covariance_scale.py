"""``fusion.side_rig.vo_covariance_scale``: a side rig's own factor on its odometry's motion covariance.

* Unset (the default) a side rig's filter takes the section's ``vo_covariance_scale``: its settings are the ones
  without the field, every one, and its measurement covariance the same to the bit.
* Set, a side rig's filter (optical axis across its motion) takes it and a rear rig's keeps the section's; the
  increment is unchanged and its covariance less the floor scales by the ratio of the two factors (1e-12 relative).
* A bad value is refused naming the field, before any work.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from scenarios.config import ConfigError, load_scenario
from sensor.camera import StereoRig
from sensor.fusion import FusedVisoOt
from sensor.fusion_noise import FusionNoise, SideRigFusion
from vehicle_model.presets import VEHICLE_PRESETS

PARAMS = VEHICLE_PRESETS["au-b-double"]()
SIDE = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.25, unit=1)
_YAW = 0.003
MOTION = np.array(
    [
        [np.cos(_YAW), 0.0, np.sin(_YAW), 0.05],
        [0.0, 1.0, 0.0, 0.01],
        [-np.sin(_YAW), 0.0, np.cos(_YAW), 0.9],
        [0.0, 0.0, 0.0, 1.0],
    ]
)
"""A camera motion of one frame (4×4, a turn of 3 mrad about the camera's y axis and a translation [m])."""
COVARIANCE = np.diag([1e-7, 2e-7, 1.5e-7, 1e-6, 4e-6, 2e-6]) + 1e-8
"""The odometry's 6×6 covariance of it."""


def _increment(noise: FusionNoise) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The side rig's filter's increment, its covariance and its floor (the covariance without the odometry's)."""
    camera = SIDE.camera_in_trailer("left", PARAMS)
    fused = FusedVisoOt(PARAMS, camera, noise.for_camera((0.0, 1.0)), unit=1)
    z, r = fused.measurement(MOTION, COVARIANCE)
    _, floor = fused.measurement(MOTION, np.zeros((6, 6)))
    return z, r, floor


def test_unset_a_side_rig_takes_the_sections_scale_bit_for_bit() -> None:
    """The default side rig's settings are the ones without the field and its covariance equals them bitwise."""
    default = FusionNoise()
    assert default.side_rig.vo_covariance_scale is None
    assert "vo_covariance_scale" not in default.side_rig.given()
    without = default.side_rig.model_dump()
    without.pop("vo_covariance_scale")
    assert default.for_camera((0.0, 1.0)) == FusionNoise(side_rig=without).for_camera((0.0, 1.0))
    assert default.for_camera((0.0, 1.0)).vo_covariance_scale == default.vo_covariance_scale
    z0, r0, _ = _increment(default)
    z1, r1, _ = _increment(FusionNoise(side_rig=SideRigFusion(**without)))
    assert np.array_equal(z0, z1) and np.array_equal(r0, r1)


def test_set_it_scales_the_side_rigs_covariance_alone() -> None:
    """Set to 1 under a section at 4: the side rig's covariance less its floor is a quarter, the increment the
    same, and a rear rig's (and a linked rig's) settings keep the section's."""
    noise = FusionNoise(vo_covariance_scale=4.0, side_rig={"vo_covariance_scale": 1.0})
    assert noise.for_camera((0.0, 1.0)).vo_covariance_scale == 1.0
    assert noise.for_camera((-1.0, 0.0)).vo_covariance_scale == 4.0
    assert noise.for_camera((-1.0, 0.0), unit=2).vo_covariance_scale == 4.0
    z4, r4, floor4 = _increment(FusionNoise(vo_covariance_scale=4.0))
    z1, r1, floor1 = _increment(noise)
    assert np.array_equal(z4, z1) and np.array_equal(floor4, floor1)
    odometry4, odometry1 = r4 - floor4, r1 - floor1
    assert np.abs(odometry4).max() > 0.0
    np.testing.assert_allclose(odometry1, odometry4 / 4.0, rtol=1e-12, atol=1e-12 * np.abs(odometry4).max())


def test_a_bad_scale_is_refused_naming_the_field() -> None:
    """Below 1 or above 1e4 is refused by the scenario's loader, naming the field, before any run."""
    for bad in (0.5, 2e4):
        with pytest.raises(ConfigError, match=re.escape("fusion.side_rig.vo_covariance_scale")):
            load_scenario("roundabout-3", {"vehicle": "lst", "fusion.side_rig.vo_covariance_scale": bad})
    config = load_scenario("roundabout-3", {"vehicle": "lst", "fusion.side_rig.vo_covariance_scale": 1.0})
    assert config.fusion.side_rig.vo_covariance_scale == 1.0
