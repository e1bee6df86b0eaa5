"""``offtrack bench vo``'s comparison of two odometries: its settings checked before any work, and the per-frame
error it reports against the true motion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from scenarios.bench.vo import compared_settings, frame_errors
from scenarios.cli import app


class _Result:
    def __init__(self, motion: np.ndarray | None) -> None:
        self.motion = motion


def _rigid(yaw: float, t: tuple[float, float, float]) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    m = np.eye(4)
    m[:3, :3] = [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
    m[:3, 3] = t
    return m


def test_frame_errors_are_the_analytic_translation_and_angle() -> None:
    """Exact motions err by 0; a motion off by a known rotation θ about y and a known offset d errs by θ and |d|
    (1e-12); a frame without a motion is NaN."""
    truth = np.stack([_rigid(0.01 * k, (0.0, 0.0, 0.3)) for k in range(3)])
    off = _rigid(0.002, (0.003, -0.004, 0.0))
    results = [_Result(None), _Result(truth[0]), _Result(truth[1] @ off), _Result(None)]
    errors = frame_errors(results, truth)
    assert errors[0] == pytest.approx([0.0, 0.0], abs=1e-12)
    assert errors[1] == pytest.approx([0.005, 0.002], abs=1e-12)
    assert np.isnan(errors[2]).all()


def test_compared_settings_pass_a_valid_change_through() -> None:
    assert compared_settings({"gradient_refinement": "lucas_kanade", "refinement": 2}) == {
        "gradient_refinement": "lucas_kanade",
        "refinement": 2,
    }
    assert compared_settings(None) == {}


@pytest.mark.parametrize(
    ("given", "named"),
    [
        ("gradient_refinement=nope", "--compare gradient_refinement='nope': Input should be 'off'"),
        ("refinement=7", "--compare refinement=7: Input should be less than or equal to 2"),
        ("nosuch=1", "--compare nosuch: not an odometry setting; one of baseline,"),
        ("x", "--compare 'x': give KEY=VALUE"),
    ],
)
def test_a_bad_comparison_is_refused_on_one_line_before_any_work(given, named, tmp_path, monkeypatch) -> None:
    """Exit 2, one ``error:`` line naming ``--compare`` and the field, and nothing rendered (the cache stays empty)."""
    monkeypatch.setenv("OFFTRACK_CACHE_DIR", str(tmp_path))
    result = CliRunner().invoke(app, ["bench", "vo", "--compare", given])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: " + named), result.output
    assert not any(tmp_path.iterdir())
