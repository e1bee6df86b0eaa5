"""The own reference with each axle at its own slip angle ((T5) of :mod:`sensor.unit_slip_reference`,
``reference_axles: each``).

* With every axle at one slip angle (no yaw rate, no steer; the presets' stiffnesses are in proportion to the loads)
  (T5) is (T4), to 1e-9 m/s, up to a demand of 0.95 of the friction.
* A two-axle trailer (the ``field`` preset) at a slip chosen by hand, one axle below its friction and one past it:
  the reading its brush tyres' moment asks gives that slip back (1e-9 m/s).
* The slip falls with the reading, is finite and continuous up to and past the axles' most (the saturation slip
  beyond it, reached within 1e-9 m/s), and mirrors with the reading's, the yaw rate's and the steer's sign (1e-12).
* The rate sensitivities equal a finite difference of the slip (1e-6 relative), and (R1)'s σ_r is the secant at
  the tick's yaw rate and steer.
* Refused, naming the field: ``each`` without ``reference_road_friction``, with another reference, an unknown
  name; the sensitivities before the tick's rates.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from scenarios.config import ConfigError, load_scenario
from sensor.fusion_noise import FusionNoise
from sensor.fusion_reference import OwnReference
from sensor.unit_slip_reference import UnitSlipReference
from vehicle_model.errors import InputError
from vehicle_model.parameters import GRAVITY
from vehicle_model.presets import vehicle_preset

LST = vehicle_preset("lst")
MU = 0.1
OWN = "trailer_lateral_acceleration"
TURN = (0.25, 4.13, np.array([-0.0464, -0.0724]))  # yaw rate [rad/s], wheel speed [m/s], steer [rad]: a ring on ice


def test_each_axle_at_one_slip_angle_is_t4() -> None:
    each = UnitSlipReference(LST, 1, None, MU, "each")
    group = UnitSlipReference(LST, 1, None, MU)
    for speed in (1.0, 4.0, 12.0):
        for demand in (-0.95, -0.5, 0.0, 0.1, 0.31, 0.77, 0.95):
            lateral = demand * MU * GRAVITY
            assert each.slip_velocity(0.0, speed, None, lateral) == pytest.approx(
                group.slip_velocity(0.0, speed, None, lateral), abs=1e-9
            )


def test_a_two_axle_case_by_hand() -> None:
    params = vehicle_preset("field")
    reference = UnitSlipReference(params, 1, None, MU, "each")
    trailer = params.trailers[0]
    towed = params.axle_table.unit == 1
    lengths = (7.7, 9.0)
    stiffness = params.axle_cornering_stiffness()[towed]
    loads = params.axle_table.static_load[towed]
    slip_point = float(np.dot(stiffness, lengths) / stiffness.sum())
    yaw_rate, speed = 0.3, 5.0
    for slip in (-0.05, -0.14, 0.02):  # the second puts the rear axle past its friction, the front below it
        moment = 0.0
        for length, c, load in zip(lengths, stiffness, loads, strict=True):
            alpha = -(slip + yaw_rate * (slip_point - length)) / speed  # eq (1)'s geometry, no steer
            x = c * alpha / (3.0 * MU * load)
            force = MU * load * (1.0 - (1.0 - min(abs(x), 1.0)) ** 3) * np.sign(x)
            moment += force * length
        if slip == -0.14:  # the front axle below its friction, the rear past it
            front, rear = (
                c * -(slip + yaw_rate * (slip_point - ln)) / speed / (3 * MU * f)
                for ln, c, f in zip(lengths, stiffness, loads, strict=True)
            )
            assert front < 1.0 < rear
        lateral = moment / (trailer.mass * -trailer.cg_x)  # (T1), one unit, no fifth wheel
        assert reference.slip_velocity(yaw_rate, speed, None, lateral) == pytest.approx(slip, abs=1e-9)


def test_monotone_finite_past_saturation_and_mirrored() -> None:
    reference = UnitSlipReference(LST, 1, None, MU, "each")
    yaw_rate, speed, steer = TURN
    readings = np.linspace(-2.0, 2.0, 401) * MU * GRAVITY
    slips = np.array([reference.slip_velocity(yaw_rate, speed, steer, f) for f in readings])
    assert np.all(np.isfinite(slips))
    assert np.all(np.diff(slips) <= 1e-12)
    most = float(np.dot(LST.axle_table.static_load[LST.axle_table.unit == 1], [8.0, 9.3, 10.6])) * MU
    trailer = LST.trailers[0]
    limit = most / (trailer.mass * -trailer.cg_x)  # the reading at which every axle is at its friction, (T1)
    beyond = [reference.slip_velocity(yaw_rate, speed, steer, f * limit) for f in (1.0, 1.5, 3.0)]
    assert beyond[0] == beyond[1] == beyond[2]
    gaps = [abs(reference.slip_velocity(yaw_rate, speed, steer, (1.0 - e) * limit) - beyond[0]) for e in (1e-6, 1e-12)]
    assert gaps[1] < 1e-4 and gaps[1] < gaps[0] / 50.0  # continuous into saturation: the gap as ε^(1/3) of the brush
    for f in (0.3, 0.9, 1.5 * limit):
        assert reference.slip_velocity(-yaw_rate, speed, -steer, -f) == pytest.approx(
            -reference.slip_velocity(yaw_rate, speed, steer, f), abs=1e-12
        )
    for low_speed in (0.0, 0.3, 1.0 - 1e-9):  # (T4)'s at a standstill, continuous to (T5)'s at u_0
        assert np.isfinite(reference.slip_velocity(yaw_rate, low_speed, steer, 0.3))
    group = UnitSlipReference(LST, 1, None, MU)
    assert reference.slip_velocity(yaw_rate, 0.0, steer, 0.3) == group.slip_velocity(yaw_rate, 0.0, steer, 0.3)
    assert reference.slip_velocity(yaw_rate, 1.0 - 1e-9, steer, 0.3) == pytest.approx(
        reference.slip_velocity(yaw_rate, 1.0, steer, 0.3), abs=1e-7
    )


def test_rate_sensitivity_and_r1_at_the_operating_point() -> None:
    noise = FusionNoise(
        kinematic_rear_point=OWN, reference_road_friction=MU, reference_axles="each", reference_accelerometer_bias=0.05
    )
    reference = OwnReference(LST, 1, noise)
    yaw_rate, speed, steer = TURN
    with pytest.raises(RuntimeError, match="lateral"):
        reference.rate_sensitivity(steer, 0.3)
    for lateral in (0.1, 0.303, 0.7, -0.5):
        reference.lateral(yaw_rate, speed, steer, lateral)
        d_yaw, d_speed = reference.rate_sensitivity(steer, lateral)
        h = 2.5e-6  # a quarter of RATE_STEP: the truncation (h²) 1e-10, the roots (1e-14 m/s) 1e-8 relative
        fd_yaw = (
            reference.slip_velocity(yaw_rate + h, speed, steer, lateral)
            - reference.slip_velocity(yaw_rate - h, speed, steer, lateral)
        ) / (2 * h)
        fd_speed = (
            reference.slip_velocity(yaw_rate, speed + h, steer, lateral)
            - reference.slip_velocity(yaw_rate, speed - h, steer, lateral)
        ) / (2 * h)
        assert d_yaw == pytest.approx(fd_yaw, rel=1e-6)
        assert d_speed == pytest.approx(fd_speed, rel=1e-6)
        sigma = 0.5 * abs(
            reference.slip_velocity(yaw_rate, speed, steer, lateral + 0.05)
            - reference.slip_velocity(yaw_rate, speed, steer, lateral - 0.05)
        )
        assert reference.bias_std(speed, lateral) == pytest.approx(max(sigma, 1e-4), rel=1e-12)


def test_each_is_refused_without_its_needs() -> None:
    with pytest.raises(InputError, match=r"reference_axles = 'each'.*reference_road_friction"):
        UnitSlipReference(LST, 1, None, None, "each")
    with pytest.raises(InputError, match="reference_axles = 'all'"):
        UnitSlipReference(LST, 1, None, MU, "all")
    with pytest.raises(ValueError, match="reference_axles"):
        FusionNoise(reference_axles="all")
    own = {
        "vehicle": "lst",
        "signals.trailer_lateral_acceleration": {},
        "fusion.side_rig.kinematic_rear_point": OWN,
    }
    field = "fusion.side_rig.reference_axles"
    with pytest.raises(ConfigError, match=re.escape(f"{field} = each needs") + ".*reference_road_friction"):
        load_scenario("roundabout-3", {**own, field: "each"})
    with pytest.raises(ConfigError, match=re.escape(f"{field} = each needs fusion.side_rig.kinematic_rear_point")):
        load_scenario("roundabout-3", {"vehicle": "lst", field: "each"})
    with pytest.raises(ConfigError, match=re.escape("fusion.reference_axles = each needs")):
        load_scenario("roundabout-3", {"vehicle": "lst", "fusion.reference_axles": "each"})
    config = load_scenario("roundabout-3", {**own, field: "each", "fusion.side_rig.reference_road_friction": MU})
    assert config.fusion.for_camera((0.0, -1.0)).reference_axles == "each"
    assert config.fusion.reference_axles == "group"
