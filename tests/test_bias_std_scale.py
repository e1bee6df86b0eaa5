"""``bias_std_scale``, ``f_b`` of eq (5) (:mod:`sensor.fusion_std`): a factor on the std's biases' term alone.

* The estimate, the state and its covariance do not move with it; the biases' term is ``f_b²`` times the one
  without (to 1e-12 relative) and every other term is the same to the bit; unset (1) the filter is the default's
  bit for bit.
* A side rig takes it from ``fusion.side_rig`` and a forward camera keeps the section's.
* A bad factor is refused before any work, naming the field (exit 2).
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
from sensor.fusion import STD_PARTS, FusedVisoOt, FusionNoise
from tests.test_fusion import CAMERA, PARAMS, drive_with_truth, run

SCALE = 0.87


@pytest.fixture(scope="module")
def filters() -> dict[str, tuple[FusedVisoOt, np.ndarray, np.ndarray]]:
    r_m, w_m, incs, _ = drive_with_truth(n=400, slip=0.0)  # 8 s: a straight, then the turn's entry
    out = {}
    for name, noise in (
        ("default", FusionNoise()),
        ("one", FusionNoise(bias_std_scale=1.0)),
        ("scaled", FusionNoise(bias_std_scale=SCALE)),
    ):
        fused = FusedVisoOt(PARAMS, CAMERA, noise)
        est, std, _ = run(fused, r_m, w_m, incs)
        out[name] = (fused, np.asarray(est, dtype=float), np.asarray(std, dtype=float))
    return out


def test_only_the_biases_term_moves(filters) -> None:
    default, one, scaled = filters["default"], filters["one"], filters["scaled"]
    assert np.isfinite(default[1]).sum() > 50  # estimates were made
    for other in (one, scaled):
        assert np.array_equal(default[1], other[1], equal_nan=True)  # the estimate does not move
        assert np.array_equal(default[0].state, other[0].state)
        assert np.array_equal(default[0].covariance, other[0].covariance)
    assert np.array_equal(default[2], one[2], equal_nan=True)  # f_b = 1: the default's std to the bit
    parts, narrowed = default[0].std_parts, scaled[0].std_parts
    assert parts["biases"] > 0.0
    assert math.isclose(narrowed["biases"], SCALE**2 * parts["biases"], rel_tol=1e-12)
    for part in STD_PARTS:
        if part != "biases":
            assert narrowed[part] == parts[part], part
    ok = np.isfinite(default[2])
    assert np.all(scaled[2][ok] < default[2][ok])  # narrower wherever there is a std


def test_the_side_rig_takes_it_and_a_bad_factor_is_refused(tmp_path: Path) -> None:
    field = "fusion.side_rig.bias_std_scale"
    config = load_scenario("roundabout-3", {field: SCALE})
    assert config.fusion.for_camera((0.0, -1.0)).bias_std_scale == SCALE  # the side rig's filter
    assert config.fusion.for_camera((1.0, 0.0)).bias_std_scale == 1.0  # a forward camera: the section's
    for bad in (0.0, -0.5, 1.5, float("nan")):
        with pytest.raises(ConfigError, match=re.escape(field)):
            load_scenario("roundabout-3", {field: bad})
    args = ["run", "roundabout-3", "--out", str(tmp_path / "run"), "--set", "fusion.bias_std_scale=2"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    assert "fusion.bias_std_scale" in result.output
    assert not (tmp_path / "run").exists()
