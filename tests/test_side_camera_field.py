"""A side camera's odometry error along its optical axis, estimated as a state of the fused filter.

A side camera's weakest direction is along its optical axis, the off-tracking direction: a disparity offset (the
mount's twist, a calibration's left–right mismatch) scales its translation along that axis (docs/field_bias.md §7).
The steady no-slip turn of ``tests/test_unit_fusion.py`` with a side camera on the B-double's rear trailer whose
odometry overstates that translation by 3 %: with ``vo_axial_scale`` the filter finds the error against the
zero-slip kinematics and removes it, without it the estimate keeps the drift. The same for an error along the axis
that grows with the square of the camera's motion across it between frames (``vo_axial_flow``: the image's flow
through a calibration's residual, docs/field_bias.md §7.4).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensor.camera import StereoRig
from sensor.fusion import ChainSignals, FusedVisoOt, FusionNoise
from tests.test_unit_fusion import DT, EVERY, RADIUS, SPEED, drive, steady_pose, unit_speed
from vehicle_model.geometry import unit_frame
from vehicle_model.offtracking import OfftrackingBuffer, increments_from_poses
from vehicle_model.presets import VEHICLE_PRESETS

SCALE_ERROR = 0.03  # the odometry's relative overstatement along the optical axis
TICKS = 1000  # 20 s of the steady turn
LATE = 700  # the last 6 s: the error the state has had time to find
FLOW_ERROR = 0.1  # [1/m] the odometry's error along its axis per square metre of motion across it between frames


def drive_with_flow_error(noise: FusionNoise):
    """Estimates, stds, truths and the filter over the steady turn of ``drive`` whose camera motions carry an error
    ``FLOW_ERROR·t·|t|`` along the optical axis, ``t`` the frame's motion along the image's x axis."""
    params = VEHICLE_PRESETS["au-b-double"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275, unit=2)
    estimator = FusedVisoOt(params, rig.camera_in_trailer("left", params), noise, unit=2)
    truth = OfftrackingBuffer(params.follow_point_offset_of(2))
    r = SPEED / RADIUS
    est, std, ref = [], [], []
    previous = last_world = None
    for k in range(TICKS):
        pose = steady_pose(params, k * DT)
        frame = unit_frame(params, pose, 2)
        if previous is not None:
            truth.push(*increments_from_poses(np.vstack([previous[0], frame[0]]), np.array([previous[1], frame[1]]))[0])
        previous = frame
        estimator.propagate(
            k, DT, r, unit_speed(params, pose, 2), None, ChainSignals(SPEED, r, pose.angles, math.nan, (r,))
        )
        if k % EVERY == 0:
            world = rig.camera_in_world(params, pose, "left")
            if last_world is not None:
                motion = np.linalg.inv(last_world) @ world
                motion[2, 3] += FLOW_ERROR * motion[0, 3] * abs(motion[0, 3])
                estimator.measure(k, motion, np.eye(6) * 1e-10)
            last_world = world
        est.append(math.nan if estimator.estimate is None else estimator.estimate)
        std.append(estimator.std)
        value = truth.offtracking()
        ref.append(math.nan if value is None else value)
    return np.array(est), np.array(std), np.array(ref), estimator


@pytest.fixture(scope="module")
def runs():
    params = VEHICLE_PRESETS["au-b-double"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275, unit=2)
    noises = {"plain": FusionNoise(), "state": FusionNoise(vo_axial_scale=0.05, vo_axial_scale_walk=1e-3)}
    out = {
        name: drive(params, 2, rig, fused=True, noise=noise, axial_scale=1.0 + SCALE_ERROR, ticks=TICKS)
        for name, noise in noises.items()
    }
    out["flow plain"] = drive_with_flow_error(FusionNoise())
    out["flow state"] = drive_with_flow_error(FusionNoise(vo_axial_flow=0.2))
    return out


def _late_errors(run) -> tuple[np.ndarray, np.ndarray]:
    est, std, ref, _ = run
    late = np.isfinite(est) & np.isfinite(ref) & (np.arange(len(est)) >= LATE)
    return est[late] - ref[late], std[late]


def test_the_state_finds_the_axial_scale_error(runs):
    """The state's estimate is within a third of the true 3 % after 20 s of the turn."""
    filt = runs["state"][3]
    assert filt.state.size == 8
    assert abs(filt.state[-1] - SCALE_ERROR) < SCALE_ERROR / 3.0


def test_the_state_removes_the_drift_and_its_std_covers_the_rest(runs):
    """The late error is under half of the filter's without the state (which keeps the drift, > 2 cm), and 2σ of
    the state's filter covers it on every late tick (2σ of the plain filter does not)."""
    plain, plain_std = _late_errors(runs["plain"])
    state, state_std = _late_errors(runs["state"])
    assert plain.size > 200 and state.size == plain.size
    assert np.sqrt(np.mean(plain**2)) > 0.02
    assert np.sqrt(np.mean(state**2)) < 0.5 * np.sqrt(np.mean(plain**2))
    assert np.all(np.abs(state) <= 2.0 * state_std)
    assert np.mean(np.abs(plain) <= 2.0 * plain_std) < 0.5


def test_without_the_state_the_filter_has_its_seven_states(runs):
    assert runs["plain"][3].state.size == 7


def test_the_flow_state_finds_and_removes_its_error(runs):
    """``vo_axial_flow``'s state ends within a third of the injected error; its late error is under half of the
    plain filter's (which keeps a drift over 2 cm), and 2σ covers it on every late tick."""
    filt = runs["flow state"][3]
    assert filt.state.size == 8
    assert abs(filt.state[-1] - FLOW_ERROR) < FLOW_ERROR / 3.0
    plain, _ = _late_errors(runs["flow plain"])
    state, state_std = _late_errors(runs["flow state"])
    assert np.sqrt(np.mean(plain**2)) > 0.02
    assert np.sqrt(np.mean(state**2)) < 0.5 * np.sqrt(np.mean(plain**2))
    assert np.all(np.abs(state) <= 2.0 * state_std)
