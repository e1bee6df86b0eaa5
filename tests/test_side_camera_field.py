"""A side camera's odometry error along its optical axis, estimated as a state of the fused filter.

A side camera's weakest direction is along its optical axis, the off-tracking direction: a disparity offset (the
mount's twist, a calibration's left–right mismatch) scales its translation along that axis (docs/field_bias.md §7).
The steady no-slip turn of ``tests/test_unit_fusion.py`` with a side camera on the B-double's rear trailer whose
odometry overstates that translation by 3 %: with ``vo_axial_scale`` the filter finds the error against the
zero-slip kinematics and removes it, without it the estimate keeps the drift.
"""

from __future__ import annotations

import numpy as np
import pytest

from sensor.camera import StereoRig
from sensor.fusion import FusionNoise
from tests.test_unit_fusion import drive
from vehicle_model.presets import VEHICLE_PRESETS

SCALE_ERROR = 0.03  # the odometry's relative overstatement along the optical axis
TICKS = 1000  # 20 s of the steady turn
LATE = 700  # the last 6 s: the error the state has had time to find


@pytest.fixture(scope="module")
def runs():
    params = VEHICLE_PRESETS["au-b-double"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275, unit=2)
    noises = {"plain": FusionNoise(), "state": FusionNoise(vo_axial_scale=0.05, vo_axial_scale_walk=1e-3)}
    return {
        name: drive(params, 2, rig, fused=True, noise=noise, axial_scale=1.0 + SCALE_ERROR, ticks=TICKS)
        for name, noise in noises.items()
    }


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
