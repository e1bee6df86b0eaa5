"""On-board signals: rate, bias, noise and seeding."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensor.signals import CHANNELS, ChannelSpec, OnboardSignals, standstill_reading


def truth(value: float) -> dict:
    return {c: value for c in CHANNELS} | {"trailer_steer": np.array([value, -value])}


def run(specs, seed, n=2000, dt=0.01):
    sensors = OnboardSignals(specs, np.random.default_rng(seed))
    return np.array([sensors.measure(k * dt, truth(float(k)))["tractor_yaw_rate"][0] for k in range(n)])


def test_ideal_channels_pass_the_truth():
    sensors = OnboardSignals({}, np.random.default_rng(0))
    out = sensors.measure(0.0, truth(0.3))
    assert all(out[c][0] == 0.3 for c in CHANNELS)
    assert out["trailer_steer"] == pytest.approx([0.3, -0.3])


def test_rate_holds_between_samples():
    values = run({"tractor_yaw_rate": ChannelSpec(rate_hz=10.0)}, 0, n=50, dt=0.01)
    # sampled every 0.1 s = 10 control ticks: k = 0, 10, 20, …
    assert values[:10] == pytest.approx(np.zeros(10))
    assert values[10:20] == pytest.approx(np.full(10, 10.0))
    assert len(np.unique(values)) == 5


def test_bias_and_noise_statistics():
    spec = ChannelSpec(noise_std=0.02, bias=0.005, rate_hz=100.0)
    sensors = OnboardSignals({"articulation": spec}, np.random.default_rng(3))
    err = np.array([sensors.measure(k * 0.01, truth(1.0))["articulation"][0] - 1.0 for k in range(20000)])
    assert err.mean() == pytest.approx(0.005, abs=4 * 0.02 / np.sqrt(20000))
    assert err.std() == pytest.approx(0.02, rel=0.03)


def test_same_seed_same_numbers_and_different_seed_differs():
    spec = {"tractor_yaw_rate": ChannelSpec(noise_std=0.1)}
    assert np.array_equal(run(spec, 42), run(spec, 42))
    assert not np.array_equal(run(spec, 42), run(spec, 43))


def test_bad_specs():
    with pytest.raises(ValueError, match="noise_std"):
        ChannelSpec(noise_std=-1.0)
    with pytest.raises(ValueError, match="unknown signal channels"):
        OnboardSignals({"gps": ChannelSpec()}, np.random.default_rng(0))


def test_a_standstill_reading_is_the_offset_within_the_noise_of_its_mean() -> None:
    spec = ChannelSpec(noise_std=1.2e-3, bias=1e-3, rate_hz=50.0)
    means = [standstill_reading(spec, 10.0, np.random.default_rng(seed)) for seed in range(200)]
    assert {n for _, n in means} == {500}  # 10 s at 50 Hz
    errors = np.array([m for m, _ in means]) - spec.bias
    assert abs(np.mean(errors)) < 3 * 1.2e-3 / math.sqrt(500 * 200)  # unbiased
    assert np.std(errors) == pytest.approx(1.2e-3 / math.sqrt(500), rel=0.15)  # σ/√n
    assert standstill_reading(ChannelSpec(bias=2e-3), 1.0, np.random.default_rng(0)) == (2e-3, 50)  # no noise: exact
    value, n = standstill_reading(spec, 0.0, np.random.default_rng(0))
    assert n == 0 and math.isnan(value)
