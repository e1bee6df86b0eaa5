"""The camera latency and the pipelined camera (``scenarios/camera/delivery.py``): what the controller sees is set
by the latency alone.

A pipelined run renders in spawned worker processes while the co-simulation runs the odometry; a serial run
does everything in-process on the tick the frame is taken. For the same seed and latency both must record
the same time series (the timing columns aside), the estimate must reach the controller exactly the latency
after its frame, and a render worker that dies must end the run with a clear status, not a hang.
"""

from __future__ import annotations

import multiprocessing
import os
import signal

import numpy as np
import pytest

from scenarios.camera.delivery import latency_ticks
from scenarios.camera.workers import DEFAULT_WORKERS, RENDER_NICENESS, default_workers
from scenarios.config import ConfigError, load_scenario
from scenarios.run.drive import simulate
from scenarios.setup.build import build_scenario

pytestmark = pytest.mark.rendering

TIMING_COLUMNS = {"render_ms", "vo_ms"}
SMALL_CAMERA = {"camera.width": 672, "camera.height": 196}


def camera_run(workers: int, duration: float = 4.0, feedback: str = "viso_ot", progress=None, **overrides):
    """A short LST run on roundabout-3 at 25 km/h (the VISO-OT buffer fills in ~2 s), steered by ``feedback``."""
    cfg = load_scenario(
        "roundabout-3",
        {
            "vehicle": "lst",
            "estimators.viso_ot": True,
            "feedback": feedback,
            "duration_s": duration,
            "speed.cornering_kmh": 25.0,
            **overrides,
        },
    )
    setup = build_scenario(cfg)
    return simulate(setup, progress=progress, camera_workers=workers)  # the trailer steered on ``feedback``


def assert_same_series(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert a.keys() == b.keys()
    differ = [k for k in a if k not in TIMING_COLUMNS and not np.array_equal(a[k], b[k], equal_nan=True)]
    assert differ == []


@pytest.mark.parametrize("workers", [1, pytest.param(2, marks=pytest.mark.slow)])  # one: the default
def test_pipelined_and_serial_runs_are_identical_at_the_default_latency(workers: int) -> None:
    serial_outcome, serial = camera_run(0, duration=3.0, **SMALL_CAMERA)  # the size does not enter the delivery
    piped_outcome, piped = camera_run(workers, duration=3.0, **SMALL_CAMERA)
    assert serial_outcome.status == piped_outcome.status == "completed"
    assert piped_outcome.camera["workers"] == workers and piped_outcome.camera["latency_ticks"] == 5
    assert_same_series(serial, piped)
    # the first frames' one-off costs (OpenGL contexts, kernels) are kept apart for the benchmark
    for cam in (serial_outcome.camera, piped_outcome.camera):
        assert cam["startup_frames"] == 2
        assert 0.0 < cam["startup_render_cpu_s"] < cam["render_cpu_s"]
        assert 0.0 < cam["startup_vo_cpu_s"] < cam["vo_cpu_s"]
    # the estimate did steer the trailer (the comparison covers the closed loop, not only the recording)
    assert np.isfinite(serial["offtracking_viso_ot"]).sum() > 20
    assert np.isfinite(serial["vo_valid"][serial["camera_frame"] > 0.5]).all()  # every frame's row complete


@pytest.mark.slow  # the default latency's identity runs in the default suite
@pytest.mark.parametrize(("latency", "workers"), [(0.0, 1), (0.25, 2)])
def test_pipelined_and_serial_runs_are_identical_at_any_latency(latency: float, workers: int) -> None:
    over = {**SMALL_CAMERA, "camera.latency_s": latency}
    serial_outcome, serial = camera_run(0, duration=3.0, **over)
    piped_outcome, piped = camera_run(workers, duration=3.0, **over)
    assert serial_outcome.status == piped_outcome.status == "completed"
    assert_same_series(serial, piped)


def test_the_estimate_reaches_the_controller_exactly_one_latency_after_its_frame() -> None:
    # Truth feedback: the motion does not depend on the camera, so the series only shift. One latency, not a whole
    # number of ticks: the shift is the same code for every latency, and the default's 5 ticks (a frame period) are
    # checked in test_latency_ticks_round_up_to_control_ticks.
    _, now = camera_run(0, duration=3.0, feedback="truth", **SMALL_CAMERA, **{"camera.latency_s": 0.0})
    _, later = camera_run(0, duration=3.0, feedback="truth", **SMALL_CAMERA, **{"camera.latency_s": 0.23})
    np.testing.assert_array_equal(now["X"], later["X"])
    ticks = 12  # 0.23 s is released on the first 20 ms tick after it
    used = later["offtracking_viso_ot"]
    assert np.isfinite(now["offtracking_viso_ot"][:-ticks]).sum() > 20  # the shift is of estimates, not NaN only
    np.testing.assert_array_equal(used[ticks:], now["offtracking_viso_ot"][:-ticks])
    assert np.isnan(used[:ticks]).all()
    # the frames' own records stay on the rows they were taken on
    np.testing.assert_array_equal(now["vo_inliers"], later["vo_inliers"])


def test_latency_ticks_round_up_to_control_ticks() -> None:
    def ticks(**over):
        return latency_ticks(build_scenario(load_scenario("roundabout-test", over)))

    assert ticks() == 5  # one frame period at 10 Hz camera, 50 Hz control
    assert ticks(**{"rates.camera_hz": 25.0}) == 2
    assert ticks(**{"camera.latency_s": 0.0}) == 0
    assert ticks(**{"camera.latency_s": 0.02}) == 1
    assert ticks(**{"camera.latency_s": 0.021}) == 2


@pytest.mark.parametrize("value", [-0.1, 1.5, float("inf"), float("nan")])
def test_a_bad_latency_is_refused_naming_the_field(value: float) -> None:
    with pytest.raises(ConfigError, match=r"camera\.latency_s"):
        load_scenario("roundabout-test", {"camera.latency_s": value})


def test_default_workers_follow_the_environment_and_the_run_length(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("OFFTRACK_CAMERA_WORKERS", raising=False)
    assert default_workers(10) == 0  # too short to pay for the start-up
    assert default_workers(10_000) == (DEFAULT_WORKERS if (os.cpu_count() or 1) >= 2 else 0)
    monkeypatch.setenv("OFFTRACK_CAMERA_WORKERS", "1")
    assert default_workers(10) == 1
    monkeypatch.setenv("OFFTRACK_CAMERA_WORKERS", "many")
    with pytest.raises(ValueError, match="OFFTRACK_CAMERA_WORKERS"):
        default_workers(10)


@pytest.mark.parametrize("workers", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_a_render_worker_that_dies_ends_the_run_with_a_clear_status(workers: int) -> None:
    killed: list[int] = []
    niceness: list[int] = []

    def kill_a_worker(sim_time: float, fraction: float) -> None:
        if sim_time >= 1.0 and not killed:
            worker = next(p for p in multiprocessing.active_children() if p.name.startswith("offtrack-render"))
            niceness.append(os.getpriority(os.PRIO_PROCESS, worker.pid))
            os.kill(worker.pid, signal.SIGKILL)
            killed.append(worker.pid)

    outcome, columns = camera_run(workers, duration=30.0, progress=kill_a_worker, **SMALL_CAMERA)
    assert killed
    # the workers yield to the co-simulation process (the critical path)
    assert niceness == [min(os.getpriority(os.PRIO_PROCESS, 0) + RENDER_NICENESS, 19)]
    assert outcome.status == "failed"
    assert "camera render worker" in outcome.message and "SIGKILL" in outcome.message, outcome.message
    assert str(killed[0]) in outcome.message
    assert outcome.rows == len(columns["time"]) > 50  # the rows up to the failure are kept
    assert columns["time"][-1] < 5.0  # it stopped at the failure, long before the 30 s
    assert not [p for p in multiprocessing.active_children() if p.name.startswith("offtrack-render")]
