"""``controller.uncertain_feedback = "taper"``: the estimate weighted by ``(σ_max/σ)²`` above the limit, so the command
is continuous in the std across the limit (no two outcomes on a rounding of the std)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from uncertain_feedback_setup import DT, GAINS, MAX_STD, state

from controller.path_following import TrailerSteeringController
from controller.path_following_config import PathFollowingConfig
from scenarios.config import ConfigError, load_scenario
from scenarios.loop.trailer_steer import trailer_steer_for
from scenarios.setup.build import build_scenario
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.presets import lst_laden


@pytest.fixture(scope="module")
def params():
    return lst_laden()


def hovering(nudge: float) -> list[OfftrackingEstimate]:
    """A held 10 Hz camera-like sequence at 50 Hz whose std sits on the limit, nudged by ``nudge`` [m]: above it by
    a rounding with ``nudge > 0``, at it with ``nudge = 0``."""
    out = []
    for k in range(150):
        value = -0.2 - 0.3 * (k // 5) / 30  # an outswing growing to -0.5 m, as in a turn on feed-forward alone
        std = MAX_STD if k % 10 < 5 else MAX_STD - 0.01  # on the limit half of the time
        out.append(OfftrackingEstimate.of(value, std + nudge if std == MAX_STD else std))
    return out


def steer(params, config: PathFollowingConfig, sequence) -> np.ndarray:
    ctrl = TrailerSteeringController(params, config)
    return np.array([ctrl(state(k * DT), estimate) for k, estimate in enumerate(sequence)])


def test_taper_is_continuous_across_the_limit_where_drop_and_shrink_step(params) -> None:
    nudge = 1e-12  # a rounding of the std: the estimates of two runs that differ in their last bits
    on, above = hovering(0.0), hovering(nudge)
    taper = PathFollowingConfig(gains=GAINS, uncertain_feedback="taper")
    gap = np.max(np.abs(steer(params, taper, on) - steer(params, taper, above)))
    assert gap < 1e-9  # rad: the command moves by the rounding's order (w = 1 - 2e-12/0.075 above the limit)
    for rule in ("drop", "shrink"):  # the test's teeth: the stepped rules move the command by far more
        config = PathFollowingConfig(gains=GAINS, uncertain_feedback=rule)
        assert np.max(np.abs(steer(params, config, on) - steer(params, config, above))) > 1e-3


@pytest.mark.parametrize("std", [0.076, 0.1, 0.3])
def test_taper_applies_the_inverse_variance_weight_and_integrates_the_weighted_error(params, std: float) -> None:
    ctrl = TrailerSteeringController(params, PathFollowingConfig(gains=GAINS, uncertain_feedback="taper"))
    ctrl(state(0.0), OfftrackingEstimate.of(0.01, 0.05))  # certain: w = 1
    assert ctrl.feedback_weight == 1.0 and ctrl.estimate == 0.01
    weight = MAX_STD**2 / std**2
    for k in range(1, 40):  # a held uncertain estimate, past the output's rate limit settling
        ctrl(state(k * DT), OfftrackingEstimate.of(0.01, std))
        assert ctrl.feedback_weight == pytest.approx(weight, abs=1e-12)
        assert ctrl.estimate == pytest.approx(weight * 0.01, abs=1e-12)
    integral, distance = ctrl.integral, ctrl.distance
    ctrl(state(40 * DT), OfftrackingEstimate.of(0.01, std))
    # not frozen (shrink freezes it): the integral advances by the weighted error over the distance travelled
    assert ctrl.integral - integral == pytest.approx(weight * 0.01 * (ctrl.distance - distance), rel=1e-9)
    assert ctrl.integral > integral
    ctrl(state(41 * DT), OfftrackingEstimate.of(math.nan, 0.05))  # a missing value is dropped, as in the others
    assert ctrl.estimate is None and ctrl.feedback_steer == 0.0


def test_taper_reaches_the_controller_and_a_bad_value_names_the_field(params) -> None:
    setup = build_scenario(
        load_scenario("roundabout-3", {"vehicle": "lst", "feedback": "truth", "controller.uncertain_feedback": "taper"})
    )
    assert trailer_steer_for(setup).controller.config.uncertain_feedback == "taper"
    with pytest.raises(ConfigError) as info:
        load_scenario("roundabout-3", {"controller.uncertain_feedback": "tapered"})
    assert "taper" in str(info.value)  # the allowed values are named
