"""A camera on any towed unit: the unit's frame from the chain's articulation, and the rig mounted on it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensor.camera import StereoRig
from vehicle_model.geometry import ChainPose, CombinationPose, towed_outlines, trailer_frames, unit_frame
from vehicle_model.presets import vehicle_preset


@pytest.fixture(scope="module")
def b_double():
    return vehicle_preset("au-b-double")


def test_unit_frame_is_the_chain_frame_of_each_unit(b_double):
    """Each unit's kingpin and heading equal trailer_frames' (to 1e-12 m / rad) at an arbitrary pose."""
    pose = ChainPose(3.0, -2.0, 0.7, (0.3, -0.2))
    frames = trailer_frames(b_double, pose.x, pose.y, pose.psi1, pose.angles)
    for unit, (origin, heading) in enumerate(frames, start=1):
        got_origin, got_heading = unit_frame(b_double, pose, unit)
        np.testing.assert_allclose(got_origin, origin, atol=1e-12)
        assert got_heading == pytest.approx(float(heading), abs=1e-12)
    # the rear unit's heading is ψ1 − Γ − Γ2
    assert unit_frame(b_double, pose, 2)[1] == pytest.approx(0.7 - 0.3 + 0.2, abs=1e-12)


def test_a_combination_pose_gives_the_first_unit_only(b_double):
    pose = CombinationPose(1.0, 2.0, 0.1, 0.2)
    assert unit_frame(b_double, pose, 1)[1] == pytest.approx(0.1 - 0.2)
    with pytest.raises(ValueError, match="unit 2 needs 2"):
        unit_frame(b_double, pose, 2)
    with pytest.raises(ValueError, match="1 to 2"):
        unit_frame(b_double, ChainPose(0, 0, 0, (0.0, 0.0)), 3)


def test_a_rear_unit_rig_sits_at_that_units_rear(b_double):
    """A rear-facing rig on unit 2 (station: its rear) sits on the rear unit's rear edge, 3 m up, looking back."""
    pose = ChainPose(0.0, 0.0, 0.4, (0.25, -0.3))
    rig = StereoRig(unit=2)
    left, right = rig.camera_in_world(b_double, pose, "left"), rig.camera_in_world(b_double, pose, "right")
    centre = 0.5 * (left[:3, 3] + right[:3, 3])
    rear_left, rear_right = towed_outlines(b_double, pose.x, pose.y, pose.psi1, pose.angles)[1][[3, 2]]
    np.testing.assert_allclose(centre[:2], 0.5 * (rear_left + rear_right), atol=1e-9)
    assert centre[2] == pytest.approx(3.0)
    heading = 0.4 - 0.25 + 0.3
    axis = left[:3, 2]  # optical axis: backwards along the rear unit
    np.testing.assert_allclose(axis[:2], [-math.cos(heading), -math.sin(heading)], atol=1e-12)


def test_first_unit_rig_is_unchanged_by_a_chain_pose(b_double):
    """On unit 1 a ChainPose and its CombinationPose mount the camera identically (bit for bit)."""
    pose = ChainPose(5.0, 1.0, -0.3, (0.2, 0.1))
    rig = StereoRig()
    np.testing.assert_array_equal(
        rig.camera_in_world(b_double, pose, "left"), rig.camera_in_world(b_double, pose.combination, "left")
    )


def test_arrays_of_poses_on_a_rear_unit(b_double):
    psi = np.array([0.0, 0.5, 1.0])
    pose = ChainPose(np.zeros(3), np.zeros(3), psi, (0.1 * psi, -0.1 * psi))
    poses = StereoRig(unit=2).camera_in_world(b_double, pose, "left")
    assert poses.shape == (3, 4, 4)
    one = StereoRig(unit=2).camera_in_world(b_double, ChainPose(0.0, 0.0, 0.5, (0.05, -0.05)), "left")
    np.testing.assert_allclose(poses[1], one, atol=1e-12)


def test_rig_unit_is_checked():
    with pytest.raises(Exception, match="unit"):
        StereoRig(unit=0)
