"""VISO-OT: camera motion → kingpin increments → off-tracking, on exact camera motions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scenarios.config import load_scenario
from scenarios.run.drive import simulate
from scenarios.setup.build import build_scenario
from sensor.viso_ot import VisoOtEstimator
from vehicle_model.errors import InputError
from vehicle_model.offtracking import OfftrackingBuffer, increments_from_poses


def camera_mount(facing_yaw: float, station: float, lateral: float, height: float) -> np.ndarray:
    """T_trailer←camera for a level camera looking along ISO yaw ``facing_yaw`` (OpenCV camera axes)."""
    forward = np.array([math.cos(facing_yaw), math.sin(facing_yaw), 0.0])
    right = np.array([math.sin(facing_yaw), -math.cos(facing_yaw), 0.0])
    down = np.array([0.0, 0.0, -1.0])
    t = np.eye(4)
    t[:3, :3] = np.column_stack([right, down, forward])
    t[:3, 3] = [station, lateral, height]
    return t


def trailer_pose(kx: float, ky: float, psi2: float) -> np.ndarray:
    t = np.eye(4)
    c, s = math.cos(psi2), math.sin(psi2)
    t[:2, :2] = [[c, -s], [s, c]]
    t[:2, 3] = [kx, ky]
    return t


@pytest.fixture(scope="module")
def run_columns():
    cfg = load_scenario("roundabout-3", {"path.turns": 0.3, "path.exit_length": 5.0, "path.entry_length": 15.0})
    return simulate(build_scenario(cfg))[1], build_scenario(cfg).params


@pytest.mark.parametrize(
    ("facing", "station", "lateral"),
    [(math.pi, -12.0, 0.0), (math.pi, -12.0, 0.8), (-1.5 * math.pi, -6.0, 1.2), (0.3, -3.0, -0.5)],
)
def test_exact_camera_motion_gives_the_true_offtracking(run_columns, facing, station, lateral):
    cols, params = run_columns
    frames = np.flatnonzero(cols["camera_frame"] > 0.5)
    mount = camera_mount(facing, station, lateral, 3.0)
    est = VisoOtEstimator(params, mount)
    truth = OfftrackingBuffer(params.follow_point_offset)
    prev_cam, prev_pose = None, None
    errors = []
    for k in frames:
        kp = np.array([cols["kingpin_x"][k], cols["kingpin_y"][k]])
        world_cam = trailer_pose(kp[0], kp[1], cols["psi2"][k]) @ mount
        if prev_cam is not None:
            e = est.update(np.linalg.inv(prev_cam) @ world_cam)
            truth.push(
                *increments_from_poses(np.vstack([prev_pose[0], kp]), np.array([prev_pose[1], cols["psi2"][k]]))[0]
            )
            t = truth.offtracking()
            if t is not None:
                assert e is not None
                errors.append(e - t)
                # and against the 50 Hz truth of the run (the 10 Hz chords differ by well under a millimetre)
                assert e == pytest.approx(cols["offtracking_truth"][k], abs=1e-3)
        prev_cam, prev_pose = world_cam, (kp, cols["psi2"][k])
    assert len(errors) > 100
    assert np.abs(errors).max() < 1e-9


def test_eq2_lever_arm_on_the_centre_line(reference):
    # Camera a behind the kingpin on the centre line, pure yaw Δψ about the camera: the kingpin moves
    # a·(cos Δψ − 1, sin Δψ) (de Saxe & Cebon 2018, eq (2) in ISO order).
    a, dpsi = 10.0, 0.05
    mount = camera_mount(math.pi, -a, 0.0, 3.0)
    est = VisoOtEstimator(reference, mount)
    rot_trailer = np.eye(4)
    rot_trailer[:2, :2] = [[math.cos(dpsi), -math.sin(dpsi)], [math.sin(dpsi), math.cos(dpsi)]]
    # camera motion = inv(mount) · (trailer rotation about the camera point) · mount
    about_camera = np.eye(4)
    about_camera[:3, 3] = mount[:3, 3]
    move = about_camera @ rot_trailer @ np.linalg.inv(about_camera)
    dx, dy, got = est.kingpin_increment(np.linalg.inv(mount) @ move @ mount)
    assert got == pytest.approx(dpsi, abs=1e-12)
    assert (dx, dy) == pytest.approx((a * (math.cos(dpsi) - 1.0), a * math.sin(dpsi)), abs=1e-12)


def test_failed_frames_are_bridged_then_reset(reference):
    mount = camera_mount(math.pi, -12.0, 0.0, 3.0)
    est = VisoOtEstimator(reference, mount, max_consecutive_failures=2)
    step = np.eye(4)
    step[2, 3] = -0.5  # rear-facing camera: driving forwards is camera −z
    for _ in range(30):
        value = est.update(step)
    assert value == pytest.approx(0.0, abs=1e-12)
    points = len(est.buffer)
    assert est.update(None) == pytest.approx(0.0, abs=1e-12)  # bridged with the last motion
    assert len(est.buffer) >= points
    est.update(None)
    assert est.update(None) is None  # the third failure in a row clears the buffer
    assert len(est.buffer) <= 1 and est.failed_frames == 3
    for _ in range(23):
        value = est.update(step)
    assert value is None  # 11.5 m driven: not yet a trailer length
    assert est.update(step) == pytest.approx(0.0, abs=1e-12)


def test_bad_mount(reference):
    with pytest.raises(InputError, match="rigid"):
        VisoOtEstimator(reference, np.ones((4, 4)))
