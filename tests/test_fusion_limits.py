"""The fused filter at the steering's limits: the scrub demand (K5) of :mod:`sensor.fusion_slip`.

The LST's trailer (a fixed axle ahead of two steerable ones) is propagated on its own signals, without a camera: on a
straight road with its axles straight the demand is zero and the filter is the one without the demand, to the bit;
with both steerable axles at 25° in the 11.5 m turn of the field figure-of-eight the fixed axle and the steered ones
run far beyond their tyres' linear range, the demand is full and the slip velocity's variance grows by the scrub
walk's share.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensor.camera import StereoRig
from sensor.fusion import FusedVisoOt, FusionNoise
from sensor.fusion_slip import ScrubDemand
from sensor.unit_kinematics import slip_kinematics, unit_axles
from vehicle_model.presets import VEHICLE_PRESETS

DT = 0.02  # control period [s]
TICKS = 100
SPEED = 4.2  # [m/s], 15 km/h as on the field figure-of-eight
SCRUB = {"scrub_slip_angle": 0.05, "scrub_slip_walk": 0.3}


@pytest.fixture(scope="module")
def lst():
    return VEHICLE_PRESETS["lst"]()


def _propagate(params, noise: FusionNoise, yaw_rate: float, steer: float) -> FusedVisoOt:
    rig = StereoRig.from_degrees(psi_c2v_deg=180.0)
    fused = FusedVisoOt(params, rig.camera_in_trailer("left", params), noise)
    steer_angles = np.full(fused.steer_weights.size, steer)
    for k in range(TICKS):
        fused.propagate(k, DT, yaw_rate, SPEED, steer_angles)
    return fused


def test_the_demand_is_zero_free_rolling_or_sliding_and_full_at_the_lock(lst) -> None:
    slip_point, weights = slip_kinematics(lst, 1)
    demand = ScrubDemand(FusionNoise(**SCRUB), *unit_axles(lst, 1), slip_point, weights)
    steer = np.zeros(weights.size)
    assert demand(0.0, SPEED, steer, 0.0) == 0.0  # straight ahead
    # a gentle free-rolling turn (50 m): every slip angle within a degree and a half
    assert demand(SPEED / 50.0, SPEED, steer, 0.0) == 0.0
    # both steerable axles at 25° in the 11.5 m turn: far past twice the 0.05 rad onset
    assert demand(SPEED / 11.5, SPEED, np.full(weights.size, math.radians(25.0)), 0.0) == 1.0
    # the whole trailer sliding sideways at 1 m/s, axles straight: one slip angle for all, no disagreement
    assert demand(0.0, SPEED, steer, 1.0) == 0.0
    assert (
        ScrubDemand(FusionNoise(), *unit_axles(lst, 1), slip_point, weights)(
            SPEED / 11.5, SPEED, np.full(weights.size, math.radians(25.0)), 0.0
        )
        == 0.0
    )  # off by default


def test_free_rolling_the_filter_is_the_one_without_the_demand(lst) -> None:
    on = _propagate(lst, FusionNoise(**SCRUB), 0.0, 0.0)
    off = _propagate(lst, FusionNoise(), 0.0, 0.0)
    assert on.scrub_demand == 0.0
    assert np.array_equal(on.state, off.state)
    assert np.array_equal(on.covariance, off.covariance)


def test_at_the_lock_the_slip_velocitys_variance_grows_by_the_scrub_walk(lst) -> None:
    rate, lock = SPEED / 11.5, math.radians(25.0)
    on = _propagate(lst, FusionNoise(**SCRUB), rate, lock)
    off = _propagate(lst, FusionNoise(), rate, lock)
    assert on.scrub_demand == 1.0
    grown = on.covariance[3, 3] - off.covariance[3, 3]
    # no measurement: each tick after the first adds walk²·dt to v_s's variance (within 1 %)
    assert grown == pytest.approx(SCRUB["scrub_slip_walk"] ** 2 * DT * (TICKS - 1), rel=0.01)
