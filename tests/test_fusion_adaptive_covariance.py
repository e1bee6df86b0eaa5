"""The camera's covariance grown by the median NIS of the motions before it, eq (V1) of :mod:`sensor.fusion_adaptive`.

* Synthetic innovations whose covariance is under-stated by a known factor (2.5, the prediction's covariance 5 % of
  the motion's): the factor converges to the NIS's scale, ``(0.05 + 2.5)/1.05``, its mean over the settled motions
  within 3 % (the median over 100 χ²₃ draws has a relative std of about 11 %), every value within ``[1, f_max]``;
  far beyond the ceiling it sits at the ceiling; it is 1 until ``N`` motions have been seen, a motion is taken with
  the factor of the motions before it, and one wild motion moves it by under 5 %.
* Consistent innovations: the factor stays at the floor within its sampling spread (the clipped median of 100
  draws: mean ≤ 1.1, largest ≤ 1.4);
  off, the covariance is the same array and nothing is kept; a filter with the setting off but other values in its
  fields is the default's bit for bit, and one on is fed its grown covariance at the gate.
* Bad bounds are refused before any work, naming the field (exit 2 from the CLI).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import sensor.fusion as fusion
from scenarios.cli import app
from scenarios.config import ConfigError, load_scenario
from sensor.fusion import FusedVisoOt, FusionNoise
from sensor.fusion_adaptive import AdaptiveCovariance
from tests.test_fusion import CAMERA, PARAMS, drive_with_truth, run

R = np.array([[9e-6, 2e-6, 1e-7], [2e-6, 1.6e-5, -2e-7], [1e-7, -2e-7, 4e-8]])  # a motion's covariance at s₀
H = np.hstack([np.eye(3), np.zeros((3, 4))])
P = np.zeros((7, 7))
P[:3, :3] = 0.05 * R  # the prediction's covariance, small beside the motion's
ON = FusionNoise(vo_covariance_adaptive=True)  # N = 100, f_max = 4


def feed(adaptive: AdaptiveCovariance, rng: np.random.Generator, under: float, n: int) -> np.ndarray:
    """The factor each of ``n`` motions is taken with, their innovations drawn with ``R`` ``under`` times too small."""
    chol = np.linalg.cholesky(0.05 * R + under * R)
    factors = np.empty(n)
    for k in range(n):
        factors[k] = adaptive.factor
        np.testing.assert_array_equal(adaptive.scaled(R), adaptive.factor * R)  # the factor of the motions before
        adaptive.observe(H, P, chol @ rng.standard_normal(3), R)
    return factors


def test_the_factor_converges_to_a_known_under_statement() -> None:
    rng = np.random.default_rng(0)
    adaptive = AdaptiveCovariance(ON)
    factors = feed(adaptive, rng, 2.5, 700)
    assert np.all(factors[:100] == 1.0)  # the floor until N motions
    expected = (0.05 + 2.5) / 1.05  # the NIS's scale against the unscaled S
    assert np.mean(factors[200:]) == pytest.approx(expected, rel=0.03)
    assert np.all((factors >= 1.0) & (factors <= ON.vo_adaptive_max_factor))
    before = adaptive.factor
    adaptive.observe(H, P, np.array([1.0, 1.0, 0.1]), R)  # one wild motion (NIS ~1e5)
    assert adaptive.factor == pytest.approx(before, rel=0.05)
    far = AdaptiveCovariance(ON)
    assert np.all(feed(far, rng, 50.0, 200)[101:] == ON.vo_adaptive_max_factor)  # the ceiling


def test_consistent_innovations_stay_at_the_floor() -> None:
    factors = feed(AdaptiveCovariance(ON), np.random.default_rng(3), 1.0, 700)  # S as stated
    assert 1.0 <= np.mean(factors[100:]) <= 1.1  # seeds 0-4: 1.02-1.10
    assert np.max(factors) <= 1.4  # seeds 0-4: 1.20-1.37
    off = AdaptiveCovariance(FusionNoise())
    assert off.scaled(R) is R
    off.observe(H, P, np.array([1.0, 1.0, 0.1]), R)
    assert off.factor == 1.0 and not off._nis


def test_the_filter_takes_the_grown_covariance_and_off_is_the_default(monkeypatch) -> None:
    r_m, w_m, incs, _ = drive_with_truth(n=400, slip=0.0)
    errors = np.random.default_rng(2).normal(0.0, [0.02, 0.02, 2e-3], (len(incs) // 5 + 1, 3))  # far above R
    default = FusedVisoOt(PARAMS, CAMERA, FusionNoise())
    quiet = FusedVisoOt(PARAMS, CAMERA, FusionNoise(vo_adaptive_window=10, vo_adaptive_max_factor=2.0))  # off
    est, std, _ = run(default, r_m, w_m, incs, frame_error=errors)
    est_quiet, std_quiet, _ = run(quiet, r_m, w_m, incs, frame_error=errors)
    np.testing.assert_array_equal(est, est_quiet)
    np.testing.assert_array_equal(std, std_quiet)
    taken, floor = [], []
    gated = fusion.gated_update

    def gate(x, p, h, innovation, r, *rest):
        taken.append(r)
        return gated(x, p, h, innovation, r, *rest)

    monkeypatch.setattr(fusion, "gated_update", gate)
    on = FusedVisoOt(PARAMS, CAMERA, FusionNoise(vo_covariance_adaptive=True, vo_adaptive_window=10))
    measurement = on.measurement

    def measured(*args):
        out = measurement(*args)
        floor.append(out[1])
        return out

    monkeypatch.setattr(on, "measurement", measured)
    run(on, r_m, w_m, incs, frame_error=errors)
    ratios = np.array([t[0, 0] / f[0, 0] for t, f in zip(taken, floor, strict=True)])
    assert len(ratios) > 50 and np.all(ratios[:10] == 1.0)
    assert np.all(ratios[-20:] == ON.vo_adaptive_max_factor)  # errors far above R: at the ceiling
    assert on._adaptive.factor == ON.vo_adaptive_max_factor


def test_bad_bounds_are_refused(tmp_path: Path) -> None:
    settings = {"fusion.vo_covariance_adaptive": True, "fusion.vo_adaptive_window": 50}
    config = load_scenario("roundabout-3", {**settings, "fusion.vo_adaptive_max_factor": 2.0})
    assert config.fusion.vo_covariance_adaptive and config.fusion.vo_adaptive_window == 50
    for field, bad in (
        ("fusion.vo_adaptive_window", 5),
        ("fusion.vo_adaptive_window", 20000),
        ("fusion.vo_adaptive_max_factor", 0.5),
        ("fusion.vo_adaptive_max_factor", 1e3),
        ("fusion.vo_adaptive_max_factor", float("nan")),
        ("fusion.vo_covariance_adaptive", "sometimes"),
    ):
        with pytest.raises(ConfigError, match=re.escape(field)):
            load_scenario("roundabout-3", {field: bad})
    args = ["run", "roundabout-3", "--out", str(tmp_path / "run"), "--set", "fusion.vo_adaptive_max_factor=0"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    assert "fusion.vo_adaptive_max_factor" in result.output
    assert not (tmp_path / "run").exists()
