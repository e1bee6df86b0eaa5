"""VISO-OT on rendered images in the loop (de Saxe & Cebon 2018, §3 reference case) and the right-image correction."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from scenarios.camera.frame_cache import FRAME_CACHE_ENV
from scenarios.config import load_scenario
from scenarios.loop.trailer_steer import UnsteeredTrailer, trailer_axles
from scenarios.run.drive import simulate
from scenarios.run.metrics import estimator_errors
from scenarios.setup.build import build_scenario
from sensor.camera import StereoRig
from sensor.field_optics import right_correction_homography

pytestmark = pytest.mark.rendering

TIMING_COLUMNS = {"render_ms", "vo_ms"}


def constant_slip(frame_cache: Path | None = None, **overrides):
    """The constant-slip case's columns; with ``frame_cache`` its frames kept there, or taken back from there when a
    run of the same camera kept them at the same poses (the frame cache gives back what a run renders:
    test_camera_assembly.py)."""
    cfg = load_scenario("constant-slip", {"estimators.viso_ot": True, "estimators.zero_slip": False, **overrides})
    setup = build_scenario(cfg)
    with pytest.MonkeyPatch.context() as patch:
        if frame_cache is not None:
            patch.setenv(FRAME_CACHE_ENV, str(frame_cache))
        return simulate(setup, UnsteeredTrailer(trailer_axles(setup)))[1]


@pytest.fixture(scope="module")
def frame_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The reference case's frames, kept by :func:`reference_start` for the runs of the same camera after it."""
    return tmp_path_factory.mktemp("frames")


@pytest.fixture(scope="module")
def reference_case():
    # de Saxe & Cebon 2018 §3.2.1 reference: 14° slip, 0.5 m baseline, rear-facing cameras, 5 m/s, 10 fps, 100 m.
    return constant_slip()


@pytest.fixture(scope="module")
def reference_start(frame_cache: Path):
    # The reference case's first 6 s (61 frames, rendered in-process): the default suite's version of it. Its frames
    # are kept for the failed-frames run, which takes the same frames (the motion does not depend on the camera).
    return constant_slip(frame_cache, duration_s=6.0)


def _meets_the_paper_accuracy(cols, duration: float) -> None:
    err = estimator_errors(cols["offtracking_truth"], cols["offtracking_viso_ot"])
    assert err["valid_fraction"] > 0.95
    assert err["rms_error"] <= 0.04  # the paper's §3: 0.01–0.04 m RMS in simulation
    assert err["max_abs_error"] <= 0.15  # the 0.15 m maximum target
    frames = cols["camera_frame"] > 0.5
    assert frames.sum() == pytest.approx(10.0 * duration + 1, abs=1)  # at 10 fps
    assert np.nanmean(cols["vo_matches"][frames]) > 200
    assert np.nanmean(cols["vo_valid"][frames][1:]) > 0.95


@pytest.mark.slow  # its first 6 s run in the default suite
def test_viso_ot_meets_the_paper_accuracy_on_the_reference_case(reference_case):
    _meets_the_paper_accuracy(reference_case, 20.0)


def test_viso_ot_meets_the_paper_accuracy_on_the_reference_cases_first_6_s(reference_start):
    # Measured: 0.020 m RMS, 0.034 m maximum, 97 % valid, 310 matches a frame.
    _meets_the_paper_accuracy(reference_start, 6.0)


def test_same_seed_same_output(reference_start):
    # A second run of the reference case's first 2 s (21 frames) records the 6 s run's rows. Another seed changes
    # the odometry's columns within those 2 s, so the check can fail. The timing columns differ between any two runs.
    a = constant_slip(duration_s=2.0)
    n = len(a["time"])
    assert n == 101 and a.keys() == reference_start.keys()
    differ = [
        k for k in a if k not in TIMING_COLUMNS and not np.array_equal(a[k], reference_start[k][:n], equal_nan=True)
    ]
    assert differ == []


@pytest.mark.slow  # the default suite's pipelined and serial runs: tests/test_loop_pipelining.py
def test_the_reference_case_rendered_in_workers_records_the_in_process_rows(reference_case, reference_start):
    # The whole case (201 frames) renders in worker processes, its first 6 s in-process: the same rows, the timing
    # columns aside.
    n = len(reference_start["time"])
    assert n == 301 and reference_start.keys() == reference_case.keys()
    differ = [
        k
        for k in reference_start
        if k not in TIMING_COLUMNS and not np.array_equal(reference_start[k], reference_case[k][:n], equal_nan=True)
    ]
    assert differ == []


@pytest.mark.parametrize(
    "duration", [pytest.param(6.0, id="6-s"), pytest.param(20.0, id="whole-case", marks=pytest.mark.slow)]
)
def test_failed_frames_are_survived(monkeypatch, duration, reference_start, frame_cache: Path):
    # Every fifth frame of the odometry fails; the estimator bridges them and still meets the target (with the
    # failures 0.029 m RMS and 97 % valid in the first 6 s, 0.048 m in the first 10 s against 0.034 m without; an
    # estimator that drops its estimate after a failure instead of bridging is valid 0 % of the 6 s).
    from sensor.vo import StereoOdometry, VOResult

    original = StereoOdometry.process
    calls = {"n": 0}

    def flaky(self, left, right):
        result = original(self, left, right)
        calls["n"] += 1
        if calls["n"] % 5 == 0:
            return VOResult(False, None, result.n_matches, 0, 0.0, 0.0, 0.0, 0.0, reason="injected failure")
        return result

    monkeypatch.setattr(StereoOdometry, "process", flaky)
    # the first 6 s's frames taken back from the reference run's (the odometry is what fails, not the rendering)
    kept = {f: f.stat().st_mtime_ns for f in frame_cache.glob("*/*.npz")}
    cols = constant_slip(frame_cache, duration_s=duration)
    assert len(kept) == 61 and all(f.stat().st_mtime_ns == stamp for f, stamp in kept.items())  # read, not rendered
    frames = cols["camera_frame"] > 0.5
    assert frames.sum() == pytest.approx(10.0 * duration + 1, abs=1)
    assert (cols["vo_valid"][frames] < 0.5).sum() >= 0.17 * frames.sum()  # every fifth frame but the first
    err = estimator_errors(cols["offtracking_truth"], cols["offtracking_viso_ot"])
    assert err["valid_fraction"] > 0.9 and err["rms_error"] <= 0.06


def test_right_correction_undoes_a_misalignment():
    rig = StereoRig.from_degrees(roll_deg=-0.15, pitch_deg=0.05, yaw_deg=0.10)
    correction = right_correction_homography(rig, (-0.15, 0.05, 0.10))
    combined = correction @ rig.misalignment_homography()
    assert combined / combined[2, 2] == pytest.approx(np.eye(3), abs=1e-12)
    assert right_correction_homography(rig, (0.0, 0.0, 0.0)) is None
    assert math.isfinite(float(np.linalg.cond(correction)))
