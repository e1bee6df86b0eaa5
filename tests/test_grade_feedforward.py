"""The speed controller's grade feed-forward from each unit's own slope (``speed.grade_feedforward: units``, the
default; :func:`controller.speed.combination_grade_feedforward`), against the tractor's slope for the whole mass
(``tractor``).

* With every unit on one slope and in line it is the default feed-forward (the combination's mass times gravity along
  the tractor) to 1e-12; a trailer climbing behind a level tractor adds its own ``m·g·sinθ`` through the
  articulation's cosine, which the tractor's slope alone does not see.
* On the rough wet-clay gravel yard (0.15 m undulations over 12 m, shorter than the LST) the combination at rest at
  its start: the model's own acceleration times the combination's mass is the units' feed-forward to 1e-9, while
  the tractor's slope times the whole mass misses it by more than the drive's traction limit.
* End to end (slow): the unsteered LST on that yard at seed 1. With the tractor's slope for the whole mass the speed
  controller brakes on descents the trailer is not on, and the combination stalls on the first climb of the circle
  and rolls back; with each unit's own slope it drives on.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from controller.speed import combination_grade_feedforward, grade_feedforward, traction_limit
from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from scenarios.studies.off_highway import off_highway_case, run_off_highway_case
from vehicle_model.parameters import GRAVITY
from vehicle_model.simulator import Simulator


def test_on_one_slope_in_line_it_is_the_combinations_mass_times_the_tractors_gravity() -> None:
    masses = (9841.0, 33101.0, 12000.0)
    along = -GRAVITY * 0.08 / math.sqrt(1.0 + 0.08**2)
    units = combination_grade_feedforward(masses, (along,) * 3, (0.0, 0.0))
    assert units == pytest.approx(grade_feedforward(sum(masses), along), rel=1e-12)
    assert units > 0.0  # uphill: it drives


def test_a_trailer_climbing_behind_a_level_tractor_adds_its_own_weight_through_the_articulation() -> None:
    climb = -GRAVITY * 0.05 / math.sqrt(1.0 + 0.05**2)
    articulation = 0.4
    force = combination_grade_feedforward((9841.0, 33101.0), (0.0, climb), (articulation,))
    assert force == pytest.approx(-33101.0 * climb * math.cos(articulation), rel=1e-12)
    assert grade_feedforward(9841.0 + 33101.0, 0.0) == 0.0  # the tractor's slope says nothing
    with pytest.raises(ValueError, match="gravity_along"):
        combination_grade_feedforward((1.0, 2.0), (0.0,), (0.0,))


def _yard(seed: int, feedforward: str | None = None) -> dict:
    overrides = dict(off_highway_case("gravel-yard", "wet_clay", "rough", "ideal", "none", True, seed=seed).overrides)
    if feedforward is not None:
        overrides["speed.grade_feedforward"] = feedforward
    return overrides


def test_on_the_rough_yard_the_units_feedforward_is_the_models_gravity_load_and_the_tractors_is_not() -> None:
    config = load_scenario("gravel-yard", _yard(1))
    assert config.speed.grade_feedforward == "units"  # the default
    setup = build_scenario(config)
    sim = Simulator(setup.params, setup.surface, model=setup.model)
    start = setup.initial_state
    state = start.__class__.from_vector(
        np.r_[start.to_vector()[:3], 0.0, start.to_vector()[4:]], 0.0, len(setup.params.axle_table.names)
    )
    sim.reset(state)  # at rest, in line, no drive: only gravity accelerates it
    masses = [unit.mass for unit in setup.params.units]
    heading, gravity = state.psi1, [sim.unit_gravity(0, state.psi1)[0]]
    for k, angle in enumerate(state.articulations, start=1):
        heading -= angle
        gravity.append(sim.unit_gravity(k, heading)[0])
    units = combination_grade_feedforward(masses, gravity, state.articulations)
    u_dot = float(np.asarray(sim.model.rhs(sim.state_vector, sim.input_vector)).ravel()[3])
    assert -sum(masses) * u_dot == pytest.approx(units, rel=1e-9)
    tractor = grade_feedforward(sum(masses), sim.tractor_gravity()[0])
    driven = setup.params.axle_table.driven
    limit = traction_limit(0.2, float(setup.params.axle_table.static_load[driven].sum()))
    assert abs(units - tractor) > limit  # the trailer's tri-axle is on a climb the tractor is not


@pytest.mark.slow
def test_the_unsteered_lst_falls_behind_on_the_wet_clay_yard_with_the_tractors_slope_alone(
    tmp_path: Path,
) -> None:
    # docs/terrain.md, "The unsteered LST on the rough wet-clay yard", seed 1, 30 s, ideal signals. With each body's
    # gravity from its axles (`terrain.body_slope: axles`) the feed-forward on the tractor's slope alone brakes the
    # combination into a stall on the circle's first climb (measured 27.6 m, rolling back at 1.2 m/s) where each
    # unit's own slope drives on (53.3 m, least speed 0.97 m/s). With the default `supports` (the trailer's kingpin
    # share pushed on the tractor's plane) the tractor's slope is nearer the combination's load: no stall, but it
    # still falls behind (measured 42.7 m, least 0.64 m/s, against 56.3 m and 1.01 m/s).
    reached = {}
    for form, feedforward in (("axles", "tractor"), ("axles", "units"), ("supports", "tractor"), ("supports", "units")):
        spec = off_highway_case("gravel-yard", "wet_clay", "rough", "ideal", "none", True, seed=1)
        extra = (("speed.grade_feedforward", feedforward), ("duration_s", 30.0), ("terrain.body_slope", form))
        spec = type(spec)(spec.study, spec.scenario, (*spec.overrides, *extra), spec.labels)
        row = run_off_highway_case(spec, tmp_path / form / feedforward)
        assert row["status"] == "completed"
        series = pd.read_parquet(tmp_path / form / feedforward / spec.name / "timeseries.parquet")
        reached[form, feedforward] = (float(series["path_progress"].max()), float(series["u"].min()))
    assert reached["axles", "tractor"][0] < 30.0 and reached["axles", "tractor"][1] < 0.0  # stalled, rolled back
    assert reached["axles", "units"][0] > 45.0 and reached["axles", "units"][1] > 0.5
    assert reached["supports", "tractor"][0] < 0.85 * reached["supports", "units"][0]
    assert reached["supports", "tractor"][1] < 0.8 < 0.9 < reached["supports", "units"][1]
