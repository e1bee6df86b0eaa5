"""An estimator from a separately installed distribution reaches everything a built-in one does.

``tests/data/plugin_estimator`` holds the package ``offtrack_test_plugin`` (the truth shifted by a constant, its
settings model, its own columns and colour) and its ``offtrack_test_plugin-0.1.dist-info`` declaring it under the
entry-point group ``offtrack.estimators``: on ``PYTHONPATH`` it is an installed distribution, found by
:mod:`importlib.metadata` in every process — the command line, the spawned workers of a sweep, ``offtrack estimate``
through its offline adapter. Nothing in the project names it. ``tests/data/plugin_broken`` declares one whose
module does not exist.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).parent / "data"
PLUGIN = DATA / "plugin_estimator"
BROKEN = DATA / "plugin_broken"
NAME, COLOUR, SHIFT = "shifted_truth", "#8c2d04", 0.05
"""The plug-in's estimator, its declared colour and its default shift [m] (offtrack_test_plugin)."""


def _python(code: str, *paths: Path, args: tuple[str, ...] = ()) -> subprocess.CompletedProcess[str]:
    """Run ``code`` in a fresh interpreter with ``paths`` (the plug-ins' folders) and the project on PYTHONPATH."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(str(p) for p in (*paths, ROOT))}
    env.setdefault("OFFTRACK_CACHE_DIR", "/tmp/offtrack-cache")
    env.setdefault("PYOPENGL_PLATFORM", "egl")
    return subprocess.run(
        [sys.executable, "-c", code, *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600
    )


CLI = "import sys; from scenarios.cli import main; sys.argv[0] = 'offtrack'; main()"


def _shifted(run_dir: Path, shift: float) -> pd.DataFrame:
    """The run's time series, checked to hold the plug-in's declared columns: the truth shifted by ``shift``."""
    series = pd.read_parquet(run_dir / "timeseries.parquet")
    truth, shifted = series["offtracking_truth"].to_numpy(), series[f"offtracking_{NAME}"].to_numpy()
    defined = np.isfinite(truth)
    assert defined.sum() > 50 and np.array_equal(np.isfinite(shifted), defined)
    assert np.abs(shifted[defined] - truth[defined] - shift).max() < 1e-12
    assert np.all(series["shifted_truth_shift"] == shift)
    return series


def test_the_command_line_runs_a_plugin_estimator_records_measures_and_feeds_it_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    # 12 s: the truth is defined from 10.26 s (88 samples by the end, > 50 as _shifted asks)
    args = ("run", "roundabout-test", "--vehicle", "lst", "--feedback", NAME, "--duration", "12", "--no-plots")
    done = _python(CLI, PLUGIN, args=(*args, "--out", str(out)))
    assert done.returncode == 0, done.stderr
    _shifted(out, SHIFT)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["offtracking"]["estimators"][NAME]["mean_error"] == pytest.approx(SHIFT, abs=1e-12)
    assert "shifted_truth: true" in (out / "config.yaml").read_text()  # the resolved file says what ran
    # its help lists it; without the distribution, the same command is refused naming the choices: through main()
    # in this process, which never has the plug-in's folder on its path (a process's exit 2: test_faults.py)
    assert NAME in _python(CLI, PLUGIN, args=("run", "--help")).stdout
    from test_faults import offtrack_in_process

    refused = offtrack_in_process(monkeypatch, capsys, *args, "--out", str(tmp_path / "without"))
    assert refused.returncode == 2 and "must be one of none, zero_slip" in refused.stderr
    assert not (tmp_path / "without").exists()


SWEEP = """
import os
import sys
from pathlib import Path
from scenarios.run.metrics import estimator_names
from scenarios.run.plots import offtracking_figure
from scenarios.studies.executors import local_executor
from scenarios.studies.records import CaseSpec
from scenarios.studies.sweep import run_sweep

if __name__ == "__main__":
    out = Path(sys.argv[1])
    base = (("vehicle", "lst"), ("feedback", "shifted_truth"), ("duration_s", 12.0))
    cases = [
        CaseSpec("plugin", "roundabout-test", base, (("shift", "default"),)),
        CaseSpec(
            "plugin", "roundabout-test", base + (("estimators.shifted_truth", {"shift_m": 0.1}),), (("shift", "0.1"),)
        ),
    ]
    with local_executor(1) as pool:  # one spawned worker runs both cases
        result = run_sweep(cases, out, executor=pool)
    pids = {r.worker["pid"] for r in result.records}
    print(*(r.status for r in result.records), len(pids), os.getpid() in pids)
    import pandas as pd
    series = pd.read_parquet(out / "shift-default" / "timeseries.parquet")
    columns = {c: series[c].to_numpy(dtype=float) for c in series.columns}
    figure = offtracking_figure(columns, estimator_names(columns), "a plug-in")
    print(*(f"{line.get_label()}|{line.get_color()}" for line in figure.axes[0].lines), sep="\\n")
"""


def test_spawned_sweep_workers_run_a_plugin_estimator_with_its_settings_and_figures_draw_its_colour(
    tmp_path: Path,
) -> None:
    from matplotlib.colors import to_hex

    done = _python(SWEEP, PLUGIN, args=(str(tmp_path),))
    assert done.returncode == 0, done.stderr
    statuses, *lines = done.stdout.strip().splitlines()
    assert statuses == "done done 1 False"  # both cases on the one spawned worker, not in the sweep's process
    _shifted(tmp_path / "shift-default", SHIFT)
    _shifted(tmp_path / "shift-0.1", 0.1)  # its settings, validated by its own model, reached the worker
    colours = {label.split(":")[0]: colour for label, colour in (line.split("|") for line in lines)}
    assert to_hex(colours[NAME]) == COLOUR
    assert to_hex(colours["zero_slip"]) == to_hex("tab:orange")  # the built-ins keep theirs


def test_a_broken_plugin_is_left_out_with_one_line_naming_it() -> None:
    done = _python("from scenarios.registry import feedback_sources; print(*feedback_sources())", PLUGIN, BROKEN)
    assert done.returncode == 0
    assert done.stdout.split() == ["none", "zero_slip", "viso_ot", "viso_ot_fused", "truth", NAME]
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "'broken_estimator'" in lines[0] and "offtrack_broken_plugin_missing" in lines[0]
    assert "Traceback" not in done.stderr


def _recording(folder: Path, frames: int) -> Path:
    """A tiny KITTI folder (64×48 noise: the odometry refuses every frame) whose reference poses drive straight
    ahead 0.5 m a frame, so that the reference's off-tracking exists after a trailer length; signals beside it."""
    rng = np.random.default_rng(0)
    for side in ("image_0", "image_1"):
        (folder / side).mkdir(parents=True)
        for k in range(frames):
            cv2.imwrite(str(folder / side / f"{k:06d}.png"), rng.integers(0, 256, (48, 64), dtype=np.uint8))
    (folder / "times.txt").write_text("".join(f"{0.1 * k:.6e}\n" for k in range(frames)))
    p0, p1 = "50 0 31.5 0 0 50 23.5 0 0 0 1 0", "50 0 31.5 -25 0 50 23.5 0 0 0 1 0"
    (folder / "calib.txt").write_text(f"P0: {p0}\nP1: {p1}\nP2: {p0}\nP3: {p1}\n")
    (folder / "poses.txt").write_text("".join(f"1 0 0 0 0 1 0 0 0 0 1 {-0.5 * k}\n" for k in range(frames)))
    signals = [f"{0.05 * k:.3f},5.0,0.0,0.0" for k in range(2 * frames)]
    header = "time_s,speed_m_s,yaw_rate_deg_s,articulation_deg\n"
    (folder.parent / "signals.csv").write_text(header + "\n".join(signals))
    (folder.parent / "rig.yaml").write_text("vehicle: lst\npsi_c2v_deg: 180\nlever_arm_m: [-14.05, 0.0, 3.0]\n")
    return folder


def test_estimate_runs_a_plugins_offline_adapter_beside_the_built_in_ones(tmp_path: Path) -> None:
    folder, out = _recording(tmp_path / "seq", 34), tmp_path / "estimate"
    args = ("estimate", str(folder), "--rig", str(tmp_path / "rig.yaml"), "--signals", str(tmp_path / "signals.csv"))
    done = _python(CLI, PLUGIN, args=(*args, "--out", str(out), "--no-plots"))
    assert done.returncode == 0, done.stderr
    series = pd.read_parquet(out / "timeseries.parquet")
    # its columns after the built-ins' and the signals', as declared
    own = [f"offtracking_{NAME}", "shifted_truth_shift"]
    assert list(series.columns[-4:]) == ["trailer_wheel_speed", "tractor_lateral_acceleration", *own]
    assert "offtracking_zero_slip" in series and "offtracking_viso_ot_fused" in series
    truth, shifted = series["offtracking_truth"].to_numpy(), series[f"offtracking_{NAME}"].to_numpy()
    defined = np.isfinite(truth)
    assert defined.sum() > 5 and np.array_equal(np.isfinite(shifted), defined)
    assert np.abs(shifted[defined] - truth[defined] - SHIFT).max() < 1e-12
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["offtracking"]["estimators"][NAME]["mean_error"] == pytest.approx(SHIFT, abs=1e-12)
