"""The figure-eight's camber between its two loops: a superelevation run-off, not a crease.

Each loop of the figure-eight falls radially; at the crossover the two loops' crossfalls are opposite. Taking the
nearest loop's camber would flip the crossfall from -5 % to +5 % at a point, which on ice makes even the truth-fed
loop lose control (t ≈ 113 s): the trailer axles have to reverse a lateral force near μ·F_z at once.
``LoopCamber`` blends the two over ``CAMBER_RUNOFF`` either side of the bisector, through flat.
"""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.config import load_scenario
from scenarios.run.drive import simulate
from scenarios.run.metrics import after_warmup
from scenarios.setup.build import build_scenario
from vehicle_model.surface import grade_to_sin


def _crossfall_along_path(name: str, camber: float) -> tuple[np.ndarray, np.ndarray]:
    setup = build_scenario(load_scenario(name, {"camber.percent": camber}))
    path = setup.path
    s = np.arange(0.0, path.length, 0.5)
    pts = np.array([path.at(si)[:2] for si in s])
    heading = np.array([path.at(si)[2] for si in s])
    slope = setup.surface.slope(pts)  # sin θ times the fall direction
    normal = np.stack([-np.sin(heading), np.cos(heading)], axis=1)  # left of the direction of travel
    return s, np.sum(slope * normal, axis=1)


def test_the_figure_eight_crossfall_turns_smoothly_between_the_loops() -> None:
    _, cross = _crossfall_along_path("figure-eight", 5.0)
    # Full camber is reached on both loops, with opposite signs ...
    assert cross.max() == pytest.approx(grade_to_sin(5.0), abs=1e-6)
    assert cross.min() == pytest.approx(-grade_to_sin(5.0), abs=1e-6)
    # ... and between them it changes by under 1 % per 0.5 m (nearest-loop camber: a 9.9 % step).
    # A linear run-off over the path's ~16 m at the crossover changes it by ~0.3 % per 0.5 m.
    assert np.abs(np.diff(cross)).max() < 0.01


def test_a_single_loop_roundabout_is_unchanged_by_the_runoff() -> None:
    s, cross = _crossfall_along_path("roundabout-3", 5.0)
    setup = build_scenario(load_scenario("roundabout-3", {"camber.percent": 5.0}))
    on_loop = (s > setup.path.turn_span[0] + 5.0) & (s < setup.path.turn_span[1] - 5.0)
    # Radial camber of one centre: the full crossfall on the whole circulatory carriageway.
    np.testing.assert_allclose(np.abs(cross[on_loop]), grade_to_sin(5.0), atol=1e-9)


def test_the_truth_fed_figure_eight_on_ice_and_camber_stays_under_control() -> None:
    # The first 120 s of the 171 s: the crossing between the loops (about 86 s in) and the second loop's first
    # third, past where the crease made it leave the road.
    overrides = {"vehicle": "lst", "feedback": "truth", "surface.preset": "ice", "camber.percent": 5.0}
    cfg = load_scenario("figure-eight", {**overrides, "duration_s": 120.0})
    setup = build_scenario(cfg)
    outcome, cols = simulate(setup)  # model only
    assert outcome.status == "completed"  # with the crease: lost_control (left the road) at t ≈ 113 s
    e = cols["offtracking_truth"][after_warmup(cols, setup.params.follow_point_offset)]
    assert np.sqrt(np.mean(e**2)) <= 0.05  # measured 0.016 m (the whole figure of eight: 0.014 m)
    assert np.abs(e).max() <= 0.15  # measured 0.095 m (the same over the whole figure of eight)
