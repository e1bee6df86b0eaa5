"""A side rig's flow state ``s_f`` and the odometry's yaw error taken at the camera's lever (``vo_yaw_lever``).

A side camera's yaw error that is a rotation about the camera itself (its mount) moves the kingpin's increment
sideways by the camera's distance behind the kingpin times that error, the lever; eq (3) of :mod:`sensor.fusion_model`
couples only ``κ·c_y`` of it to ``β_ψ`` (the frame covariance's regression), and on a straight road the rest is
indistinguishable from the flow state's ``s_f·t·|t|``, which takes it. (3'') couples the lever along the optical axis
instead (docs/field_bias.md §7.24).

The LST drives kinematically (no tyre slips): its tractor's rear point straight for 10 s, then 10 s on a 30 m left
turn, at 3.5 m/s; the semi-trailer's heading keeps its zero-slip point (``L_c`` of eq (1)) without lateral velocity. Its
left side rig's motions are exact but for the injected error: (a) a yaw error of 1 mrad per metre, a rotation about
the camera, and no error along the optical axis; (b) no yaw error and an error ``0.03·t·|t|`` along the optical axis
(``t`` the frame's motion across it, as tests/test_side_camera_field.py injects). The frames' covariance correlates
the camera's yaw with its motion along its axis so that eq (3)'s ``κ·c_y`` is about half the 14.3 m lever, as the
field camera's is on the straight (docs/field_bias.md §7.24).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensor.camera import StereoRig
from sensor.fusion import FusedVisoOt, FusionNoise, TractorSignals
from vehicle_model.geometry import ChainPose, unit_frame
from vehicle_model.offtracking import OfftrackingBuffer, increments_from_poses
from vehicle_model.presets import VEHICLE_PRESETS

DT, EVERY = 0.02, 5  # control period [s], ticks per camera frame
SPEED, RADIUS = 3.5, 30.0  # the tractor's rear point [m/s], the turn's radius [m]
STRAIGHT, TICKS = 500, 1000  # 10 s straight, then 10 s of the turn
YAW_ERROR = 1e-3  # [rad/m] (a)
SUBSTEPS = 2  # of the kinematics per control period
FLOW_ERROR = 0.03  # [1/m] (b)
SIDE = {  # the side rig's states as a run's tafnsj settings give them, the gyro zeroed
    "vo_axial_flow": 0.05,
    "kinematic_error_model": "state",
    "vo_axial_effect": "posterior",
}


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """4×4 rotation by ``angle`` about the unit vector ``axis`` (Rodrigues), no translation."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    out = np.eye(4)
    out[:3, :3] = np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)
    return out


def _covariance(rho: float) -> np.ndarray:
    """The frames' odometry covariance of ``(rx, ry, rz, tx, ty, tz)``: 0.3 mrad and 5 mm, the yaw ``ry`` (about
    the camera's vertical) correlated ``rho`` with the motion ``tz`` along the optical axis."""
    c = np.diag([3e-4**2] * 3 + [5e-3**2] * 3)
    c[1, 5] = c[5, 1] = rho * 3e-4 * 5e-3
    return c


COVARIANCE = _covariance(0.5)


def drive(lever: bool, yaw_error: float = 0.0, flow_error: float = 0.0) -> dict[str, np.ndarray | FusedVisoOt]:
    """The fused filter over the straight and the turn: its estimates, the true off-tracking, ``s_f`` per tick."""
    params = VEHICLE_PRESETS["lst"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275)
    camera = rig.camera_in_trailer("left", params)
    fused = FusedVisoOt(params, camera, FusionNoise(**SIDE, vo_yaw_lever=lever))
    fused.zero_gyro(0.0, 500)
    vertical = camera[:3, :3].T @ np.array([0.0, 0.0, 1.0])  # the unit's vertical in the camera's axes
    ahead, kingpin_ahead = params.tractor_wheelbase(), params.tractor.fifth_wheel_x + params.tractor_wheelbase()
    cg_ahead = params.tractor.cg_x + ahead
    rear, psi1, psi2 = np.zeros(2), 0.0, 0.0
    truth = OfftrackingBuffer(params.follow_point_offset)
    steer = np.zeros(fused.steer_weights.size)
    est, ref, sf = [], [], []
    previous = last_world = None

    def rates(psi1: float, psi2: float, r1: float) -> tuple[float, float]:
        """The trailer's forward speed and yaw rate: its zero-slip point without lateral velocity, eq (1)."""
        f1, n1 = np.array([math.cos(psi1), math.sin(psi1)]), np.array([-math.sin(psi1), math.cos(psi1)])
        kingpin_velocity = SPEED * f1 + r1 * kingpin_ahead * n1
        u2 = kingpin_velocity[0] * math.cos(psi2) + kingpin_velocity[1] * math.sin(psi2)
        v2 = -kingpin_velocity[0] * math.sin(psi2) + kingpin_velocity[1] * math.cos(psi2)
        return float(u2), float(v2) / fused.slip_point

    for k in range(TICKS):
        r1 = 0.0 if k < STRAIGHT else SPEED / RADIUS
        u2, r2 = rates(psi1, psi2, r1)
        f1 = np.array([math.cos(psi1), math.sin(psi1)])
        cg = rear + cg_ahead * f1
        pose = ChainPose(float(cg[0]), float(cg[1]), psi1, (psi1 - psi2,))
        frame = unit_frame(params, pose, 1)
        if previous is not None:
            truth.push(*increments_from_poses(np.vstack([previous[0], frame[0]]), np.array([previous[1], frame[1]]))[0])
        previous = frame
        fused.propagate(k, DT, r2, u2, steer, TractorSignals(SPEED, r1, psi1 - psi2, math.nan))
        if k % EVERY == 0:
            world = rig.camera_in_world(params, pose, "left")
            if last_world is not None:
                motion = np.linalg.inv(last_world) @ world
                motion = motion @ _rotation(vertical, yaw_error * float(np.linalg.norm(motion[:3, 3])))
                motion[2, 3] += flow_error * motion[0, 3] * abs(motion[0, 3])
                fused.measure(k, motion, COVARIANCE)
            last_world = world
        est.append(math.nan if fused.estimate is None else fused.estimate)
        value = truth.offtracking()
        ref.append(math.nan if value is None else value)
        sf.append(fused.state[-1])
        for _ in range(SUBSTEPS):  # the rear point rolls along its heading; the trailer follows, eq (1)
            h = DT / SUBSTEPS
            rear = rear + SPEED * h * np.array([math.cos(psi1 + 0.5 * r1 * h), math.sin(psi1 + 0.5 * r1 * h)])
            k1 = rates(psi1, psi2, r1)[1]
            k2 = rates(psi1 + 0.5 * r1 * h, psi2 + 0.5 * h * k1, r1)[1]
            psi1, psi2 = psi1 + r1 * h, psi2 + h * k2
    return {"estimate": np.array(est), "truth": np.array(ref), "s_f": np.array(sf), "filter": fused}


@pytest.fixture(scope="module")
def yaw_runs() -> dict[bool, dict]:
    return {lever: drive(lever, yaw_error=YAW_ERROR) for lever in (False, True)}


def _turn_error(run: dict) -> np.ndarray:
    late = (np.arange(TICKS) >= STRAIGHT + 250) & np.isfinite(run["estimate"]) & np.isfinite(run["truth"])
    return run["estimate"][late] - run["truth"][late]


def test_eq_3_couples_about_half_the_lever_with_these_frames() -> None:
    """The premise: eq (3)'s ``κ·c_y`` of these frames is 5–9 m against the camera's 14.3 m behind the kingpin."""
    params = VEHICLE_PRESETS["lst"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275)
    camera = rig.camera_in_trailer("left", params)
    fused = FusedVisoOt(params, camera, FusionNoise(**SIDE))
    motion = np.eye(4)
    motion[0, 3] = SPEED * EVERY * DT
    _, r = fused.measurement(motion, COVARIANCE)
    assert 5.0 < fused.noise.vo_bias_coupling * r[1, 2] / r[2, 2] < 9.0
    assert fused.geometry.camera_position[0] == pytest.approx(-14.3)


def test_with_the_lever_the_flow_state_takes_no_yaw_error(yaw_runs) -> None:
    """(a): without the lever ``s_f`` takes the lever's uncoupled part (above 0.015 /m throughout the turn); with it
    ``s_f`` stays within 0.002 /m of 0 from 5 s on, and the turn's off-tracking error (from 5 s into it) is under a
    quarter of the plain filter's (which is over 5 mm RMS)."""
    plain, lever = yaw_runs[False], yaw_runs[True]
    assert np.min(np.abs(plain["s_f"][STRAIGHT:])) > 0.015
    assert np.max(np.abs(lever["s_f"][STRAIGHT // 2 :])) < 0.002
    e_plain, e_lever = _turn_error(plain), _turn_error(lever)
    assert e_plain.size > 200 and e_lever.size == e_plain.size
    rms_plain, rms_lever = np.sqrt(np.mean(e_plain**2)), np.sqrt(np.mean(e_lever**2))
    assert rms_plain > 0.005  # [m]
    assert rms_lever < 0.25 * rms_plain


def test_with_the_lever_the_flow_state_still_finds_a_flow_error() -> None:
    """(b): a real error along the optical axis and no yaw error; with the lever ``s_f`` ends within a sixth of the
    injected 0.03 /m: the setting does not switch the flow state off."""
    run = drive(True, flow_error=FLOW_ERROR)
    assert abs(run["s_f"][-1] - FLOW_ERROR) < FLOW_ERROR / 6.0


def test_off_by_default_and_side_rig_setting_plumbed() -> None:
    """The default is eq (3) (``False``); a run's ``fusion.side_rig.vo_yaw_lever`` reaches a side rig's filter only,
    and a value that is not a boolean is refused naming the field."""
    from scenarios.config import ConfigError, load_scenario
    from scenarios.configuration.sections import FusionConfig

    assert FusionNoise().vo_yaw_lever is False and FusionConfig().side_rig.vo_yaw_lever is None
    config = load_scenario("roundabout-3", {"fusion.side_rig.vo_yaw_lever": True}).fusion
    assert config.for_camera((0.0, 1.0)).vo_yaw_lever is True
    assert config.for_camera((-1.0, 0.0)).vo_yaw_lever is False
    with pytest.raises(ConfigError, match=r"fusion\.side_rig\.vo_yaw_lever"):
        load_scenario("roundabout-3", {"fusion.side_rig.vo_yaw_lever": "sometimes"})
