"""The camera's 6-DoF motion on terrain through the rendered images and the odometry, into VISO-OT's level frame.

Small images (672 × 196) and few frames. The fast test drives straight up a tilted plane (a 10 % grade with 3 %
crossfall) and on the level road: the odometry's 3-D motion on the grade matches the ideal camera's, in the mean over
the frames, within 1 cm and 0.05° of the level road's error (each frame within 4 cm and 0.1°), and VISO-OT's
level-frame kingpin increments match the horizontal truth within 4 cm and 0.1°. The slow test drives a steady turn
on the tilted plane and on the level road: VISO-OT's RMS error against the truth-fed buffer on the plane within
3 cm of the level road's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from scenarios.camera.build import frame_odometry, stereo_camera
from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from vehicle_model.geometry import CombinationPose
from vehicle_model.terrain_pose import unit_attitude

pytestmark = pytest.mark.rendering

SMALL = {"camera.width": 672, "camera.height": 196}


@dataclass(frozen=True)
class TiltedPlane:
    a: float
    b: float

    def height(self, p):
        p = np.asarray(p, float)
        return self.a * p[:, 0] + self.b * p[:, 1]

    def gradient(self, p):
        return np.tile([self.a, self.b], (len(p), 1))


PLANE = TiltedPlane(0.10, 0.03)


def _rotation_angle(r: np.ndarray) -> float:
    return math.acos(max(-1.0, min(1.0, 0.5 * (float(np.trace(r)) - 1.0))))


@pytest.fixture(scope="module")
def setup():
    return build_scenario(load_scenario("constant-slip", SMALL))


def _drive(setup, camera, odometry, poses, terrain):
    """Render and process every pose; return the odometry's frames and the ideal left-camera poses."""
    params = setup.params
    frames, cams = [], []
    for k, pose in enumerate(poses):
        left, right = camera.pair(pose, k)
        tilt = None
        if odometry.estimator.level_reference == "accelerometer":
            att = unit_attitude(params, pose, terrain, 1)
            tilt = (float(att.pitch), float(att.roll))
        frames.append(odometry.process(left, right, tilt=tilt))
        cams.append(camera.rig.camera_in_world(params, pose, "left", terrain))
    return frames, cams


def _errors(frames, cams):
    """Per-frame translation [m] and rotation [rad] errors of the odometry's motions against the ideal camera's."""
    out = []
    for k in range(1, len(frames)):
        result = frames[k].vo
        assert result.valid, result.reason
        truth = np.linalg.inv(cams[k - 1]) @ cams[k]
        m = result.camera_motion
        out.append((np.linalg.norm(m[:3, 3] - truth[:3, 3]), _rotation_angle(m[:3, :3].T @ truth[:3, :3])))
    return np.array(out)


def test_the_odometry_sees_the_cameras_3d_motion_on_a_grade_and_the_level_frame_makes_it_horizontal(setup):
    poses = [CombinationPose(30.0 + 0.5 * k, 0.0, 0.0, 0.0) for k in range(5)]
    level_camera = stereo_camera(setup, ideal=True)
    level = _errors(*_drive(setup, level_camera, frame_odometry(setup, level_camera.optics), poses, None))
    camera = stereo_camera(setup, ideal=True, terrain=PLANE)
    odometry = frame_odometry(setup, camera.optics, level_reference="accelerometer")
    frames, cams = _drive(setup, camera, odometry, poses, PLANE)
    grade = _errors(frames, cams)
    assert grade[:, 0].mean() <= level[:, 0].mean() + 0.01 and grade[:, 0].max() < 0.04
    assert grade[:, 1].mean() <= level[:, 1].mean() + math.radians(0.05) and grade[:, 1].max() < math.radians(0.1)
    # the kingpin's horizontal step is 0.5 m straight ahead; the level frame recovers it from the 3-D motion
    estimator = odometry.estimator
    for k in range(1, len(poses)):
        increment, _ = estimator.level_increment(frames[k].vo.camera_motion, estimator.tilt)
        assert abs(increment[0] - 0.5) < 0.04 and abs(increment[1]) < 0.04 and abs(math.degrees(increment[2])) < 0.1
