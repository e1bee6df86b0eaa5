"""Configuration of the fused VISO-OT loop: the controller's std fallback and the filter's bias term."""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.config import ConfigError, FusionConfig, load_scenario
from scenarios.loop.estimators import fused_viso_ot
from scenarios.loop.participant import LoopContext
from scenarios.loop.trailer_steer import trailer_steer_for
from scenarios.setup.build import build_scenario
from sensor.fusion import FusionNoise


@pytest.mark.parametrize(
    ("assignment", "field"),
    [
        ({"controller.feedback_max_std_m": 0.0}, "controller.feedback_max_std_m"),
        ({"controller.feedback_max_std_m": 1.5}, "controller.feedback_max_std_m"),
        ({"fusion.offtracking_bias_std": -0.01}, "fusion.offtracking_bias_std"),
        ({"fusion.offtracking_bias_std": 0.6}, "fusion.offtracking_bias_std"),
    ],
)
def test_out_of_range_values_are_refused_in_one_line_naming_the_field(assignment: dict, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        load_scenario("roundabout-3", assignment)
    lines = [line for line in str(info.value).splitlines() if field in line]
    assert len(lines) == 1 and "[m]" in lines[0]  # the field, its value and its range with the unit


def test_the_bias_term_reaches_the_filter() -> None:
    class Camera:  # only the pose is read
        camera_in_trailer = np.eye(4)

    def fused(setup):
        context = LoopContext(setup, None, 0.02, estimators={"viso_ot": Camera()})  # type: ignore[arg-type]
        return fused_viso_ot(context).filter

    setup = build_scenario(load_scenario("roundabout-3", {"vehicle": "lst", "fusion.offtracking_bias_std": 0.04}))
    assert fused(setup).noise.offtracking_bias_std == 0.04
    default = build_scenario(load_scenario("roundabout-3", {"vehicle": "lst"}))
    # the run's own default (the schema's), not the bare filter's
    assert fused(default).noise.offtracking_bias_std == FusionConfig().offtracking_bias_std
    assert FusionConfig().offtracking_bias_std != FusionNoise().offtracking_bias_std


def test_the_std_fallback_threshold_reaches_the_controller() -> None:
    setup = build_scenario(
        load_scenario("roundabout-3", {"vehicle": "lst", "feedback": "truth", "controller.feedback_max_std_m": 0.08})
    )
    assert trailer_steer_for(setup).controller.config.feedback_max_std == 0.08
    default = build_scenario(load_scenario("roundabout-3", {"vehicle": "lst", "feedback": "truth"}))
    assert trailer_steer_for(default).controller.config.feedback_max_std == 0.075


def test_a_config_with_the_removed_frame_drop_is_refused_like_any_unknown_field() -> None:
    with pytest.raises(ConfigError, match=r"fusion\.drop_every = 2: not a field of the configuration"):
        load_scenario("roundabout-3", {"fusion.drop_every": 2})
