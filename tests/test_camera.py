"""Stereo rig geometry: camera axes, intrinsics, mounting (ψ_c2v), misalignment (de Saxe & Cebon 2018, §4.4).

No rendering.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensor.camera import (
    Misalignment,
    StereoRig,
    opencv_to_opengl,
    opengl_to_opencv,
    project,
    rotation_rpy,
)
from vehicle_model.errors import InputError
from vehicle_model.geometry import CombinationPose, trailer_points


def _random_pose(rng: np.random.Generator) -> np.ndarray:
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    t = np.eye(4)
    t[:3, :3] = r
    t[:3, 3] = rng.uniform(-50, 50, 3)
    return t


def test_opencv_opengl_round_trip_and_axes() -> None:
    rng = np.random.default_rng(1)
    poses = np.stack([_random_pose(rng) for _ in range(5)])
    gl = opencv_to_opengl(poses)
    np.testing.assert_allclose(opengl_to_opencv(gl), poses, atol=1e-12)
    # Same optical centre; the OpenGL camera looks down its −z, which is the OpenCV +z (forward),
    # and its +y (up) is the OpenCV −y (down); x (right) is shared.
    np.testing.assert_allclose(gl[:, :3, 3], poses[:, :3, 3])
    np.testing.assert_allclose(-gl[:, :3, 2], poses[:, :3, 2], atol=1e-12)
    np.testing.assert_allclose(-gl[:, :3, 1], poses[:, :3, 1], atol=1e-12)
    np.testing.assert_allclose(gl[:, :3, 0], poses[:, :3, 0], atol=1e-12)
    with pytest.raises(InputError):
        opencv_to_opengl(np.eye(3))


def test_intrinsics_from_image_size_and_hfov() -> None:
    rig = StereoRig()
    k = rig.intrinsics()
    f = 672.0 / math.tan(math.radians(50.0))  # (w/2) / tan(hfov/2)
    assert k[0, 0] == pytest.approx(f) and k[1, 1] == pytest.approx(f)
    assert (k[0, 2], k[1, 2]) == pytest.approx((671.5, 195.0))  # image centre, OpenCV pixel centres
    assert k[0, 1] == 0.0 and k[2].tolist() == [0.0, 0.0, 1.0]
    assert rig.vfov == pytest.approx(2 * math.atan(195.5 / f))


def test_point_in_front_projects_to_expected_pixel(reference) -> None:
    rig = StereoRig()
    state = CombinationPose(12.0, -4.0, 0.7, 0.2)  # X, Y, ψ1, Γ
    pose = rig.camera_in_world(reference, state, "left")
    k = rig.intrinsics()
    for xc, yc, zc in [(0.0, 0.0, 10.0), (2.0, -1.0, 20.0), (-5.0, 1.5, 7.5)]:
        world = pose[:3, :3] @ np.array([xc, yc, zc]) + pose[:3, 3]
        uv = project(k, np.linalg.inv(pose), world[None])[0]
        np.testing.assert_allclose(uv, [k[0, 2] + k[0, 0] * xc / zc, k[1, 2] + k[1, 1] * yc / zc], atol=1e-9)
    behind = pose[:3, :3] @ np.array([0.0, 0.0, -5.0]) + pose[:3, 3]
    assert np.all(np.isnan(project(k, np.linalg.inv(pose), behind[None])))


@pytest.mark.parametrize(
    ("psi_c2v_deg", "axis"),
    [(180.0, (-1.0, 0.0)), (90.0, (0.0, -1.0)), (270.0, (0.0, 1.0)), (0.0, (1.0, 0.0))],
)
def test_psi_c2v_facing_direction(psi_c2v_deg: float, axis: tuple[float, float]) -> None:
    """ψ_c2v is clockwise from the trailer's forward axis: 180° rear, 90° right (−y), 270° left (+y)."""
    rig = StereoRig.from_degrees(psi_c2v_deg=psi_c2v_deg, station=-12.0)
    for which in ("left", "right"):
        r = rig.camera_in_trailer(which)[:3, :3]
        np.testing.assert_allclose(r[:, 2], [*axis, 0.0], atol=1e-12)  # optical axis, horizontal
        np.testing.assert_allclose(r[:, 1], [0.0, 0.0, -1.0], atol=1e-12)  # image down = trailer down
        np.testing.assert_allclose(np.cross(r[:, 1], r[:, 2]), r[:, 0], atol=1e-12)  # right-handed
        assert np.linalg.det(r) == pytest.approx(1.0)


def test_mount_baseline_and_default_station(reference) -> None:
    rig = StereoRig(baseline=2.5, lateral=0.3, mount_height=3.2)
    with pytest.raises(InputError, match="station"):
        rig.camera_in_trailer("left")  # the trailer's rear is only known with the params
    tl = rig.camera_in_trailer("left", reference)
    tr = rig.camera_in_trailer("right", reference)
    mid = 0.5 * (tl[:3, 3] + tr[:3, 3])
    np.testing.assert_allclose(mid, [reference.trailer.rear_x, 0.3, 3.2], atol=1e-12)
    # The right camera sits +baseline along the camera x axis (OpenCV: right) of the left one.
    np.testing.assert_allclose(tl[:3, :3].T @ (tr[:3, 3] - tl[:3, 3]), [2.5, 0.0, 0.0], atol=1e-12)
    # Rear-facing: the image's right is the trailer's left (+y).
    np.testing.assert_allclose(tl[:3, 0], [0.0, 1.0, 0.0], atol=1e-12)
    with pytest.raises(InputError, match="left' or 'right"):
        rig.camera_in_trailer("centre", reference)  # type: ignore[arg-type]


def test_camera_in_world_follows_the_trailer(reference) -> None:
    rig = StereoRig(station=-10.0)
    x, y, psi1, gamma = np.array([1.0, 5.0]), np.array([-2.0, 3.0]), np.array([0.3, -1.2]), np.array([0.25, -0.1])
    poses = rig.camera_in_world(reference, CombinationPose(x, y, psi1, gamma), "left")
    assert poses.shape == (2, 4, 4)
    psi2 = psi1 - gamma
    for k in range(2):
        mount = trailer_points(reference, x[k], y[k], psi1[k], gamma[k], np.array([[-10.0, 0.0]]))[0]
        pose = CombinationPose(x[k], y[k], psi1[k], gamma[k])
        centre = 0.5 * (poses[k, :3, 3] + rig.camera_in_world(reference, pose, "right")[:3, 3])
        np.testing.assert_allclose(centre, [*mount, 3.0], atol=1e-9)
        # Rear-facing optical axis points along ψ2 + π in the world.
        np.testing.assert_allclose(poses[k, :3, 2], [-math.cos(psi2[k]), -math.sin(psi2[k]), 0.0], atol=1e-12)
        single = rig.camera_in_world(reference, pose, "left")
        np.testing.assert_allclose(single, poses[k], atol=1e-12)


def test_rotation_rpy_is_paper_eq_9() -> None:
    phi, theta, psi = 0.03, -0.02, 0.05  # roll, pitch, yaw
    rz = np.array([[math.cos(phi), -math.sin(phi), 0], [math.sin(phi), math.cos(phi), 0], [0, 0, 1]])
    ry = np.array([[math.cos(psi), 0, math.sin(psi)], [0, 1, 0], [-math.sin(psi), 0, math.cos(psi)]])
    rx = np.array([[1, 0, 0], [0, math.cos(theta), -math.sin(theta)], [0, math.sin(theta), math.cos(theta)]])
    np.testing.assert_allclose(rotation_rpy(phi, theta, psi), rz @ ry @ rx, atol=1e-15)
    m = Misalignment.from_degrees(roll=0.15, pitch=0.0, yaw=-0.1)
    assert (m.roll, m.pitch, m.yaw) == pytest.approx((math.radians(0.15), 0.0, math.radians(-0.1)))
    with pytest.raises(InputError, match=r"misalignment\.yaw"):
        Misalignment.from_degrees(yaw=45.0)


def test_misalignment_moves_right_image_points_by_homography(reference) -> None:
    """de Saxe & Cebon 2018, eq (8): a rotation about the optical centre maps pixels by K·R·K⁻¹."""
    ideal = StereoRig()
    rig = StereoRig.from_degrees(roll_deg=0.8, pitch_deg=-0.5, yaw_deg=1.2)
    k = rig.intrinsics()
    state = CombinationPose(3.0, 1.0, 0.4, 0.1)
    p_ideal = ideal.camera_in_world(reference, state, "right")
    p_real = rig.camera_in_world(reference, state, "right")
    np.testing.assert_allclose(p_ideal[:3, 3], p_real[:3, 3], atol=1e-12)  # same optical centre
    np.testing.assert_allclose(
        ideal.camera_in_world(reference, state, "left"), rig.camera_in_world(reference, state, "left"), atol=1e-12
    )
    rng = np.random.default_rng(3)
    cam_pts = np.column_stack([rng.uniform(-10, 10, 50), rng.uniform(-2, 2, 50), rng.uniform(3, 300, 50)])
    world = cam_pts @ p_ideal[:3, :3].T + p_ideal[:3, 3]
    uv0 = project(k, np.linalg.inv(p_ideal), world)
    uv1 = project(k, np.linalg.inv(p_real), world)
    h = rig.misalignment_homography()
    pred = np.column_stack([uv0, np.ones(len(uv0))]) @ h.T
    np.testing.assert_allclose(pred[:, :2] / pred[:, 2:], uv1, atol=1e-8)  # exact for every depth


def test_kitti_projection_matrices_give_disparity() -> None:
    rig = StereoRig(baseline=0.5)
    p0, p1 = rig.projection_matrices()
    f = rig.focal_length
    assert p1[0, 3] == pytest.approx(-f * 0.5)
    x = np.array([1.0, -0.5, 20.0, 1.0])
    u0, u1 = (p0 @ x)[:2] / (p0 @ x)[2], (p1 @ x)[:2] / (p1 @ x)[2]
    assert u0[0] - u1[0] == pytest.approx(f * 0.5 / 20.0)
    assert u0[1] == pytest.approx(u1[1])


@pytest.mark.parametrize(
    ("field", "value"),
    [("baseline", 0.0), ("width", 4), ("mount_height", -1.0), ("noise_std", -2.0), ("station", 40.0)],
)
def test_invalid_rig_names_the_field(field: str, value: float) -> None:
    with pytest.raises(InputError, match=rf"rig\.{field}"):
        StereoRig(**{field: value})


def test_from_degrees_converts_at_the_edge() -> None:
    rig = StereoRig.from_degrees(hfov_deg=90.0, psi_c2v_deg=270.0, yaw_deg=0.1, baseline=2.5)
    assert rig.hfov == pytest.approx(math.pi / 2)
    assert rig.psi_c2v == pytest.approx(1.5 * math.pi)
    assert rig.misalignment.yaw == pytest.approx(math.radians(0.1))
    assert rig.baseline == 2.5
    with pytest.raises(InputError, match="hfov"):
        StereoRig.from_degrees(hfov_deg=180.0)
    with pytest.raises(InputError, match="unknown stereo-rig setting"):
        StereoRig.from_degrees(focal=3.0)
