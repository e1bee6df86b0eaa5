"""VISO-OT on terrain that is not a plane (sensor/level_reference.py, sensor/viso_ot.py): an ideal camera's 3-D motion.

The ideal camera's motion between frames is exact (poses from ``StereoRig.camera_in_world`` on the terrain), so the
only differences from the level road are the terrain's: with the true tilt the level frame is exact and the estimate
equals the level road's to rounding (1e-9 m); with the odometry's integrated tilt from a known start likewise (the
ideal motions carry no rotation noise); with an accelerometer's tilt (bias 0.3° in pitch and roll, noise 0.05° per
frame) within 2 cm of it (the bias turns the camera's 3 m lever arm by 1.6 cm). The planar eqs fed the same 3-D
motions are worse on the ramp and the waves by more than that (docs/terrain_camera.md §4 has the figures).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import pytest
from analytic_terrains import TiltedPlane

from sensor.camera import StereoRig
from sensor.level_reference import AccelerometerTilt, split_yaw, tilt_angles, tilt_rotation
from sensor.viso_ot import VisoOtEstimator
from vehicle_model.errors import InputError
from vehicle_model.geometry import CombinationPose, kingpin_position
from vehicle_model.presets import reference_laden
from vehicle_model.terrain import FlatTerrain
from vehicle_model.terrain_pose import unit_attitude


@dataclass(frozen=True)
class Ramp:
    """Level for x < x0, then a 12 % grade."""

    x0: float = 5.0
    grade: float = 0.12

    def height(self, p):
        return self.grade * np.maximum(np.asarray(p, float)[:, 0] - self.x0, 0.0)

    def gradient(self, p):
        x = np.asarray(p, float)[:, 0]
        return np.column_stack([np.where(x > self.x0, self.grade, 0.0), np.zeros(len(x))])


@dataclass(frozen=True)
class Undulation:
    """Crossing waves: 0.25 m amplitude, 9 m and 14 m wavelengths, on a 6 % grade."""

    def height(self, p):
        p = np.asarray(p, float)
        return 0.06 * p[:, 0] + 0.25 * np.sin(2 * math.pi * p[:, 0] / 9.0) * np.cos(2 * math.pi * p[:, 1] / 14.0)

    def gradient(self, p):
        p = np.asarray(p, float)
        kx, ky = 2 * math.pi / 9.0, 2 * math.pi / 14.0
        return np.column_stack(
            [
                0.06 + 0.25 * kx * np.cos(kx * p[:, 0]) * np.cos(ky * p[:, 1]),
                -0.25 * ky * np.sin(kx * p[:, 0]) * np.sin(ky * p[:, 1]),
            ]
        )


def steady_turn(params, radius: float, frames: int, speed: float = 5.0, dt: float = 0.1) -> list[CombinationPose]:
    """A kinematic tractor–semi-trailer: tractor CG on a circle (anticlockwise) from x = 0, heading +x; the trailer
    heading follows its kingpin without slip (sub-stepped)."""
    l_axle = float(np.mean(params.trailer_axle_distances(1)))
    poses, psi2, sub = [], 0.0, 20
    for k in range(frames):
        for j in range(sub):
            t = (k + j / sub) * dt
            th = speed * t / radius
            x, y, psi1 = radius * math.sin(th), radius * (1 - math.cos(th)), th
            kp = kingpin_position(params, x, y, psi1)
            th2 = speed * (t + dt / sub) / radius
            kp2 = kingpin_position(params, radius * math.sin(th2), radius * (1 - math.cos(th2)), th2)
            v = (kp2 - kp) / (dt / sub)
            psi2 += (v[1] * math.cos(psi2) - v[0] * math.sin(psi2)) / l_axle * (dt / sub)
        th = speed * k * dt / radius
        poses.append(CombinationPose(radius * math.sin(th), radius * (1 - math.cos(th)), th, th - psi2))
    return poses


def _motions(rig, params, poses, terrain):
    cams = [rig.camera_in_world(params, p, "left", terrain) for p in poses]
    return [np.linalg.inv(a) @ b for a, b in itertools.pairwise(cams)]


def _run(estimator, motions, tilts=None):
    out = []
    for k, m in enumerate(motions):
        out.append(estimator.update(m, None if tilts is None else tilts[k + 1]))
    return np.array([np.nan if e is None else e for e in out])


@pytest.fixture(scope="module")
def setting():
    params = reference_laden()
    rig = StereoRig(width=64, height=32)
    poses = steady_turn(params, 30.0, 140)
    level = _run(VisoOtEstimator(params, rig.camera_in_trailer("left", params)), _motions(rig, params, poses, None))
    assert np.isfinite(level[-40:]).all() and np.nanmax(np.abs(level)) > 0.3  # a real off-tracking in the turn
    return params, rig, poses, level


@pytest.mark.parametrize("terrain", [TiltedPlane(0.06, 0.04), Ramp(), Undulation()], ids=["plane", "ramp", "wave"])
def test_the_level_frame_recovers_the_level_roads_estimate_on_terrain(setting, terrain):
    params, rig, poses, level = setting
    motions = _motions(rig, params, poses, terrain)
    atts = [unit_attitude(params, p, terrain) for p in poses]
    truth = [(float(a.pitch), float(a.roll)) for a in atts]
    left = rig.camera_in_trailer("left", params)
    given = _run(VisoOtEstimator(params, left, level_reference="accelerometer", initial_tilt=truth[0]), motions, truth)
    integrated = _run(VisoOtEstimator(params, left, level_reference="odometry", initial_tilt=truth[0]), motions)
    imu = AccelerometerTilt(math.radians(0.3), math.radians(-0.3), math.radians(0.05), seed=2)
    read = [imu.read(*t) for t in truth]
    measured = _run(VisoOtEstimator(params, left, level_reference="accelerometer", initial_tilt=read[0]), motions, read)
    planar = _run(VisoOtEstimator(params, left), motions)
    ok = np.isfinite(level)
    assert np.array_equal(ok, np.isfinite(given)) and np.array_equal(ok, np.isfinite(integrated))
    assert np.max(np.abs(given[ok] - level[ok])) < 1e-9
    assert np.max(np.abs(integrated[ok] - level[ok])) < 1e-9
    assert np.nanmax(np.abs(measured[ok] - level[ok])) < 0.02
    assert np.nanmax(np.abs(planar[ok] - level[ok])) > np.max(np.abs(given[ok] - level[ok]))
    if not isinstance(terrain, TiltedPlane):  # where the unit's tilt changes, the planar eqs fail
        assert np.nanmax(np.abs(planar[ok] - level[ok])) > 0.05


def test_on_a_level_road_every_level_reference_gives_the_planar_numbers_bit_for_bit(setting):
    params, rig, poses, level = setting
    motions = _motions(rig, params, poses, FlatTerrain())
    left = rig.camera_in_trailer("left", params)
    zero = [(0.0, 0.0)] * len(poses)
    given = _run(VisoOtEstimator(params, left, level_reference="accelerometer"), motions, zero)
    assert np.array_equal(given, level, equal_nan=True)
    integrated = _run(VisoOtEstimator(params, left, level_reference="odometry"), motions)
    assert np.nanmax(np.abs(integrated - level)) < 1e-12  # the ideal level motions' rounding only


def test_tilt_helpers_and_refused_inputs():
    a = tilt_rotation(0.1, -0.2)
    assert np.allclose(a @ a.T, np.eye(3), atol=1e-15)
    assert np.allclose(tilt_angles(a), (0.1, -0.2), atol=1e-15)
    rz = np.array([[math.cos(0.7), -math.sin(0.7), 0.0], [math.sin(0.7), math.cos(0.7), 0.0], [0.0, 0.0, 1.0]])
    yaw, tilt = split_yaw(rz @ a)
    assert abs(yaw - 0.7) < 1e-15 and np.allclose(tilt, a, atol=1e-15)
    params = reference_laden()
    left = StereoRig(width=64, height=32).camera_in_trailer("left", params)
    with pytest.raises(InputError, match="level_reference"):
        VisoOtEstimator(params, left, level_reference="gravity")
    with pytest.raises(InputError, match="accelerometer"):
        VisoOtEstimator(params, left, level_reference="accelerometer").update(np.eye(4))
    with pytest.raises(InputError, match="tilt given"):
        VisoOtEstimator(params, left).update(np.eye(4), (0.0, 0.0))
    with pytest.raises(InputError, match="bias_roll"):
        AccelerometerTilt(bias_roll=0.5)


def test_a_straight_drive_from_level_onto_a_ramp_with_the_tilt_integrated_from_the_level_start():
    params = reference_laden()
    rig = StereoRig(width=64, height=32)
    left = rig.camera_in_trailer("left", params)
    poses = [CombinationPose(-30.0 + 0.5 * k, 0.0, 0.0, 0.0) for k in range(160)]  # 80 m, the ramp from x = 5 m
    level = _run(VisoOtEstimator(params, left), _motions(rig, params, poses, None))
    ramp = _run(VisoOtEstimator(params, left, level_reference="odometry"), _motions(rig, params, poses, Ramp()))
    ok = np.isfinite(level)
    assert ok.sum() > 100 and np.array_equal(ok, np.isfinite(ramp))
    assert np.max(np.abs(ramp[ok] - level[ok])) < 1e-9 and np.max(np.abs(level[ok])) < 1e-9  # straight: no off-tracking


def test_the_fused_filters_camera_increment_is_viso_ots_level_frame_one(setting):
    """The fused filter's camera measurement on a terrain is VISO-OT's level-frame kingpin increment (1e-12), frame
    after frame with the tilt it carries over from :meth:`FusedVisoOt.measure`; the planar increment it replaces is
    off by more than 5 mm on the waves (so the test sees which one is used)."""
    from sensor.fusion import FusedVisoOt
    from sensor.level_reference import tilt_rotation

    params, rig, poses, _ = setting
    terrain = Undulation()
    motions = _motions(rig, params, poses, terrain)
    truth = [(float(a.pitch), float(a.roll)) for a in (unit_attitude(params, p, terrain) for p in poses)]
    left = rig.camera_in_trailer("left", params)
    fused = FusedVisoOt(params, left, level_reference="accelerometer")
    viso = VisoOtEstimator(params, left, level_reference="accelerometer", initial_tilt=truth[0])
    fused.geometry.tilt = viso.tilt
    worst_planar = 0.0
    for k, motion in enumerate(motions):
        z, _ = fused.measurement(motion, None, tilt_rotation(*truth[k + 1]))
        expected, _ = viso.level_increment(motion, tilt_rotation(*truth[k + 1]))
        np.testing.assert_allclose(z, expected, rtol=0, atol=1e-12)
        worst_planar = max(worst_planar, float(np.max(np.abs(np.array(viso.kingpin_increment(motion)) - z))))
        viso.update(motion, truth[k + 1])
        fused.measure(k + 1, motion, None, truth[k + 1])  # no propagation yet: only the tilt is carried over
        np.testing.assert_array_equal(fused.geometry.tilt, viso.tilt)
    assert worst_planar > 0.005
    with pytest.raises(InputError, match="tilt"):
        fused.measure(1, motions[0], None, None)


def test_horizontal_speed_is_the_wheel_speed_times_the_cosine_of_the_pitch_alone():
    """``u·cos θ`` to 1e-15 whatever the roll; a level tilt returns the speed bit for bit."""
    from sensor.level_reference import horizontal_speed

    for pitch, roll in [(0.12, 0.0), (-0.1, 0.07), (0.0, 0.2)]:
        assert horizontal_speed(7.0, tilt_rotation(pitch, roll)) == pytest.approx(7.0 * math.cos(pitch), abs=1e-15)
    assert horizontal_speed(7.3, tilt_rotation(0.0, 0.0)) == 7.3


@pytest.mark.parametrize("grade", [0.12, -0.10])
def test_the_fused_filter_takes_the_wheel_speed_along_a_grade_as_horizontal(grade):
    """A straight drive up (or down) a constant grade at 8 m/s horizontal, the wheel speed read along the ground
    (``u/cos θ``, 0.7 % and 0.5 % more), the camera's exact motions with the true tilt at 10 Hz, the filter at
    50 Hz: with the speed made horizontal the filter's wheel-speed bias stays under 5 mm/s, where the along-ground
    excess it would otherwise have to learn is 40–57 mm/s (so the test sees which speed the model takes)."""
    from sensor.fusion import FusedVisoOt

    params, rig = reference_laden(), StereoRig(width=64, height=32)
    terrain, speed, dt, every, ticks = TiltedPlane(grade, 0.0), 8.0, 0.02, 5, 1500
    poses = [CombinationPose(speed * k * dt, 0.0, 0.0, 0.0) for k in range(0, ticks, every)]
    motions = _motions(rig, params, poses, terrain)
    tilts = [(float(a.pitch), float(a.roll)) for a in (unit_attitude(params, p, terrain) for p in poses)]
    assert abs(math.cos(tilts[0][0]) - 1.0 / math.hypot(1.0, grade)) < 1e-12  # the unit lies on the grade
    along_ground = speed * math.hypot(1.0, grade)
    fused = FusedVisoOt(params, rig.camera_in_trailer("left", params), level_reference="accelerometer")
    fused.geometry.tilt = tilt_rotation(*tilts[0])
    for k in range(ticks):
        fused.propagate(k, dt, 0.0, along_ground)
        if k % every == 0 and k > 0:
            fused.measure(k, motions[k // every - 1], np.eye(6) * 1e-6, tilts[k // every])
    from sensor.fusion_model import BW

    assert abs(float(fused.state[BW])) < 0.005, fused.state[BW]
    assert along_ground - speed > 0.035


def test_the_zero_slip_measurement_takes_the_tractors_wheel_speed_made_horizontal():
    """The tractor's wheel speed, read along the ground, enters the zero-slip kinematics (K1) as ``u·cos θ`` with
    the unit's pitch (to 1e-15, whatever the roll) and unchanged, bit for bit, on a level unit: a measurement that
    took the along-ground speed would put ``u·(1 − cos θ)·sin Γ`` (0.7 % of the speed at 12 %) into the kingpin's
    lateral velocity in a turn."""
    from sensor.fusion import FusedVisoOt
    from sensor.unit_kinematics import TractorSignals

    params, rig = reference_laden(), StereoRig(width=64, height=32)
    for pitch, roll in ((math.atan(0.12), 0.03), (math.atan(-0.10), -0.05), (0.0, 0.0)):
        fused = FusedVisoOt(params, rig.camera_in_trailer("left", params), level_reference="accelerometer")
        assert fused.noise.kinematics
        fused.geometry.tilt = tilt_rotation(pitch, roll)
        taken: list[float] = []
        measure = fused._chain.lateral

        def spy(signals, dt, measure=measure, taken=taken):
            taken.append(signals.speed)
            return measure(signals, dt)

        fused._chain.lateral = spy
        for k in range(3):
            fused.propagate(k, 0.02, 0.1, 8.0, None, TractorSignals(8.0, 0.12, 0.2))
        assert len(taken) == 2
        for speed in taken:
            if pitch == 0.0:
                assert speed == 8.0
            else:
                assert speed == pytest.approx(8.0 * math.cos(pitch), abs=1e-15)
