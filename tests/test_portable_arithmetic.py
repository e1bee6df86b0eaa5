"""The portable arithmetic (``OFFTRACK_PORTABLE_ARITHMETIC=1``): OpenCV's CPU-dependent code off in every process.

What is checked: a spawned sweep worker applies the mode (``cv2.useOptimized()`` False with it, True without); a bad
value is one line naming the variable (exit code 2 from the command line); the calibration cache's key differs with
the mode; and the property itself on the smallest pieces that the trace of a field camera run (docs/usage.md,
"Portable arithmetic") found to round differently: a ``float32`` Gaussian blur (the world's grass texture) in two
processes, with and without ``OPENCV_CPU_DISABLE=AVX2,FMA3,AVX``, and a ``float32`` perspective warp (the right
camera's flex) with IPP at its own dispatch and at ``OPENCV_IPP=sse42``.

Machine facts relied on: an x86-64 CPU with AVX2 and FMA3 (else the differences with the mode off cannot show:
skipped), OpenCV built with AVX2 dispatch for the blur and with IPP for the warp (else that half is skipped). The
equality with the mode on holds wherever OpenCV runs its baseline code; the inequality with it off is what this
machine (an AMD EPYC with AVX2, OpenCV 5.1.0's wheel, IPP 2026.1.0) shows, asserted so that the test can fail.
"""

from __future__ import annotations

import concurrent.futures
import hashlib
import multiprocessing
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from scenarios.camera.calibration_cache import calibration_key
from scenarios.portable_arithmetic import ENV, PortableArithmeticError, apply, enabled, record
from sensor.camera import Lens, StereoRig

REPO = Path(__file__).resolve().parents[1]
CPU_AVX2, CPU_FMA3 = 11, 12
"""OpenCV's ``cv::CpuFeatures`` ids of AVX2 and FMA3 (``core/cvdef.h``; not exported to Python)."""

_PIECES = """
import hashlib, sys
import cv2
from scenarios.portable_arithmetic import apply
apply()
import numpy as np
rng = np.random.default_rng(3)
img = rng.random((128, 128), dtype=np.float32)
blur = cv2.GaussianBlur(img, (0, 0), 3.0)  # as sensor.textures._blur
k = np.array([[1.0, 0.01, 2.0], [0.003, 1.0, -1.5], [1e-5, 2e-5, 1.0]])
warp = cv2.warpPerspective(img, k, (128, 128), flags=cv2.INTER_LINEAR)  # as FieldOptics.optical's flex
print(hashlib.sha256(blur.tobytes()).hexdigest(), hashlib.sha256(warp.tobytes()).hexdigest(), cv2.useOptimized())
"""


def _pieces(**env: str) -> tuple[str, str, str]:
    """The blur's and the warp's digests and ``cv2.useOptimized()`` in a fresh process with ``env`` added."""
    environ = {k: v for k, v in os.environ.items() if k not in (ENV, "OPENCV_CPU_DISABLE", "OPENCV_IPP")}
    environ.update(env, PYTHONPATH=str(REPO))
    out = subprocess.run(
        [sys.executable, "-c", _PIECES], env=environ, capture_output=True, text=True, check=True, timeout=60
    )
    blur, warp, optimized = out.stdout.split()
    return blur, warp, optimized


def _worker_optimized() -> bool:
    return bool(cv2.useOptimized())


def _spawned_worker_optimized() -> bool:
    """``cv2.useOptimized()`` in a spawned process set up as a sweep worker (its initializer's set-up)."""
    from scenarios.studies.workers import setup_process

    ctx = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=ctx, initializer=setup_process) as pool:
        return pool.submit(_worker_optimized).result(timeout=60)


@pytest.mark.parametrize(("value", "expected"), [("1", False), ("0", True)])
def test_a_spawned_sweep_worker_applies_the_mode(monkeypatch: pytest.MonkeyPatch, value: str, expected: bool) -> None:
    monkeypatch.setenv(ENV, value)  # inherited by the spawned worker
    assert _spawned_worker_optimized() is expected


@pytest.mark.parametrize("value", ["yes", "2", "on", "true"])
def test_a_bad_value_is_one_line_naming_the_variable(monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    monkeypatch.setenv(ENV, value)
    with pytest.raises(PortableArithmeticError) as caught:
        apply()
    message = str(caught.value)
    assert ENV in message and "0" in message and "1" in message and "\n" not in message
    assert cv2.useOptimized()  # nothing was changed


def test_the_command_line_rejects_a_bad_value_before_any_work(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from scenarios import cli

    monkeypatch.setenv(ENV, "yes")
    monkeypatch.setattr(sys, "argv", ["offtrack", "list"])
    with pytest.raises(SystemExit) as stopped:
        cli.main()
    assert stopped.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and ENV in err[0]


def test_off_by_default_and_nothing_recorded(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(ENV, raising=False)
    assert not enabled() and not apply() and record() == {}
    assert cv2.useOptimized()
    assert enabled({ENV: "1"}) and not enabled({ENV: "0"}) and not enabled({ENV: ""})


def test_apply_switches_opencv_to_its_baseline_on_one_thread(monkeypatch: pytest.MonkeyPatch) -> None:
    threads = cv2.getNumThreads()
    monkeypatch.setenv(ENV, "1")
    try:
        assert apply() and apply()  # idempotent
        assert not cv2.useOptimized() and cv2.getNumThreads() == 1 and not cv2.ipp.useIPP()
        assert record() == {"portable_arithmetic": True, "opencv_optimized": False, "opencv_threads": 1}
    finally:
        cv2.setUseOptimized(True)
        cv2.setNumThreads(threads)
    assert cv2.useOptimized()


def test_the_calibration_key_differs_with_the_mode() -> None:
    rig, lens = StereoRig(width=160, height=48), Lens(k1=-0.05)
    settings = {"views": 8, "seed": 1}
    before = calibration_key(rig, lens, lens, **settings)
    try:
        cv2.setUseOptimized(False)
        assert not any(cv2.checkHardwareSupport(i) for i in range(1, 512))
        assert not cv2.ipp.useIPP()
        portable = calibration_key(rig, lens, lens, **settings)
    finally:
        cv2.setUseOptimized(True)
    assert cv2.useOptimized()
    assert calibration_key(rig, lens, lens, **settings) == before  # back as it was
    assert portable != before


def _has(feature: int) -> bool:
    return bool(cv2.checkHardwareSupport(feature))


@pytest.mark.skipif(
    not (_has(CPU_AVX2) and _has(CPU_FMA3)), reason="needs an x86-64 CPU with AVX2 and FMA3 (module notes)"
)
def test_the_same_bits_under_each_cpu_switch_with_the_mode_on() -> None:
    """Mode on: the blur and the warp to the bit with OpenCV's dispatch at AVX2 or at SSE4.2, and with IPP at its
    own dispatch or at SSE4.2; mode off: they differ (on this machine), so the comparison can fail."""
    on = _pieces(**{ENV: "1"})
    assert on[2] == "False"
    assert _pieces(**{ENV: "1", "OPENCV_CPU_DISABLE": "AVX2,FMA3,AVX"}) == on
    assert _pieces(**{ENV: "1", "OPENCV_IPP": "sse42"}) == on
    off = _pieces()
    assert off[2] == "True"
    no_avx = _pieces(OPENCV_CPU_DISABLE="AVX2,FMA3,AVX")
    assert no_avx[0] != off[0]  # the float32 Gaussian blur: AVX2/FMA3 code rounds otherwise
    ipp_sse42 = _pieces(OPENCV_IPP="sse42")
    if ipp_sse42[1] == off[1] and "IPP" not in cv2.getBuildInformation():
        pytest.skip("OpenCV without IPP: the warp's IPP path cannot show")
    assert ipp_sse42[1] != off[1]  # the float32 perspective warp: IPP's own CPU dispatch rounds otherwise


def test_the_mode_changes_the_default_numbers() -> None:
    """Baseline code rounds otherwise than this machine's dispatched code: the mode is not a no-op (a digest)."""
    img = np.random.default_rng(3).random((64, 64), dtype=np.float32)
    default = hashlib.sha256(cv2.GaussianBlur(img, (0, 0), 3.0).tobytes()).hexdigest()
    try:
        cv2.setUseOptimized(False)
        portable = hashlib.sha256(cv2.GaussianBlur(img, (0, 0), 3.0).tobytes()).hexdigest()
    finally:
        cv2.setUseOptimized(True)
    if _has(CPU_AVX2) and _has(CPU_FMA3):
        assert portable != default
    assert hashlib.sha256(cv2.GaussianBlur(img, (0, 0), 3.0).tobytes()).hexdigest() == default
