"""``offtrack estimate --zero-slip-grade accelerometer``: the grade of the zero-slip estimate on a recording's signals
(docs/terrain.md, "The grade from a longitudinal accelerometer"; :mod:`scenarios.loop.offline`).

A model-only run (the LST steered on the truth into the forest road's bend on a constant −10 % grade, dry, the
longitudinal accelerometer on with noise and an offset, ``estimators.zero_slip_grade: accelerometer``) is written as a
recording: its logged signals at every control tick as a signals CSV with the ``longitudinal_acceleration_m_s2``
column, and beside them a KITTI folder of two 64×48 noise frames (the odometry refuses them; only the signals'
estimates matter here) at the run's second tick and its last. Then:

* with the option, the recording's zero-slip series is the run's own zero-slip column (the same grade filter on the
  same readings, one definition), within 1e-9 m;
* without it, the series is Cheng's estimate without the grade on those signals (within 1e-12 m), the same with or
  without the column in the CSV, and the column's absence leaves the run directory's columns as they were; the
  grade moves the estimate in the bend (by more than 5 mm: the sagitta's share ``L_fp²/(2·R5)·(1/cos θ − 1)``);
* the option without the column, and an unknown value, are refused in one line naming the option, exit 2, before any
  work.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import cv2
import numpy as np
import pandas as pd
import pytest
from test_zero_slip import model_only_run
from typer.testing import CliRunner

from controller.zero_slip import ZeroSlipEstimator
from scenarios.cli import app
from vehicle_model.presets import vehicle_preset

RUN = {
    "vehicle": "lst",
    "feedback": "truth",
    "surface.preset": "dry",
    "surface.patches": [],
    "path.entry_length": 5.0,
    "duration_s": 8.0,
    "terrain.grade_profile": [],
    "terrain.undulation_amplitude_m": 0.0,
    "terrain.rut_depth_m": 0.0,
    "terrain.crossfall_percent": 0.0,
    "terrain.grade_percent": -10.0,
    "signals.tractor_longitudinal_acceleration": {"noise_std": 0.009, "bias": 0.04},
    "estimators.zero_slip_grade": "accelerometer",
}
"""The forest road's bend after 5 m of straight on a constant −10 % grade, the LST steered on the truth, model only."""

RIG = "vehicle: lst\npsi_c2v_deg: 180\nlever_arm_m: [-14.05, 0.0, 3.0]\n"
NAMES = ("wheel_speed", "tractor_yaw_rate", "articulation", "tractor_longitudinal_acceleration")


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> SimpleNamespace:
    """The run's columns and the recording made of it: a KITTI folder, a rig and two signals CSVs (with and without
    the longitudinal accelerometer)."""
    tmp = tmp_path_factory.mktemp("estimate-grade")
    outcome, cols = model_only_run("forest-road", RUN)
    assert outcome.status == "completed"
    time = cols["time"]
    folder = tmp / "seq"
    rng = np.random.default_rng(0)
    for side in ("image_0", "image_1"):
        (folder / side).mkdir(parents=True)
        for k in range(2):
            cv2.imwrite(str(folder / side / f"{k:06d}.png"), rng.integers(0, 256, (48, 64), dtype=np.uint8))
    # the first frame on the run's second tick: a run's zero-slip estimate takes its first sample there
    (folder / "times.txt").write_text(f"{time[1]:.17g}\n{time[-1]:.17g}\n")
    p0, p1 = "50 0 31.5 0 0 50 23.5 0 0 0 1 0", "50 0 31.5 -25 0 50 23.5 0 0 0 1 0"
    (folder / "calib.txt").write_text(f"P0: {p0}\nP1: {p1}\nP2: {p0}\nP3: {p1}\n")
    (tmp / "rig.yaml").write_text(RIG)
    table = pd.DataFrame(
        {
            "time_s": time,
            "speed_m_s": cols["signal_wheel_speed"],
            "yaw_rate_rad_s": cols["signal_tractor_yaw_rate"],
            "articulation_rad": cols["signal_articulation"],
            "longitudinal_acceleration_m_s2": cols["signal_tractor_longitudinal_acceleration"],
        }
    )
    table.to_csv(tmp / "signals.csv", index=False, float_format="%.17g")
    table.drop(columns="longitudinal_acceleration_m_s2").to_csv(tmp / "plain.csv", index=False, float_format="%.17g")
    return SimpleNamespace(tmp=tmp, folder=folder, cols=cols)


def _estimate(rec: SimpleNamespace, name: str, signals: str, *options: str) -> pd.DataFrame:
    out = rec.tmp / name
    args = ["estimate", str(rec.folder), "--rig", str(rec.tmp / "rig.yaml"), "--signals", str(rec.tmp / signals)]
    result = CliRunner().invoke(app, [*args, "--out", str(out), "--no-plots", *options])
    assert result.exit_code in (0, 1), result.output  # 1: the verdict on the odometry's refused noise frames
    return pd.read_parquet(out / "timeseries.parquet")


def test_the_recordings_accelerometer_grade_gives_the_runs_own_zero_slip_series(recording) -> None:
    cols = recording.cols
    series = _estimate(recording, "on", "signals.csv", "--zero-slip-grade", "accelerometer")
    # one row per tick from the run's second to its last, on the first frame's clock
    np.testing.assert_allclose(series["time"].to_numpy(), cols["time"][1:] - cols["time"][1], rtol=0.0, atol=1e-9)
    reading = cols["signal_tractor_longitudinal_acceleration"][1:]
    assert np.array_equal(series["tractor_longitudinal_acceleration"].to_numpy(), reading)
    ours, theirs = series["offtracking_zero_slip"].to_numpy(), cols["offtracking_zero_slip"][1:]
    assert np.array_equal(np.isfinite(ours), np.isfinite(theirs)) and np.isfinite(ours).sum() > 100
    assert np.nanmax(np.abs(ours - theirs)) < 1e-9  # the same filter on the same readings (measured 5e-15 m)


def test_without_the_option_the_estimate_is_cheng_without_the_grade_column_or_not(recording) -> None:
    cols = recording.cols
    off = _estimate(recording, "off", "signals.csv")["offtracking_zero_slip"].to_numpy()
    plain = _estimate(recording, "plain", "plain.csv")
    assert "tractor_longitudinal_acceleration" not in plain  # without the column the run directory is as it was
    assert np.array_equal(plain["offtracking_zero_slip"].to_numpy(), off, equal_nan=True)
    estimator = ZeroSlipEstimator(vehicle_preset("lst"))
    time = cols["time"]
    expected = [math.nan]
    for k in range(1, time.size):
        sample = {name: np.array([cols[f"signal_{name}"][k]]) for name in NAMES}
        value = estimator.update(sample | {"front_steer": np.zeros(1)}, time[k] - time[k - 1] if k > 1 else 0.0)
        expected.append(math.nan if value is None else value)
    assert np.nanmax(np.abs(off - np.array(expected[1:]))) < 1e-12
    shift = np.nanmax(np.abs(off - cols["offtracking_zero_slip"][1:]))
    assert shift > 0.005  # the grade's share of the wheel speed, in the bend


def _refused(args: list[str]) -> str:
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return " ".join(lines[0].split())


def test_the_grade_without_the_column_or_of_an_unknown_source_is_refused_naming_the_option(recording) -> None:
    rec, out = recording, recording.tmp / "refused"
    base = ["estimate", str(rec.folder), "--rig", str(rec.tmp / "rig.yaml"), "--out", str(out)]
    for signals in ([], ["--signals", str(rec.tmp / "plain.csv")]):
        line = _refused([*base, *signals, "--zero-slip-grade", "accelerometer"])
        assert "--zero-slip-grade accelerometer" in line and "longitudinal_acceleration_m_s2" in line
    line = _refused([*base, "--signals", str(rec.tmp / "signals.csv"), "--zero-slip-grade", "gps"])
    assert "--zero-slip-grade 'gps'" in line and "none, accelerometer" in line
    assert not out.exists()
