"""The trailer reference's brush-tyre slip in its mean ((T4) of :mod:`sensor.unit_slip_reference`,
``reference_road_friction``).

* (T4)'s slip less (T2)'s is ``−k(η_r)·G·u·f_p`` with ``k`` the brush tyre's excess slip solved by bisection (to
  1e-9), either turn; ``z_c`` moves by the same; without the setting the reference is (T2)'s bit for bit.
* In the filter the slip (K1) is measured against is (T4)'s (to 1e-12); with no lateral demand the run is the run
  without the setting, bit for bit, and the setting's absence leaves the filter as it was.
* A bad setting is refused before any work, naming the field (exit 2): a friction out of its range, and a friction
  with another reference than the trailer's.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from scenarios.cli import app
from scenarios.config import ConfigError, load_scenario
from sensor.unit_slip_reference import UnitSlipReference
from tests.test_reference_friction import _brush_excess, trailer_reference_filter
from vehicle_model.errors import InputError
from vehicle_model.parameters import GRAVITY
from vehicle_model.presets import vehicle_preset


def test_the_mean_takes_the_brush_tyres_slip_at_the_stated_friction() -> None:
    params = vehicle_preset("lst")
    linear, off = UnitSlipReference(params, 1), UnitSlipReference(params, 1, None, None)
    steer = np.array([0.02, -0.03])
    for reading, friction in ((0.79, 0.10), (-0.79, 0.10), (0.5, 0.8), (1.2, 0.10)):
        speed, yaw_rate = 4.17, 0.19 * math.copysign(1.0, reading)
        brush = UnitSlipReference(params, 1, road_friction=friction)
        demand = abs(reading) / (friction * GRAVITY)
        excess = _brush_excess(demand) if demand < 1.0 else 2.0  # beyond the friction: the saturated tyre's
        expected = -excess * brush.gradient * speed * reading
        shift = brush.slip_velocity(yaw_rate, speed, steer, reading) - linear.slip_velocity(
            yaw_rate, speed, steer, reading
        )
        assert math.isclose(shift, expected, rel_tol=1e-9), (reading, friction)
        assert math.copysign(1.0, shift) == -math.copysign(1.0, reading)  # more slip away from the turn's centre
        (z_b, s_b), (z_l, s_l) = (
            brush.lateral(yaw_rate, speed, steer, reading),
            linear.lateral(yaw_rate, speed, steer, reading),
        )
        assert math.isclose(z_b - z_l, s_b - s_l, rel_tol=1e-9, abs_tol=1e-15)  # z_c moves with the slip
        assert off.lateral(yaw_rate, speed, steer, reading) == (z_l, s_l)  # the setting's absence: (T2) exactly
    assert brush.residual_std(4.0, 0.8) == 0.0  # the mean's friction is not the std's
    with pytest.raises(InputError, match="reference_road_friction"):
        UnitSlipReference(params, 1, road_friction=-0.1)


def test_the_filter_measures_against_t4_and_is_unchanged_without_demand() -> None:
    from sensor.fusion import FusedVisoOt
    from tests.test_fusion import PARAMS, drive_with_truth

    r_m, w_m, incs, true = drive_with_truth(n=100, slip=0.0)  # 2 s straight on

    def filter_with(friction: float | None, reading: float) -> tuple[FusedVisoOt, np.ndarray, np.ndarray]:
        return trailer_reference_filter((r_m, w_m, incs, true), reading, reference_road_friction=friction)

    off, on = filter_with(None, 0.0), filter_with(0.1, 0.0)
    assert np.array_equal(off[1], on[1], equal_nan=True) and np.array_equal(off[2], on[2], equal_nan=True)
    assert np.array_equal(off[0].state, on[0].state) and np.array_equal(off[0]._history[-1].p, on[0]._history[-1].p)
    reading, speed = 0.6, float(w_m[-1])
    off, on = filter_with(None, reading), filter_with(0.1, reading)
    brush = UnitSlipReference(PARAMS, 1, road_friction=0.1).slip_velocity(float(r_m[-1]), speed, None, reading)
    linear = UnitSlipReference(PARAMS, 1).slip_velocity(float(r_m[-1]), speed, None, reading)
    assert math.isclose(on[0]._zero_slip.modelled_slip, brush, rel_tol=1e-12)
    assert math.isclose(off[0]._zero_slip.modelled_slip, linear, rel_tol=1e-12)
    assert abs(brush - linear) > 0.01 and not np.array_equal(off[0].state, on[0].state)  # and the states move


def test_a_bad_road_friction_is_refused_naming_the_field(tmp_path: Path) -> None:
    own = {
        "vehicle": "lst",
        "signals.trailer_lateral_acceleration": {},
        "fusion.side_rig.kinematic_rear_point": "trailer_lateral_acceleration",
    }
    field = "fusion.side_rig.reference_road_friction"
    for bad in (0.0, 0.04, 2.0, float("nan")):
        with pytest.raises(ConfigError, match=re.escape(field)):
            load_scenario("roundabout-3", {**own, field: bad})
    for name in ("reference_road_friction", "side_rig.reference_road_friction"):  # the tractor's reference: none
        with pytest.raises(ConfigError, match=re.escape(f"fusion.{name} = 0.1")):
            load_scenario("roundabout-3", {"vehicle": "lst", f"fusion.{name}": 0.1})
    config = load_scenario("roundabout-3", {**own, field: 0.1})
    assert config.fusion.side_rig.reference_road_friction == 0.1 and config.fusion.reference_road_friction is None
    assert config.fusion.for_camera((0.0, -1.0)).reference_road_friction == 0.1  # the side rig's filter takes it
    args = ["run", "roundabout-3", "--set", "vehicle=lst", "--out", str(tmp_path / "run")]
    result = CliRunner().invoke(app, [*args, "--set", f"{field}=0.1"])
    assert result.exit_code == 2, result.output
    assert field in result.output
    assert not (tmp_path / "run").exists()
