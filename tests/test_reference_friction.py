"""The trailer reference's linear-tyre residual in σ_k ((T3) of :mod:`sensor.unit_slip_reference`,
``reference_friction``).

* The closed form ``k(η)`` is the brush tyre's slip over the linear tyre's less one, against the brush model solved
  by bisection (to 1e-9), with its ends (``k(0) = 0``, ``k(1) = 2``) and its small-demand series joined (to 1e-9).
* ``σ_m = k(|f_p|/(μ_min·g))·|G·u·f_p|`` at a given speed and reading (to 1e-12), 0 without the setting.
* In the filter it joins σ_k's floor exactly: with no lateral demand the run is the run without the setting, bit for
  bit; at a steady reading σ_k is ``√(σ_0² + (u_C·v̂_s)² + σ_m²)`` (to 1e-12) and the setting off leaves it at the
  old floor.
* A bad setting is refused before any work, naming the field (exit 2): a friction out of its range, and a friction
  with another reference than the trailer's.
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest
from typer.testing import CliRunner

from scenarios.cli import app
from scenarios.config import ConfigError, load_scenario
from sensor.unit_slip_reference import UnitSlipReference, linear_slip_excess
from vehicle_model.errors import InputError
from vehicle_model.parameters import GRAVITY
from vehicle_model.presets import vehicle_preset

if TYPE_CHECKING:
    from sensor.fusion import FusedVisoOt


def _brush_excess(demand: float) -> float:
    """The brush tyre's slip at the force ``demand·μ·F_z`` over the linear tyre's, less one, by bisection on
    ``F/(μ·F_z) = 1 − (1 − x)³`` (``x = C·α/(3·μ·F_z)``; the linear tyre's ``x`` is ``demand/3``)."""
    low, high = 0.0, 1.0
    for _ in range(200):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if 1.0 - (1.0 - mid) ** 3 < demand else (low, mid)
    return 0.5 * (low + high) / (demand / 3.0) - 1.0


def trailer_reference_filter(
    drive: tuple, reading: float, **fields: float | None
) -> tuple[FusedVisoOt, np.ndarray, np.ndarray]:
    """The fused filter with the ``trailer_lateral_acceleration`` reference and ``fields`` of its noise run over
    ``drive`` (``tests.test_fusion.drive_with_truth``'s), every tick's trailer accelerometer reading ``reading``
    [m/s²]: the filter, its estimates and stds."""
    from sensor.fusion import FusedVisoOt, FusionNoise
    from tests.test_fusion import CAMERA, PARAMS, run, tractor_signals

    r_m, w_m, incs, true = drive
    lc = UnitSlipReference(PARAMS, 1).slip_point
    tractor = [
        replace(tractor_signals(u, r, r * lc, "lateral_acceleration", u * r), unit_lateral_acceleration=reading)
        for u, r, _ in true
    ]
    fused = FusedVisoOt(PARAMS, CAMERA, FusionNoise(kinematic_rear_point="trailer_lateral_acceleration", **fields))
    est, std, _ = run(fused, r_m, w_m, incs, tractor=tractor)
    return fused, np.asarray(est), np.asarray(std)


def test_the_closed_form_is_the_brush_tyres_excess_slip() -> None:
    for demand in (1e-3, 0.1, 0.5, 0.856, 0.99):
        assert math.isclose(linear_slip_excess(demand), _brush_excess(demand), rel_tol=1e-9, abs_tol=1e-12)
    assert linear_slip_excess(0.0) == 0.0 and linear_slip_excess(-0.3) == 0.0
    assert linear_slip_excess(1.0) == 2.0 and linear_slip_excess(3.0) == 2.0  # a tyre carries no more than μ·F_z
    below, above = linear_slip_excess(1e-6 * (1 - 1e-9)), linear_slip_excess(1e-6 * (1 + 1e-9))
    assert abs(below - above) < 1e-9  # the series and the closed form meet
    grid = np.linspace(0.0, 1.0, 201)
    assert np.all(np.diff([linear_slip_excess(d) for d in grid]) > 0.0)  # more demand, more excess


def test_the_residual_std_at_a_given_demand() -> None:
    params = vehicle_preset("lst")
    speed, reading, friction = 4.0, 0.84, 0.1
    reference = UnitSlipReference(params, 1, friction)
    demand = reading / (friction * GRAVITY)
    expected = _brush_excess(demand) * reference.gradient * speed * reading
    assert math.isclose(reference.residual_std(speed, reading), expected, rel_tol=1e-9)
    assert math.isclose(reference.residual_std(speed, -reading), expected, rel_tol=1e-9)  # either turn
    assert 0.3 < expected / (reference.gradient * speed * reading) < 1.0  # a sizeable share of the linear slip
    assert UnitSlipReference(params, 1).residual_std(speed, reading) == 0.0
    with pytest.raises(InputError, match="reference_friction"):
        UnitSlipReference(params, 1, 0.0)


def test_it_joins_the_floor_exactly_and_is_nothing_without_demand() -> None:
    from tests.test_fusion import PARAMS, drive_with_truth

    r_m, w_m, incs, true = drive_with_truth(n=250, slip=0.0)  # 5 s straight on
    reference = UnitSlipReference(PARAMS, 1)

    def filter_with(friction: float | None, reading: float) -> tuple[FusedVisoOt, np.ndarray, np.ndarray]:
        return trailer_reference_filter((r_m, w_m, incs, true), reading, reference_friction=friction)

    # no lateral demand: bit for bit the filter without the setting
    off, on = filter_with(None, 0.0), filter_with(0.1, 0.0)
    assert np.array_equal(off[1], on[1], equal_nan=True) and np.array_equal(off[2], on[2], equal_nan=True)
    # a steady reading (the straight's own demand would be none: it stands for the cross slope's or a turn's)
    reading, speed = 0.6, float(w_m[-1])
    off, on = filter_with(None, reading)[0], filter_with(0.1, reading)[0]
    slip = reference.slip_velocity(float(r_m[-1]), speed, None, reading)
    floor = on.noise.tractor_slip**2 + (on.noise.tractor_stiffness_uncertainty * slip) ** 2
    residual = UnitSlipReference(PARAMS, 1, 0.1).residual_std(speed, reading)
    assert residual > 0.01
    assert math.isclose(on.kinematic_std, math.sqrt(floor + residual**2), rel_tol=1e-12)
    assert math.isclose(off.kinematic_std, math.sqrt(floor), rel_tol=1e-12)


def test_a_bad_friction_is_refused_naming_the_field(tmp_path: Path) -> None:
    own = {
        "vehicle": "lst",
        "signals.trailer_lateral_acceleration": {},
        "fusion.side_rig.kinematic_rear_point": "trailer_lateral_acceleration",
    }
    for bad in (0.0, -0.1, 2.0, float("nan")):
        with pytest.raises(ConfigError, match=re.escape("fusion.side_rig.reference_friction")):
            load_scenario("roundabout-3", {**own, "fusion.side_rig.reference_friction": bad})
    for field in ("reference_friction", "side_rig.reference_friction"):  # the tractor's reference: no such term
        with pytest.raises(ConfigError, match=re.escape(f"fusion.{field} = 0.1")):
            load_scenario("roundabout-3", {"vehicle": "lst", f"fusion.{field}": 0.1})
    config = load_scenario("roundabout-3", {**own, "fusion.side_rig.reference_friction": 0.1})
    assert config.fusion.side_rig.reference_friction == 0.1 and config.fusion.reference_friction is None
    args = ["run", "roundabout-3", "--set", "vehicle=lst", "--out", str(tmp_path / "run")]
    result = CliRunner().invoke(app, [*args, "--set", "fusion.side_rig.reference_friction=0.1"])
    assert result.exit_code == 2, result.output
    assert "fusion.side_rig.reference_friction" in result.output
    assert not (tmp_path / "run").exists()
