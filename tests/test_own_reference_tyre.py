"""The own reference's (T5) root with the tyre the vehicle declares (``reference_tyre: stated``, (T6) of
:mod:`sensor.unit_slip_reference`, (S1) of :mod:`sensor.reference_tyre`).

* At a low demand (every axle at one slip angle) the slip is the linear tyres' of (T2): the Magic Formula departs
  from its slope in the third order of the slip angle, so at a demand of 0.01 of μ within 1e-4 relative and at 0.001
  within 1e-6, where the brush tyre of (T5) is already 3e-3 off (its departure is second order).
* At a near-peak demand in a bend (the group's 0.95 of μ, an axle above 0.9 of its peak force) the root's moment
  balance (T1) closes to 1e-9 relative, with each axle's force from :func:`vehicle_model.tyre.lateral_force_function`
  (the declared tyre's numeric wrapper, not the reference's evaluation); each axle's peak slip is its curve's maximum.
* The slip falls with the reading, is finite, and past the axles' most is the slip at which every axle is at its peak.
* Refused, naming the field: ``stated`` without ``reference_axles: each`` (the reference and the scenario's
  configuration), an unknown name.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from scenarios.config import ConfigError, load_scenario
from sensor.fusion_noise import FusionNoise
from sensor.fusion_reference import OwnReference
from sensor.unit_kinematics import unit_axles
from sensor.unit_slip_reference import UnitSlipReference
from vehicle_model.errors import InputError
from vehicle_model.parameters import GRAVITY
from vehicle_model.presets import vehicle_preset
from vehicle_model.tyre import lateral_force_function

LST = vehicle_preset("lst")
MU = 0.1
OWN = "trailer_lateral_acceleration"
TURN = (0.25, 4.13, np.array([-0.0464, -0.0724]))  # yaw rate [rad/s], wheel speed [m/s], steer [rad]: a ring on ice
BEND = (0.08, 6.0, np.array([-0.012, -0.024]))  # a wider bend, the axles' slip angles 0.1 of their peak's apart


def test_stated_at_low_demand_is_the_linear_slip() -> None:
    stated = UnitSlipReference(LST, 1, None, MU, "each", "stated")
    brush = UnitSlipReference(LST, 1, None, MU, "each")
    linear = UnitSlipReference(LST, 1)
    for speed in (4.0, 12.0):
        for demand, tolerance in ((0.01, 1e-4), (-0.01, 1e-4), (0.001, 1e-6), (-0.001, 1e-6)):
            lateral = demand * MU * GRAVITY
            expected = linear.slip_velocity(0.0, speed, None, lateral)
            assert stated.slip_velocity(0.0, speed, None, lateral) == pytest.approx(expected, rel=tolerance)
            if abs(demand) == 0.01:  # the brush's k(η) ≈ η/3: the test tells the two curves apart
                assert abs(brush.slip_velocity(0.0, speed, None, lateral) / expected - 1.0) > 3e-3


def test_force_balance_closes_near_the_peak() -> None:
    reference = UnitSlipReference(LST, 1, None, MU, "each", "stated")
    table = LST.axle_table
    towed = table.unit == 1
    lengths, steerable, shares = unit_axles(LST, 1)
    loads, n_tyres = table.static_load[towed], table.n_tyres[towed]
    tyres = [t for t, on in zip(table.tyres, towed, strict=True) if on]
    force = [lateral_force_function(t) for t in tyres]
    yaw_rate, speed, steer = BEND
    tangents = np.zeros(lengths.size)
    tangents[steerable] = np.tan(steer)
    slip_point = float(np.dot(shares, lengths))
    offset = yaw_rate * (slip_point - lengths) + speed * (
        float(np.dot(shares[steerable], tangents[steerable])) - tangents
    )
    trailer = LST.trailers[0]
    moment = trailer.mass * -trailer.cg_x  # (T1): one unit towing none
    peaks = reference._curve.peak_slip
    for j, peak in enumerate(peaks):  # α_pj is the curve's maximum
        at = [float(force[j](a, loads[j] / n_tyres[j], MU)) for a in (peak - 1e-4, peak, peak + 1e-4)]
        assert at[1] > at[0] and at[1] > at[2]
    lateral = 0.95 * MU * GRAVITY  # the group's demand 0.95 of μ
    slip = reference.slip_velocity(yaw_rate, speed, steer, lateral)
    alpha = -(slip + offset) / speed  # (T5)'s slip angles
    forces = np.array(
        [n * float(f(a, load / n, MU)) for n, f, a, load in zip(n_tyres, force, alpha, loads, strict=True)]
    )
    peak_forces = np.array(
        [n * float(f(p, load / n, MU)) for n, f, p, load in zip(n_tyres, force, peaks, loads, strict=True)]
    )
    assert np.all(np.abs(alpha) < peaks)  # on the rising branch, so the declared curve itself
    assert np.max(np.abs(forces) / peak_forces) > 0.9  # near the peak
    assert float(np.dot(lengths, forces)) == pytest.approx(moment * lateral, rel=1e-9)


def test_monotone_finite_and_held_past_the_peak() -> None:
    reference = UnitSlipReference(LST, 1, None, MU, "each", "stated")
    yaw_rate, speed, steer = TURN
    readings = np.linspace(-2.0, 2.0, 201) * MU * GRAVITY
    slips = np.array([reference.slip_velocity(yaw_rate, speed, steer, f) for f in readings])
    assert np.all(np.isfinite(slips))
    assert np.all(np.diff(slips) <= 1e-12)
    beyond = [reference.slip_velocity(yaw_rate, speed, steer, f * MU * GRAVITY) for f in (2.0, 3.0)]
    assert beyond[0] == beyond[1]


def test_stated_is_refused_without_each() -> None:
    with pytest.raises(InputError, match=r"reference_tyre = 'stated'.*reference_axles = each"):
        UnitSlipReference(LST, 1, None, MU, "group", "stated")
    with pytest.raises(InputError, match="reference_tyre = 'magic'"):
        UnitSlipReference(LST, 1, None, MU, "each", "magic")
    with pytest.raises(ValueError, match="reference_tyre"):
        FusionNoise(reference_tyre="magic")
    noise = FusionNoise(kinematic_rear_point=OWN, reference_road_friction=MU, reference_tyre="stated")
    with pytest.raises(InputError, match="reference_tyre = 'stated'"):
        OwnReference(LST, 1, noise)
    own = {
        "vehicle": "lst",
        "signals.trailer_lateral_acceleration": {},
        "fusion.side_rig.kinematic_rear_point": OWN,
        "fusion.side_rig.reference_road_friction": MU,
    }
    field = "fusion.side_rig.reference_tyre"
    with pytest.raises(ConfigError, match=re.escape(f"{field} = stated needs fusion.side_rig.reference_axles = each")):
        load_scenario("roundabout-3", {**own, field: "stated"})
    config = load_scenario("roundabout-3", {**own, field: "stated", "fusion.side_rig.reference_axles": "each"})
    assert config.fusion.for_camera((0.0, -1.0)).reference_tyre == "stated"
    assert config.fusion.reference_tyre == "brush"
