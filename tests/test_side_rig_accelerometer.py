"""The towed units' lateral accelerometer (:mod:`sensor.trailer_accelerometer`) and the slip reference it gives the
fused filter (:mod:`sensor.unit_slip_reference`, ``kinematic_rear_point: trailer_lateral_acceleration``).

* Off by default, and on it draws from its own stream: a run with it has every column of the run without it, bit
  for bit, and the accelerometer's column besides (its noise and bias change nothing else).
* On a steady level turn the accelerometer reads the closed form, ``u_p·r`` of its mount (a rigid body turning
  steadily: every point of the centre line has the same lateral acceleration), within 0.003 m/s² on a 5 s mean of
  data-sheet-noisy samples (σ 0.009 m/s² per sample, 250 samples: 5σ of the mean), its bias taken off.
* (T2) on the same dry turn (linear tyres): the slip velocity it predicts from the reading is the true one within
  1 mm/s (the reading's noise there is 0.6 mm/s a sample, its mean's far less).
* The mount is the centre of percussion: a point there reads the axles' moment about the coupling with the yaw
  acceleration in it (checked on a rigid body in closed form, to 1e-9).
* The reference without the accelerometer is refused before any work, naming the field (exit 2).
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from scenarios.cli import app
from scenarios.config import ConfigError, load_scenario
from scenarios.run.runner import run_scenario
from sensor.datasheet import DATASHEET_NOISE
from sensor.trailer_accelerometer import mount_station
from sensor.unit_slip_reference import UnitSlipReference
from vehicle_model.kinematics import kingpin_velocity
from vehicle_model.presets import vehicle_preset

BASE = {
    "vehicle": "lst",
    "surface.preset": "dry",
    "camber.percent": 0.0,
    "seed": 0,
    "feedback": "zero_slip",
    "duration_s": 22.0,
    "signals.wheel_speed.noise_std": DATASHEET_NOISE["wheel_speed"],
    "signals.tractor_yaw_rate.noise_std": DATASHEET_NOISE["tractor_yaw_rate"],
    "signals.articulation.noise_std": DATASHEET_NOISE["articulation"],
    "signals.trailer_yaw_rate.noise_std": DATASHEET_NOISE["trailer_yaw_rate"],
    "signals.tractor_lateral_acceleration.noise_std": DATASHEET_NOISE["tractor_lateral_acceleration"],
    "signals.tractor_lateral_acceleration.bias": 0.05,
}
BIAS = 0.04
"""The accelerometer's bias in the run with it [m/s²]."""


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The roundabout's approach and steady turn, dry and level, without and with the trailer's accelerometer."""
    frames = []
    for name, extra in (
        ("off", {}),
        (
            "on",
            {
                "signals.trailer_lateral_acceleration": {
                    "noise_std": DATASHEET_NOISE["tractor_lateral_acceleration"],
                    "bias": BIAS,
                }
            },
        ),
    ):
        run_dir = tmp_path_factory.mktemp(name)
        run_scenario(load_scenario("roundabout-3", {**BASE, **extra}), run_dir, plots=False)
        frames.append(pd.read_parquet(run_dir / "timeseries.parquet"))
    return frames[0], frames[1]


def test_off_by_default_and_its_own_stream_leaves_every_other_column_bit_identical(runs) -> None:
    off, on = runs
    assert load_scenario("roundabout-3", {"vehicle": "lst"}).signals.trailer_lateral_acceleration is None
    assert set(on.columns) - set(off.columns) == {"signal_trailer_lateral_acceleration"}
    assert on[off.columns].equals(off)


def _steady(frame: pd.DataFrame) -> tuple[pd.DataFrame, np.ndarray, np.ndarray, np.ndarray]:
    """The last 5 s (the steady turn) and, from the true states, the mount's forward speed, the kingpin's lateral
    velocity and the trailer's speed along its axles, in trailer axes."""
    params = vehicle_preset("lst")
    late = frame[frame["time"] > frame["time"].iloc[-1] - 5.0]
    vx, vy = kingpin_velocity(params, late["u"].to_numpy(), late["v1"].to_numpy(), late["r1"].to_numpy())
    gamma = late["gamma"].to_numpy()
    speed = np.cos(gamma) * vx - np.sin(gamma) * vy
    lateral = np.sin(gamma) * vx + np.cos(gamma) * vy
    return late, speed, lateral, late["r2"].to_numpy()


def test_on_a_steady_turn_it_reads_the_closed_form_lateral_acceleration(runs) -> None:
    late, speed, _, rate = _steady(runs[1])
    assert np.ptp(rate) < 0.05 * abs(rate.mean()) and rate.mean() > 0.05  # a steady left turn
    reading = late["signal_trailer_lateral_acceleration"].to_numpy()
    closed_form = speed * rate  # u_p·r: the mount's forward speed is the kingpin's (a point of the centre line)
    assert abs(np.mean(reading - BIAS - closed_form)) < 0.003
    assert 0.3 < abs(closed_form.mean()) < 0.4  # a turn that asks for a measurable force


def test_the_slip_it_gives_is_the_true_slip_on_a_dry_turn(runs) -> None:
    late, speed, lateral, rate = _steady(runs[1])
    reference = UnitSlipReference(vehicle_preset("lst"), 1)
    steer = late[["steer_trailer2", "steer_trailer3"]].to_numpy()
    reading = late["signal_trailer_lateral_acceleration"].to_numpy() - BIAS
    out = np.array([reference.lateral(r, u, s, f) for r, u, s, f in zip(rate, speed, steer, reading, strict=True)])
    true_slip = lateral - (out[:, 0] - out[:, 1])  # the kingpin's lateral velocity less eq (1)'s zero-slip part
    assert true_slip.mean() < -0.02  # the axles slip outwards in the turn
    assert abs(np.mean(out[:, 1] - true_slip)) < 1e-3


def test_the_mount_is_where_the_axles_moment_needs_no_yaw_acceleration() -> None:
    params = vehicle_preset("lst")
    trailer = params.trailers[0]
    a, mass, inertia = -trailer.cg_x, trailer.mass, trailer.yaw_inertia
    station = mount_station(params, 1)
    for cg_force, yaw_acceleration in ((1.3, 0.0), (0.0, 0.4), (-0.7, -0.25)):
        moment = mass * a * cg_force - inertia * yaw_acceleration  # (T1) about the coupling
        at_mount = cg_force - yaw_acceleration * (station - a)  # a rigid body's point behind the CG
        assert math.isclose(mass * a * at_mount, moment, rel_tol=1e-9, abs_tol=1e-6)
    assert 0.0 < station < max(-ax.x for ax in trailer.axles) + 1.0  # on the trailer, by its axle group


def test_the_reference_without_the_accelerometer_is_refused_naming_the_field(tmp_path: Path) -> None:
    for field in ("kinematic_rear_point", "side_rig.kinematic_rear_point"):
        with pytest.raises(ConfigError, match=re.escape(f"fusion.{field} = trailer_lateral_acceleration")):
            load_scenario("roundabout-3", {"vehicle": "lst", f"fusion.{field}": "trailer_lateral_acceleration"})
    on = {
        "signals.trailer_lateral_acceleration": {},
        "fusion.side_rig.kinematic_rear_point": "trailer_lateral_acceleration",
    }
    assert load_scenario("roundabout-3", {"vehicle": "lst", **on}).fusion.side_rig.kinematic_rear_point == (
        "trailer_lateral_acceleration"
    )
    args = ["run", "roundabout-3", "--set", "vehicle=lst", "--out", str(tmp_path / "run")]
    result = CliRunner().invoke(
        app, [*args, "--set", "fusion.side_rig.kinematic_rear_point=trailer_lateral_acceleration"]
    )
    assert result.exit_code == 2, result.output
    assert (
        "fusion.side_rig.kinematic_rear_point" in result.output
        and "signals.trailer_lateral_acceleration" in result.output
    )
    assert not (tmp_path / "run").exists()


def test_the_filter_takes_the_trailers_slip_from_its_own_accelerometer_and_no_evidence_against_it() -> None:
    # 0.1 m/s of slip from t = 10 s in a left turn; the tractor's kinematics (its accelerometer's point) say none,
    # the trailer's accelerometer reads what (T2) needs for it. Blinded for 7 s in the turn, the filter with the
    # trailer's reference follows the truth within 1 cm; with the tractor's it does not (over 5 cm). A camera
    # that disagrees by a steady 0.05 m/s leaves σ_k of the trailer's reference at its floor.
    from sensor.fusion import FusedVisoOt, FusionNoise, TractorSignals
    from tests.test_fusion import CAMERA, DT, PARAMS, drive_with_truth, run, tractor_signals
    from vehicle_model.errors import InputError

    r_m, w_m, incs, true = drive_with_truth(n=1500, slip=0.1)
    reference = UnitSlipReference(PARAMS, 1)
    lc = reference.slip_point
    readings = [(r * reference.spread / lc - vs) / (reference.gradient * u) if u * r else 0.0 for u, r, vs in true]
    tractor = [
        replace(tractor_signals(u, r, r * lc, "lateral_acceleration", u * r), unit_lateral_acceleration=f)
        for (u, r, _), f in zip(true, readings, strict=True)
    ]
    blind = (np.arange(1500) > 1000) & (np.arange(1500) < 1350)

    def worst(point: str, frame_error=None) -> tuple[float, FusedVisoOt]:
        fused = FusedVisoOt(PARAMS, CAMERA, FusionNoise(kinematic_rear_point=point))
        est, _, ref = run(
            fused,
            r_m,
            w_m,
            incs,
            drop=lambda frame: 200 < frame < 270,
            tractor=tractor,
            frame_error=frame_error,
            read_from=1001,  # the first tick of the window checked
        )
        return float(np.max(np.abs(est[blind] - ref[blind]))), fused

    own, _ = worst("trailer_lateral_acceleration")
    assert own < 0.01
    assert worst("lateral_acceleration")[0] > 0.05
    error = np.tile([0.0, 0.05 * DT * 5, 0.0], (300, 1))  # 0.05 m/s to the left, every frame
    _, fused = worst("trailer_lateral_acceleration", error)
    floor = math.hypot(fused.noise.tractor_slip, fused.noise.tractor_stiffness_uncertainty * 0.1)
    assert fused.kinematic_std <= floor + 1e-9
    fused = FusedVisoOt(PARAMS, CAMERA, FusionNoise(kinematic_rear_point="trailer_lateral_acceleration"))
    fused.propagate(0, DT, 0.0, 4.0)
    with pytest.raises(InputError, match=r"signals\.trailer_lateral_acceleration"):
        fused.propagate(1, DT, 0.0, 4.0, None, TractorSignals(4.0, 0.0, 0.0, 0.0))  # no reading: NaN
