"""The environments' constructors: a config mapping over ``default_config()`` (or a ScenarioChoice), the old keyword
names still accepted (as ``gymnasium.make`` passes them), unknown keys refused naming the allowed ones."""

from __future__ import annotations

import inspect

import gymnasium as gym
import numpy as np
import pytest

import scenarios.envs  # noqa: F401  (registers the environments)
from scenarios.envs.env_config import SCENARIO_KEYS
from scenarios.envs.gain_tuning_env import GainTuningEnv
from scenarios.envs.scenario import DEFAULT_OVERRIDES, ScenarioChoice
from scenarios.envs.steering_env import PREVIEW_DISTANCES, TrailerSteeringEnv
from vehicle_model.errors import InputError

ENVS = (TrailerSteeringEnv, GainTuningEnv)


@pytest.mark.parametrize("env_class", ENVS)
def test_the_constructor_takes_at_most_five_parameters(env_class: type) -> None:
    parameters = inspect.signature(env_class.__init__).parameters
    assert len(parameters) <= 5
    assert list(parameters)[:3] == ["self", "config", "render_mode"]


@pytest.mark.parametrize("env_class", ENVS)
def test_default_config_holds_every_scenario_key_and_is_a_fresh_copy(env_class: type) -> None:
    defaults = env_class.default_config()
    assert set(SCENARIO_KEYS) <= set(defaults)
    defaults["feedback"] = "zero_slip"
    assert env_class.default_config()["feedback"] == "truth"


def test_the_config_is_the_defaults_updated_by_the_mapping_then_the_keywords() -> None:
    env = TrailerSteeringEnv({"feedback": "zero_slip", "action_mode": "residual"}, action_mode="direct")
    assert env.config == {
        **TrailerSteeringEnv.default_config(),
        "feedback": "zero_slip",
        "action_mode": "direct",
    }
    assert env.choice.feedback == "zero_slip" and env.action_mode == "direct"
    assert env.choice.overrides == DEFAULT_OVERRIDES  # None in the config: the default quarter turn


def test_a_mapping_a_choice_and_keywords_make_the_same_environment() -> None:
    settings = {"feedback": "zero_slip", "mu": 0.4, "overrides": {"path.turns": 0.1}}
    by_keywords = gym.make("offtrack/TrailerSteering-v0", **settings).unwrapped
    by_config = gym.make("offtrack/TrailerSteering-v0", config=settings).unwrapped
    by_choice = TrailerSteeringEnv(ScenarioChoice(**settings))
    assert by_keywords.choice == by_config.choice == by_choice.choice
    first = [env.reset(seed=3)[0] for env in (by_keywords, by_config, by_choice)]
    assert all(np.array_equal(first[0], obs) for obs in first[1:])


def test_the_gain_tuning_environment_takes_the_same_forms() -> None:
    env = GainTuningEnv({"effort_weight": 0.2}, randomise={"mu": (0.2, 0.8)})
    assert env.effort_weight == 0.2 and env.choice.randomise.mu == (0.2, 0.8)
    assert env.config["failure_cost"] == 5.0


@pytest.mark.parametrize("env_id", ["offtrack/TrailerSteering-v0", "offtrack/GainTuning-v0"])
def test_an_unknown_keyword_is_one_error_naming_it_and_the_allowed_keys(env_id: str) -> None:
    with pytest.raises(InputError) as caught:
        gym.make(env_id, feedbak="zero_slip")
    message = str(caught.value)
    assert "'feedbak'" in message and "allowed keys: scenario, overrides, feedback" in message
    assert "\n" not in message


def test_an_unknown_config_key_and_a_config_that_is_no_mapping_are_refused() -> None:
    with pytest.raises(InputError, match="TrailerSteeringEnv config: unknown 'speed'; allowed keys"):
        TrailerSteeringEnv({"speed": 3.0})
    with pytest.raises(InputError, match="must be a mapping of settings or a ScenarioChoice"):
        TrailerSteeringEnv("roundabout-3")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="unknown 'residual_scale_deg'"):
        GainTuningEnv(residual_scale_deg=2.0)  # a setting of the other environment


def test_settings_are_still_validated_after_the_merge() -> None:
    with pytest.raises(InputError, match="action_mode = 'sideways'"):
        TrailerSteeringEnv({"action_mode": "sideways"})
    env = TrailerSteeringEnv({"preview_distances": (0.0, 5.0)})
    assert env.observation_names[-2:] == ("curvature_ahead_0m", "curvature_ahead_5m")
    assert TrailerSteeringEnv().preview_distances.tolist() == list(PREVIEW_DISTANCES)
