"""The odometry's stereo search reaches the nearest road point in view (a side camera's near scenery, a wide
baseline), and leaves a rig that the default search covers as it was."""

from __future__ import annotations

import numpy as np
import pytest

from sensor.camera import StereoRig
from sensor.field_optics import NEAR_FEATURE_MARGIN, FieldOptics, road_disparity_search
from sensor.vo.config import VOConfig
from sensor.vo.prior_ranges import default_ranges


def _config(rig: StereoRig) -> VOConfig:
    return VOConfig.from_horizontal_fov(rig.width, rig.height, rig.hfov, rig.baseline)


def test_a_rig_the_default_search_covers_is_left_as_it_was():
    rig = StereoRig(baseline=0.5)  # rear, 3 m up: the nearest road point in view has ~33 px of disparity
    config = _config(rig)
    left = rig.replace(station=0.0).camera_in_trailer("left")
    assert road_disparity_search(config, left, rig.width, rig.height) == config


@pytest.mark.parametrize("psi_c2v_deg", [270.0, 180.0])
def test_a_wide_baseline_searches_to_the_nearest_road_point(psi_c2v_deg):
    """The road point seen at a bottom corner of the image, placed in the trailer frame and projected into both
    cameras, has a disparity within the search (to 1 px, before the margin)."""
    rig = StereoRig.from_degrees(psi_c2v_deg=psi_c2v_deg, baseline=2.5, lateral=1.275, station=-10.0)
    left, right = rig.camera_in_trailer("left"), rig.camera_in_trailer("right")
    config = road_disparity_search(_config(rig), left, rig.width, rig.height)
    assert config.max_disparity is not None and config.stereo_search_radius == config.max_disparity
    # the road point behind the bottom-left pixel: the ray from the left camera to z = 0 of the trailer
    ray = left[:3, :3] @ np.array([(0.0 - config.cu) / config.f, (rig.height - 1.0 - config.cv) / config.f, 1.0])
    point = left[:3, 3] + ray * (-left[2, 3] / ray[2])
    u = []
    for camera in (left, right):
        local = np.linalg.inv(camera) @ np.append(point, 1.0)
        u.append(config.cu + config.f * local[0] / local[2])
    disparity = u[0] - u[1]
    assert disparity > config.search_radius  # the default search would not reach it
    assert config.max_disparity == pytest.approx(NEAR_FEATURE_MARGIN * disparity, abs=1.5)


def test_the_first_passs_stereo_steps_search_the_disparity_and_the_flow_steps_their_radius():
    config = VOConfig(f=500.0, cu=300.0, cv=100.0, baseline=2.5, max_disparity=240)
    lo, hi = default_ranges(config)
    assert lo[0, 0] == -240 and hi[2, 0] == 240  # stereo steps: u on the side of non-negative disparity
    assert hi[0, 0] == 0 and lo[2, 0] == 0
    r = config.search_radius
    assert (lo[[1, 3]] == -r).all() and (hi[[1, 3]] == r).all()
    plain = default_ranges(config.model_copy(update={"max_disparity": None}))
    assert plain[0][0, 0] == -r and plain[1][2, 0] == r  # None: as libviso2


def test_field_optics_give_the_odometry_the_wide_search():
    rig = StereoRig.from_degrees(psi_c2v_deg=270.0, baseline=2.5, lateral=1.275)
    assert FieldOptics.build(rig).vo_config().max_disparity is not None
    assert FieldOptics.build(StereoRig()).vo_config().max_disparity is None
