"""Each unit's kinematic pitch and roll on a terrain (vehicle_model/terrain_pose.py) and the camera's 6-DoF pose."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from analytic_terrains import TiltedPlane

from sensor.camera import StereoRig
from sensor.vehicle_bodies import unit_poses
from vehicle_model.geometry import ChainPose, CombinationPose, kingpin_position, tractor_points, unit_frame
from vehicle_model.presets import reference_laden, vehicle_preset
from vehicle_model.terrain import FlatTerrain
from vehicle_model.terrain_pose import is_flat, unit_attitude, unit_attitudes


@dataclass(frozen=True)
class Ramp:
    """Level before x = x0, then a constant grade g."""

    grade: float
    x0: float = 0.0

    def height(self, points):
        x = np.asarray(points, float)[:, 0]
        return self.grade * np.maximum(x - self.x0, 0.0)

    def gradient(self, points):
        x = np.asarray(points, float)[:, 0]
        return np.column_stack([np.where(x > self.x0, self.grade, 0.0), np.zeros(len(x))])


def _expected(a: float, b: float, psi: float) -> tuple[float, float]:
    """Pitch and roll of a body on the plane z = a·x + b·y heading psi (docs/terrain_camera.md §1)."""
    pitch = -math.atan(a * math.cos(psi) + b * math.sin(psi))
    roll = math.atan((b * math.cos(psi) - a * math.sin(psi)) * math.cos(pitch))
    return pitch, roll


@pytest.mark.parametrize("psi1, gamma", [(0.0, 0.0), (0.7, 0.3), (-2.1, -0.5)])
def test_every_unit_on_a_tilted_plane_has_the_plane_attitude_exactly(psi1, gamma):
    params = reference_laden()
    plane = TiltedPlane(0.12, -0.05, 3.0)
    pose = CombinationPose(20.0, -4.0, psi1, gamma)
    atts = unit_attitudes(params, pose, plane)
    for att, psi in zip(atts, (psi1, psi1 - gamma), strict=True):
        pitch, roll = _expected(plane.a, plane.b, psi)
        assert abs(float(att.pitch) - pitch) < 1e-9
        assert abs(float(att.roll) - roll) < 1e-9
        r = att.rotation
        assert np.allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert abs(math.atan2(r[1, 0], r[0, 0]) - math.remainder(psi, 2 * math.pi)) < 1e-12  # yaw unchanged
    kp = kingpin_position(params, 20.0, -4.0, psi1)
    assert abs(float(atts[1].z) - float(plane.height(kp[None])[0])) < 1e-9  # the kingpin's ground on the plane


def test_a_semi_trailer_on_a_ramp_pitches_by_the_grade_and_does_not_roll():
    params = reference_laden()
    grade = 0.15
    # Heading +x, the whole combination past the ramp's foot: the trailer pitches nose up by atan(grade).
    pose = CombinationPose(60.0, 0.0, 0.0, 0.0)
    att = unit_attitude(params, pose, Ramp(grade), unit=1)
    assert abs(float(att.pitch) + math.atan(grade)) < 1e-9
    assert abs(float(att.roll)) < 1e-12
    # Driving down the ramp (heading −x): nose down.
    pose = CombinationPose(60.0, 0.0, math.pi, 0.0)
    att = unit_attitude(params, pose, Ramp(grade, x0=-100.0), unit=1)
    assert abs(float(att.pitch) - math.atan(grade)) < 1e-9


def test_the_trailer_front_rides_on_the_tractor_over_a_crest():
    """Tractor past the crest of a ramp, trailer axles before it: the kingpin follows the tractor's plane, not the
    ground below the kingpin."""
    params = reference_laden()
    pose = CombinationPose(0.0, 0.0, 0.0, 0.0)
    kp = kingpin_position(params, 0.0, 0.0, 0.0)
    ramp = Ramp(0.10, x0=float(kp[0]) + 0.5)  # kingpin just short of the ramp, tractor's steer axle on it
    atts = unit_attitudes(params, pose, ramp)
    tractor, trailer = atts
    assert float(tractor.pitch) < 0.0  # the tractor's nose is lifted
    assert float(trailer.pitch) < 0.0  # the trailer's front is lifted by the fifth wheel
    r = tractor.rotation
    # The kingpin's height on the tractor's contact plane at the kingpin's horizontal position.
    steer = tractor_points(params, 0.0, 0.0, 0.0, np.zeros((1, 2)))[0]  # the tractor's origin, station 0
    z0 = float(tractor.z)
    n = r[:, 2]
    expected = z0 - (n[0] * (kp[0] - steer[0]) + n[1] * (kp[1] - steer[1])) / n[2]
    assert abs(float(trailer.z) - expected) < 1e-9
    assert float(trailer.z) > 0.0  # although the ground below the kingpin is at 0


def test_attitudes_vectorise_over_pose_arrays_and_further_units():
    params = vehicle_preset("au-b-double")
    plane = TiltedPlane(0.04, 0.08)
    psi = np.array([0.1, 1.2, -0.4])
    pose = ChainPose(np.array([1.0, 5.0, -3.0]), np.zeros(3), psi, (np.full(3, 0.2), np.full(3, -0.1)))
    atts = unit_attitudes(params, pose, plane)
    assert len(atts) == 3
    for k, att in enumerate(atts):
        heading = psi if k == 0 else np.asarray(unit_frame(params, pose, k)[1])
        for i in range(3):
            pitch, roll = _expected(plane.a, plane.b, float(heading[i]))
            assert abs(att.pitch[i] - pitch) < 1e-9 and abs(att.roll[i] - roll) < 1e-9
    assert unit_attitudes(params, CombinationPose(0.0, 0.0, 0.0, 0.0), plane)[2] is None


def test_flat_terrain_is_recognised():
    assert is_flat(None) and is_flat(FlatTerrain()) and not is_flat(TiltedPlane(0.0, 0.0))
    att = unit_attitude(reference_laden(), CombinationPose(3.0, 1.0, 0.4, 0.1), FlatTerrain())
    assert float(att.pitch) == 0.0 and float(att.roll) == 0.0 and float(att.z) == 0.0


# -- the camera's 6-DoF pose ----------------------------------------------------------------------------------------


def test_camera_poses_on_flat_terrain_are_bit_identical_to_the_level_road():
    params = vehicle_preset("au-b-double")
    psi = np.array([0.1, 1.2, -0.4])
    chain = ChainPose(np.array([1.0, 5.0, -3.0]), np.zeros(3), psi, (np.full(3, 0.2), np.full(3, -0.1)))
    for rig in (StereoRig(width=64, height=32), StereoRig(width=64, height=32, unit=2, lateral=0.3)):
        for which in ("left", "right"):
            level = rig.camera_in_world(params, chain, which)
            assert np.array_equal(level, rig.camera_in_world(params, chain, which, FlatTerrain()))
            assert np.array_equal(level, rig.camera_in_world(params, chain, which, None))
    one = ChainPose(1.0, 5.0, 0.1, (0.2, -0.1))
    frames = unit_poses(params, one)
    flat = unit_poses(params, one, FlatTerrain())
    assert all((a is None and b is None) or np.array_equal(a, b) for a, b in zip(frames, flat, strict=True))


def test_camera_on_a_tilted_plane_is_mount_height_above_it_along_its_normal_and_turned_with_the_unit():
    params = reference_laden()
    plane = TiltedPlane(-0.08, 0.06, 1.5)
    rig = StereoRig(width=64, height=32)
    pose = CombinationPose(10.0, 2.0, 0.9, 0.25)
    att = unit_attitude(params, pose, plane)
    for which in ("left", "right"):
        cam = rig.camera_in_world(params, pose, which, plane)
        normal = att.rotation[:, 2]
        ground = np.array([cam[0, 3], cam[1, 3], plane.height(cam[None, :2, 3])[0]])
        assert abs((cam[:3, 3] - ground) @ normal - rig.mount_height) < 1e-9  # height above the plane, along normal
        level = rig.camera_in_world(params, pose, which)
        # the same camera in the unit's frame: rotation R_world←unit times the level rotation's unit part
        yaw = np.array([[math.cos(0.65), -math.sin(0.65), 0.0], [math.sin(0.65), math.cos(0.65), 0.0], [0, 0, 1]])
        assert np.allclose(cam[:3, :3], att.rotation @ yaw.T @ level[:3, :3], atol=1e-12)
    frames = unit_poses(params, pose, plane)
    assert np.allclose(frames[1][:3, :3], att.rotation, atol=1e-15)
    assert abs(frames[1][2, 3] - float(att.z)) < 1e-12


@pytest.mark.parametrize("name", ["nordic-truck-dolly-semi", "au-a-double", "eu-truck-centre-axle"])
def test_dollies_drawbar_trailers_and_long_chains_have_the_plane_attitude_exactly(name):
    """A converter dolly rests on its own axles, a centre-axle trailer's eye on the truck: on a plane, all exact."""
    params = vehicle_preset(name)
    plane = TiltedPlane(0.07, -0.04, 2.0)
    pose = ChainPose(3.0, 4.0, 0.5, tuple([0.1] * len(params.trailers)))
    for k, att in enumerate(unit_attitudes(params, pose, plane)):
        psi = 0.5 if k == 0 else float(unit_frame(params, pose, k)[1])
        pitch, roll = _expected(plane.a, plane.b, psi)
        assert abs(float(att.pitch) - pitch) < 1e-9 and abs(float(att.roll) - roll) < 1e-9
