"""An uncertain estimate (std above ``feedback_max_std``): tapered by default, dropped, or shrunk toward zero."""

from __future__ import annotations

import math

import numpy as np
import pytest
from uncertain_feedback_setup import DT, GAINS, MAX_STD, state

from controller.path_following import TrailerSteeringController
from controller.path_following_config import PathFollowingConfig
from scenarios.config import ConfigError, load_scenario
from scenarios.configuration.sections import ControllerConfig
from scenarios.loop.trailer_steer import trailer_steer_for
from scenarios.setup.build import build_scenario
from vehicle_model.errors import InputError
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.presets import lst_laden


@pytest.fixture(scope="module")
def params():
    return lst_laden()


def estimates() -> list[OfftrackingEstimate]:
    """A held 10 Hz camera-like sequence at 50 Hz whose std crosses the limit both ways, with a missing stretch."""
    out = []
    for k in range(120):
        value = 0.12 * math.sin(0.05 * (k // 5))
        std = 0.04 + 0.08 * (0.5 + 0.5 * math.sin(0.07 * k))  # 0.04 .. 0.12 m
        out.append(OfftrackingEstimate.of(None) if 60 <= k < 66 else OfftrackingEstimate.of(value, std))
    return out


def steer(params, config: PathFollowingConfig, sequence) -> tuple[np.ndarray, list[float]]:
    ctrl = TrailerSteeringController(params, config)
    commands, integrals = [], []
    for k, estimate in enumerate(sequence):
        commands.append(ctrl(state(k * DT), estimate))
        integrals.append(ctrl.integral)
    return np.array(commands), integrals


def test_taper_is_the_default_and_drop_steers_as_if_the_uncertain_estimate_were_missing(params) -> None:
    sequence = estimates()
    assert PathFollowingConfig().uncertain_feedback == "taper"
    assert ControllerConfig().uncertain_feedback == "taper"  # the run's setting has the controller's default
    default, _ = steer(params, PathFollowingConfig(gains=GAINS), sequence)
    taper, _ = steer(params, PathFollowingConfig(gains=GAINS, uncertain_feedback="taper"), sequence)
    assert np.array_equal(default, taper)  # bit for bit
    drop, _ = steer(params, PathFollowingConfig(gains=GAINS, uncertain_feedback="drop"), sequence)
    missing = [e if e.std <= MAX_STD else OfftrackingEstimate.of(None) for e in sequence]
    as_missing, _ = steer(params, PathFollowingConfig(gains=GAINS, uncertain_feedback="drop"), missing)
    assert np.array_equal(drop, as_missing)  # bit for bit
    shrink, _ = steer(params, PathFollowingConfig(gains=GAINS, uncertain_feedback="shrink"), sequence)
    assert not np.array_equal(drop, shrink)  # the sequence does exercise the uncertain branch
    assert not np.array_equal(default, drop)


@pytest.mark.parametrize("std", [0.076, 0.1, 0.3])
def test_shrink_applies_the_bayesian_weight(params, std: float) -> None:
    ctrl = TrailerSteeringController(params, PathFollowingConfig(gains=GAINS, uncertain_feedback="shrink"))
    ctrl(state(0.0), OfftrackingEstimate.of(0.2, std))
    weight = MAX_STD**2 / (MAX_STD**2 + std**2)  # posterior mean of N(0.2, σ²)·N(0, σ_max²)
    assert ctrl.feedback_weight == pytest.approx(weight, abs=1e-12)
    assert ctrl.estimate == pytest.approx(weight * 0.2, abs=1e-12)
    # at the limit the estimate is used as given
    ctrl(state(DT), OfftrackingEstimate.of(0.2, MAX_STD))
    assert ctrl.feedback_weight == 1.0 and ctrl.estimate == 0.2


def test_shrink_freezes_the_integrator_above_the_limit_and_drops_a_missing_value(params) -> None:
    config = PathFollowingConfig(gains=GAINS, uncertain_feedback="shrink")
    ctrl = TrailerSteeringController(params, config)
    for k in range(10):
        ctrl(state(k * DT), OfftrackingEstimate.of(0.1, 0.05))
    integral = ctrl.integral
    assert integral > 0  # integrates while certain
    for k in range(10, 30):
        ctrl(state(k * DT), OfftrackingEstimate.of(0.1, 0.2))
        assert ctrl.integral == integral  # frozen while w < 1
        assert ctrl.feedback_steer != 0.0  # but the shrunk error still steers
    ctrl(state(30 * DT), OfftrackingEstimate.of(math.nan, 0.05))
    assert ctrl.estimate is None and ctrl.feedback_steer == 0.0 and ctrl.integral == integral


def test_the_setting_reaches_the_controller_and_a_bad_value_is_refused_in_one_line() -> None:
    with pytest.raises(ConfigError) as info:
        load_scenario("roundabout-3", {"controller.uncertain_feedback": "blend"})
    assert isinstance(info.value, InputError)  # the CLI's exit 2 (README's table)
    lines = [line for line in str(info.value).splitlines() if "controller.uncertain_feedback" in line]
    assert len(lines) == 1
    setup = build_scenario(
        load_scenario(
            "roundabout-3", {"vehicle": "lst", "feedback": "truth", "controller.uncertain_feedback": "shrink"}
        )
    )
    assert trailer_steer_for(setup).controller.config.uncertain_feedback == "shrink"
