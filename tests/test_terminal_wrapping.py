"""The run summary's verdict lines and the calibration summary wrap on word boundaries at 80 and 100 columns.

A line folded inside a word ("5.164 m" split into "5.1" and "64 m") cannot be read or searched; rich wraps plain text
on spaces, and these tests pin it for the longest lines the commands print.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from rich.console import Console
from test_roundabout_reason import FAILED

from scenarios.run.summary import run_summary
from sensor.calibration_report import calibration_line

METRICS = {
    "scenario": "roundabout-test",
    "status": "completed",
    "feedback": "zero_slip",
    "offtracking": {"truth": {"rms": 0.2, "max_abs": 0.46, "defined_fraction": 0.92}, "estimators": {}},
    "trailer_steering": {"trailer2": {"max_abs_steer_deg": 25.0, "saturated_fraction": 0.24}},
    "roundabout_test": FAILED,
    "verdict": {
        "held": False,
        "flags": [
            {
                "flag": "offtracking_above_target",
                "reason": "true off-tracking after warm-up 0.206 m RMS / 0.461 m max, not within the target 0.10 m "
                "RMS / 0.15 m max",
            }
        ],
    },
    "simulated_s": 124.3,
    "wall_time_s": 15.3,
}

CALIBRATION = {
    "rms_px": {"left": 0.1234, "right": 0.1301, "stereo": 0.1969},
    "baseline_m": {"error": -0.00012},
    "rotation_deg": {axis: {"error": 0.0123} for axis in ("roll", "pitch", "yaw")},
}


def _printed(renderables: list, width: int) -> list[str]:
    console = Console(record=True, width=width, color_system=None)
    for renderable in renderables:
        console.print(renderable)
    return console.export_text().splitlines()


def _words(text: str) -> list[str]:
    return text.split()


@pytest.mark.parametrize("width", [80, 100])
def test_the_verdict_lines_wrap_between_words(width: int) -> None:
    lines = _printed(run_summary(METRICS, Path("runs/roundabout-test/x")), width)
    assert all(len(line) <= width for line in lines)
    text = "\n".join(lines)
    start = text.index("roundabout test FAIL")
    verdict = text[start : text.index("not held", start)]
    assert len(verdict.strip().splitlines()) > 1  # long enough to wrap at these widths
    plain = Console(record=True, width=1000, color_system=None)
    plain.print(next(r for r in run_summary(METRICS, Path("x")) if isinstance(r, str) and "roundabout" in r))
    # the words of the wrapped verdict are those of the unwrapped line, none cut
    assert _words(verdict) == _words(plain.export_text())
    flag = text[text.index("offtracking_above_target") : text.index("roundabout_test_failed")]
    assert _words(flag) == _words("offtracking_above_target: " + METRICS["verdict"]["flags"][0]["reason"])


@pytest.mark.parametrize("width", [80, 100])
def test_the_calibration_summary_wraps_between_words(width: int) -> None:
    line = calibration_line(CALIBRATION)
    assert len(line) > width
    lines = _printed([line], width)
    assert len(lines) > 1 and all(len(text) <= width for text in lines)
    assert _words("\n".join(lines)) == _words(line)
    assert "stereo 0.197 px" in line and "baseline error -0.12 mm" in line
