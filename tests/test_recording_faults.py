"""Faults of recordings, calibration photos, tuning, assessment and export, each injected (tiny data in tmp dirs).

Each test gives the command what a user could: a KITTI ``calib.txt`` whose ``P1[0, 3]`` holds ``−b`` instead of
``−f·b``, both images from one bag topic, signals on another clock or of 1e300, a ``--reference`` that is missing,
a directory or binary, 1×1 and truncated photos, calibration settings out of range, ``--side-by-side`` with
``--feedback``, Ctrl-C in ``offtrack tune``, a temporary file a killed export left. A refusal is one line naming the
file, column or option and what is allowed, exit 2, before any work and without leaving an ``--out`` behind.
"""

from __future__ import annotations

import fcntl
import math
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from cli_runner import invoke
from test_recordings import _images, _kitti, _write_bag

from scenarios.export.table import export_run
from scenarios.loop.participant import Column
from scenarios.recorded.plausibility import SCALE_FACTOR, motion_flags
from scenarios.run.results import TIMESERIES_FILE, TimeSeriesWriter

RIG = "vehicle: lst\npsi_c2v_deg: 180\nlever_arm_m: [-14.05, 0.0, 3.0]\n"


def _refused(args: list[str]) -> str:
    """The one line of a refusal (exit 2, no traceback)."""
    result = invoke([str(a) for a in args])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


@pytest.fixture()
def rig(tmp_path: Path) -> Path:
    path = tmp_path / "rig.yaml"
    path.write_text(RIG)
    return path


# ------------------------------------------------------------------------------- a recording's scale and clock


def test_a_calib_txt_holding_b_for_f_times_b_is_refused_naming_the_file(tmp_path: Path, rig: Path) -> None:
    # 64×48 px, f 50 px, 3 m up: a 0.5 m baseline shows 3.9 px on the nearest road; P1[0, 3] = −b instead of −f·b
    # makes it 0.01 m and 0.08 px, which the odometry cannot tell from zero.
    out = tmp_path / "out"
    folder = _kitti(tmp_path / "seq")
    calib = folder / "calib.txt"
    calib.write_text(calib.read_text().replace(" -25.0 ", " -0.5 "))
    line = _refused(["estimate", folder, "--rig", rig, "--out", out])
    assert f"{calib}: baseline 0.01 m gives 0.078 px of disparity on the nearest road" in line
    assert "allowed: ≥ 1 px, a baseline ≥ 0.128 m" in line
    # KITTI's own numbers (f 718.856 px, b 0.5372 m) with −b: 0.75 mm, outside any stereo rig's baseline
    p0 = "718.856 0 607.1928 0 0 718.856 185.2157 0 0 0 1 0"
    calib.write_text(f"P0: {p0}\nP1: {p0.replace(' 607.1928 0 ', ' 607.1928 -0.5372 ')}\n")
    line = _refused(["vo-eval", folder])
    assert f"{calib}: baseline 0.0007473 m; allowed: [0.01, 5] m" in line
    # the rig file's measured baseline against the calibration's
    _kitti(tmp_path / "seq2")
    measured = tmp_path / "measured.yaml"
    measured.write_text(RIG + "baseline_m: 0.3\n")
    line = _refused(["estimate", tmp_path / "seq2", "--rig", measured, "--out", out])
    assert "baseline 0.5 m, the rig file's baseline_m 0.3 m; allowed: within 10% of each other" in line
    assert not out.exists()


def _steps(n: int, step: float, heading: float = 0.0) -> dict[str, np.ndarray]:
    """The columns of ``n`` frames at 10 Hz, every motion accepted, the kingpin ``step`` metres along the trailer
    each frame (negative: backwards), the trailer heading ``heading``."""
    k = np.arange(n, dtype=float)
    return {
        "time": 0.1 * k,
        "camera_frame": np.ones(n),
        "frame_missing": np.zeros(n),
        "vo_valid": np.r_[0.0, np.ones(n - 1)],
        "kingpin_x_viso_ot": step * k * math.cos(heading),
        "kingpin_y_viso_ot": step * k * math.sin(heading),
        "trailer_heading_viso_ot": np.full(n, heading),
    }


def test_odometry_against_its_wheel_speed_and_the_rigs_facing_are_flags() -> None:
    # 20 frames, 0.5 m each (5 m/s): a wheel speed of 5 m/s agrees; of 15 m/s (the odometry a third of it, a scale
    # error) it is flagged; 0.5 m backwards each frame is a camera moving against the rig's facing.
    columns = {**_steps(20, 0.5, heading=0.7), "wheel_speed": np.full(20, 5.0)}
    motion, flags = motion_flags(columns)
    assert flags == [] and motion["odometry_over_wheel"] == pytest.approx(1.0, rel=1e-9)
    assert motion["forward_m"] == pytest.approx(9.5) and motion["backward_m"] == pytest.approx(0.0, abs=1e-12)
    columns["wheel_speed"] = np.full(20, 5.0 * (SCALE_FACTOR + 1.0))
    motion, flags = motion_flags(columns)
    assert [f["flag"] for f in flags] == ["odometry_scale"] and "0.333× the wheel speed's" in flags[0]["reason"]
    motion, flags = motion_flags({**_steps(20, -0.5, heading=-2.0), "wheel_speed": np.full(20, 5.0)})
    assert [f["flag"] for f in flags] == ["camera_against_rig"]
    assert "9.5 m backwards and 0.0 m forwards" in flags[0]["reason"] and "psi_c2v_deg 0" in flags[0]["reason"]
    assert motion_flags(_steps(20, 0.01))[1] == []  # 0.19 m: too short to judge
    assert motion_flags({**_steps(3, 0.5), "vo_valid": np.zeros(3)}) == ({}, [])  # nothing accepted


def test_one_bag_topic_twice_and_signals_on_another_clock_are_refused(tmp_path: Path, rig: Path) -> None:
    out = tmp_path / "out"
    folder = _kitti(tmp_path / "seq")
    bag = tmp_path / "stereo"
    _write_bag(bag, _images(3))
    topic = "/stereo/left/image_raw"
    args = ["estimate", bag, "--rig", rig, "--left-topic", topic, "--right-topic", topic, "--out", out]
    line = _refused([*args, "--calib", folder / "calib.txt"])
    assert line == f"error: --left-topic and --right-topic are both {topic}; allowed: the two cameras' different topics"
    left = tmp_path / "left.mkv"
    left.write_bytes(b"")
    line = _refused(["estimate", left, "--right-video", left, "--times", folder / "times.txt", "--rig", rig])
    assert "--right-video" in line and "is RECORDING itself" in line
    signals = tmp_path / "signals.csv"  # the frames are at 0–0.4 s; the signals on a clock 1000 s on
    signals.write_text("time_s,speed_m_s,yaw_rate_deg_s,articulation_deg\n1000,1,0,0\n1000.1,1,0,0\n1000.4,1,0,0\n")
    line = _refused(["estimate", folder, "--rig", rig, "--signals", signals, "--out", out])
    assert f"--signals {signals}: time_s spans [1000, 1000.4] s, the recording's frames [0, 0.4] s" in line
    assert not out.exists()


@pytest.mark.parametrize(
    ("column", "value", "allowed"),
    [("speed_m_s", "1e300", "[-60, 60]"), ("articulation_deg", "-1e300", "[-200.5, 200.5]")],
)
def test_signals_beyond_the_models_limits_are_refused_naming_file_line_and_column(
    tmp_path: Path, rig: Path, column: str, value: str, allowed: str
) -> None:
    folder = _kitti(tmp_path / "seq")
    signals = tmp_path / "signals.csv"
    rows = [dict(time_s=0.1 * k, speed_m_s=1.0, yaw_rate_deg_s=0.0, articulation_deg=0.0) for k in range(5)]
    table = pd.DataFrame(rows).astype(object)
    table.loc[2, column] = value
    table.to_csv(signals, index=False)
    out = tmp_path / "out"
    line = _refused(["estimate", folder, "--rig", rig, "--signals", signals, "--out", out])
    assert line == f"error: {signals}: line 4, column {column}: {float(value):g}; allowed: {allowed}"
    assert not out.exists()


def test_a_reference_or_calibration_that_is_missing_a_directory_or_binary_is_named(tmp_path: Path, rig: Path) -> None:
    folder = _kitti(tmp_path / "seq")
    binary = tmp_path / "poses.bin"
    binary.write_bytes(bytes(range(256)) * 4)
    out = tmp_path / "out"
    base = ["estimate", folder, "--rig", rig, "--out", out]
    for given, says in ((tmp_path / "nowhere.txt", "not found"), (tmp_path, "a directory"), (binary, "not text")):
        line = _refused([*base, "--reference", given])
        assert line.startswith(f"error: --reference {given}: {says}") and "allowed: a text file of camera poses" in line
    line = _refused([*base, "--calibration", binary])
    assert line == f"error: calibration file {binary}: not an OpenCV YAML file (offtrack calibrate's)"
    assert not out.exists()


# ------------------------------------------------------------------------------------------- calibration photos


def _photos(folder: Path, size: tuple[int, int], pairs: int = 5, suffix: str = ".png") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(1)
    for k in range(pairs):
        for side in ("left", "right"):
            cv2.imwrite(str(folder / f"{side}{k:02d}{suffix}"), rng.integers(0, 256, size[::-1], dtype=np.uint8))
    return folder


def test_tiny_and_truncated_photos_are_refused_by_one_rule_before_any_detection(tmp_path: Path) -> None:
    out = tmp_path / "out"
    tiny = _photos(tmp_path / "tiny", (1, 1))
    line = _refused(["calibrate", "--images", tiny, "--out", out])
    assert line == (
        "error: the photos are 1×1 px; allowed: at least 40×28 px (either way up) for the chessboard 9×6 inner "
        "corners, 25.0 mm squares, 4 px a square"
    )
    for suffix in (".jpg", ".png"):  # a truncated JPEG is refused as a truncated PNG is, naming it
        folder = _photos(tmp_path / suffix[1:], (64, 48), suffix=suffix)
        cut = folder / f"left03{suffix}"
        cut.write_bytes(cut.read_bytes()[: len(cut.read_bytes()) // 2])
        line = _refused(["calibrate", "--images", folder, "--out", out])
        assert line.startswith(f"error: cannot read 1 image(s): {cut} ("), line
    assert not out.exists()


def test_calibrate_refuses_its_settings_before_reading_a_photo_and_leaves_no_empty_out(tmp_path: Path) -> None:
    broken = tmp_path / "broken"
    broken.mkdir()
    for side in ("left", "right"):
        (broken / f"{side}01.png").write_bytes(b"not an image")  # read first, it would be refused instead
    out = tmp_path / "out"
    for option, value in (("--min-views", "0"), ("--alpha", "2"), ("--corner-window", "1")):
        line = _refused(["calibrate", "--images", broken, "--out", out, option, value])
        assert line.startswith(f"error: {option} "), line
    plain = _photos(tmp_path / "plain", (64, 48), pairs=3)  # no board in any: refused after detection
    line = _refused(["calibrate", "--images", plain, "--out", out, "--min-views", "3"])
    assert "too few views" in line
    assert not out.exists()


# ---------------------------------------------------------------------------------------------- assess and tune


def test_assess_refuses_feedback_with_side_by_side_before_any_case(tmp_path: Path) -> None:
    out = tmp_path / "out"
    line = _refused(["assess", "lst", "--side-by-side", "--feedback", "truth", "--out", out])
    assert line.startswith("error: --feedback truth with --side-by-side") and "not both" in line
    line = _refused(["tune", "--feedback", "none", "--trials", "1", "--out", out])
    assert line.startswith("error: --feedback 'none': allowed: ")
    assert not out.exists()


def test_ctrl_c_in_tune_keeps_the_finished_trials_without_a_traceback(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Every episode is replaced by a cost without simulating; the third is stopped by Ctrl-C.
    from scenarios.envs.gain_tuning_env import GainTuningEnv

    episodes = []

    def evaluate(self: GainTuningEnv, gains: object) -> tuple:  # every trial's episode: the designed one included
        episodes.append(gains)
        if len(episodes) == 3:
            raise KeyboardInterrupt
        return float(len(episodes)), {}

    monkeypatch.setattr(GainTuningEnv, "evaluate", evaluate)
    out = tmp_path / "tune"
    result = invoke(["tune", "--trials", "5", "--draws", "1", "--out", str(out)])
    assert result.exit_code == 130, result.output
    assert "Traceback" not in result.output and "Trial" not in result.output
    assert "2 finished trial(s)" in result.output and "interrupted by the user (Ctrl-C)" in result.output
    trials = pd.read_csv(out / "trials.csv")
    assert list(trials["trial"]) == [0, 1] and set(trials["state"]) == {"complete"}


# ------------------------------------------------------------------------------------------------------- export


def test_the_temporary_a_killed_export_left_is_removed_by_the_next_one(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    writer = TimeSeriesWriter(run / TIMESERIES_FILE, [Column("time", "s", "time")])
    for k in range(3):
        writer.append({"time": 0.1 * k})
    writer.close()
    stale = run / ".timeseries.csv.k1ll3d.tmp"  # what SIGKILL leaves in the middle of a write: no one holds it
    stale.write_text("time [s]\n0.0\n")
    busy = run / ".timeseries.csv.w0rk1n.tmp"  # an export under way holds its lock
    with open(busy, "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        target = export_run(run, "csv")
        assert busy.exists()
    assert not stale.exists() and target.read_text().splitlines()[0] == "time [s]"
