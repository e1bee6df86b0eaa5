"""The camera's 6-DoF motion on terrain through the rendered images and the odometry, into VISO-OT's level frame.

Small images (672 × 196) and few frames. The fast test drives straight up a tilted plane (a 10 % grade with 3 %
crossfall) and on the level road: the odometry's 3-D motion on the grade matches the ideal camera's, in the mean over
the frames, within 1 cm and 0.05° of the level road's error (each frame within 4 cm and 0.1°), and VISO-OT's
level-frame kingpin increments match the horizontal truth within 4 cm and 0.1°. The slow test (the paper's
1344 × 391 images) drives a steady 30 m turn on the level road, on the tilted plane and on undulations (0.25 m waves
on a 6 % grade), VISO-OT in its level frame with the run's accelerometer: its RMS error against the buffer fed the
ideal motions within 3 cm of the level road's on both (the planar eqs on the same frames are printed beside).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from analytic_terrains import TiltedPlane

from scenarios.camera.build import frame_odometry, stereo_camera
from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from vehicle_model.geometry import CombinationPose
from vehicle_model.terrain_pose import unit_attitude

pytestmark = pytest.mark.rendering

SMALL = {"camera.width": 672, "camera.height": 196}


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


@pytest.mark.slow
def test_viso_ot_in_a_steady_turn_on_a_plane_and_on_waves_is_within_3_cm_rms_of_the_level_roads():
    from sensor.level_reference import trailer_accelerometer
    from sensor.viso_ot import VisoOtEstimator
    from sensor.world import RoadPath, build_world
    from tests.test_terrain_camera_viso import Undulation, steady_turn

    setup = build_scenario(load_scenario("constant-slip"))  # the paper's image size: the odometry's accuracy
    params = setup.params
    radius = 30.0
    poses = steady_turn(params, radius, 130)
    th = np.linspace(-0.5, 3.5, 800)
    road = RoadPath(radius * np.sin(th), radius * (1 - np.cos(th)), th)
    rig = stereo_camera(setup, ideal=True, world=build_world(road, seed=1)).rig
    truth = []
    ideal = VisoOtEstimator(params, rig.camera_in_trailer("left", params))  # the buffer fed the ideal motions
    cams = [rig.camera_in_world(params, p, "left") for p in poses]
    for a, b in itertools.pairwise(cams):
        value = ideal.update(np.linalg.inv(a) @ b)
        truth.append(np.nan if value is None else value)
    truth = np.array(truth)

    def rms_error(estimates) -> float:
        err = np.array([np.nan if e is None else e for e in estimates]) - truth
        ok = np.isfinite(err)
        assert ok.sum() > 40
        return float(np.sqrt(np.mean(err[ok] ** 2)))

    rms = {}
    for name, terrain in (("level", None), ("plane", PLANE), ("waves", Undulation())):
        camera = stereo_camera(setup, ideal=True, world=build_world(road, seed=1, terrain=terrain))
        reference = "planar" if terrain is None else "accelerometer"
        odometry = frame_odometry(setup, camera.optics, level_reference=reference)
        planar = VisoOtEstimator(params, rig.camera_in_trailer("left", params))
        imu = trailer_accelerometer(7)
        estimates, planar_estimates = [], []
        for k, pose in enumerate(poses):
            left, right = camera.pair(pose, k)
            tilt = None
            if terrain is not None:
                att = unit_attitude(params, pose, terrain, 1)
                tilt = imu.read(float(att.pitch), float(att.roll))
            frame = odometry.process(left, right, tilt=tilt)
            if k > 0:
                estimates.append(frame.estimate)
                planar_estimates.append(planar.update(frame.vo.camera_motion if frame.vo.valid else None))
        rms[name] = rms_error(estimates)
        rms[f"{name}_planar_eqs"] = rms_error(planar_estimates)
    print(rms)
    assert abs(rms["plane"] - rms["level"]) < 0.03, rms
    assert abs(rms["waves"] - rms["level"]) < 0.03, rms
