"""The chain stability steer's schedules kept on disk (controller.high_speed_chain, vehicle_model.disk_cache): read
back to the bit, not designed again, designed again for a damaged, foreign or stale entry, and uncached without a
home folder.

The design itself is replaced by a recorder returning a known schedule (its own tests are in
``test_high_speed_chain.py``): these tests are about what the cache keeps and when it designs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller import high_speed_chain
from controller.high_speed import StabilityWeights, design_speeds
from controller.high_speed_chain import ChainStabilitySteer, schedule_key
from vehicle_model.disk_cache import exact_text, read_entry, write_entry
from vehicle_model.presets import VEHICLE_PRESETS

CROSSOVER_START = 35.0 / 3.6


@pytest.fixture(scope="module")
def b_double():
    return VEHICLE_PRESETS["au-b-double-steered"]()


@pytest.fixture
def designs(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> list[float]:
    """An empty cache in ``tmp_path`` and a design that records each call and returns a known schedule whose gains
    are not exact in decimal (a text round trip would change them)."""
    monkeypatch.setenv("OFFTRACK_CACHE_DIR", str(tmp_path))
    calls: list[float] = []

    def recorded(params, crossover_start, weights):
        calls.append(crossover_start)
        speeds = design_speeds(crossover_start)
        n = len(speeds) * 2 * 5
        return speeds, (np.arange(n, dtype=float) / 3.0 - np.pi).reshape(len(speeds), 2, 5)

    monkeypatch.setattr(high_speed_chain, "_designed_schedule", recorded)
    high_speed_chain._scheduled_gains.cache_clear()
    yield calls
    high_speed_chain._scheduled_gains.cache_clear()  # no recorded schedule left for the other tests


def _again(params) -> ChainStabilitySteer:
    """A new process's steer: the in-process memo cleared, the disk kept."""
    high_speed_chain._scheduled_gains.cache_clear()
    return ChainStabilitySteer(params, CROSSOVER_START)


def _entry(tmp_path: Path) -> Path:
    (entry,) = (tmp_path / "stability").glob("*.npz")
    return entry


def test_a_schedule_is_designed_once_and_read_back_to_the_bit(b_double, designs, tmp_path: Path) -> None:
    first = ChainStabilitySteer(b_double, CROSSOVER_START)
    key = schedule_key(b_double, CROSSOVER_START, first.weights)
    assert len(designs) == 1 and _entry(tmp_path).name == f"{key[:32]}.npz"
    second = _again(b_double)
    assert len(designs) == 1  # read, not designed
    np.testing.assert_array_equal(second.gains, first.gains)
    np.testing.assert_array_equal(second.speeds, first.speeds)
    assert second.gains.dtype == np.float64 and not second.gains.flags.writeable


@pytest.mark.parametrize("damage", ["truncated", "another key", "wrong shape", "not finite"])
def test_a_damaged_or_foreign_entry_is_designed_again_and_replaced(b_double, designs, tmp_path: Path, damage) -> None:
    first = ChainStabilitySteer(b_double, CROSSOVER_START)
    entry = _entry(tmp_path)
    key = schedule_key(b_double, CROSSOVER_START, first.weights)
    if damage == "truncated":
        entry.write_bytes(entry.read_bytes()[: entry.stat().st_size // 2])
    elif damage == "another key":
        write_entry(entry, "0" * 64, {"speeds": first.speeds, "gains": first.gains + 1.0})
    elif damage == "wrong shape":
        write_entry(entry, key, {"speeds": first.speeds, "gains": first.gains[:, :1]})
    else:
        write_entry(entry, key, {"speeds": first.speeds, "gains": np.full_like(first.gains, np.nan)})
    again = _again(b_double)
    assert len(designs) == 2
    np.testing.assert_array_equal(again.gains, first.gains)
    stored = read_entry(entry, key, ("gains",))
    assert stored is not None
    np.testing.assert_array_equal(stored["gains"], first.gains)  # the entry replaced by a whole one


def test_the_key_follows_every_input_and_the_sources(b_double, monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    weights = StabilityWeights()
    key = schedule_key(b_double, CROSSOVER_START, weights)
    assert schedule_key(VEHICLE_PRESETS["au-b-double-steered"](), CROSSOVER_START, StabilityWeights()) == key
    assert schedule_key(b_double, np.nextafter(CROSSOVER_START, 20.0), weights) != key  # one ulp of the crossover
    assert schedule_key(VEHICLE_PRESETS["au-a-double-steered"](), CROSSOVER_START, weights) != key
    assert schedule_key(b_double, CROSSOVER_START, StabilityWeights(actuator_lag=0.05)) != key
    edited = tmp_path / high_speed_chain.DESIGN_SOURCES[0].name
    edited.write_bytes(high_speed_chain.DESIGN_SOURCES[0].read_bytes() + b"\n# edited\n")
    monkeypatch.setattr(high_speed_chain, "DESIGN_SOURCES", (edited, *high_speed_chain.DESIGN_SOURCES[1:]))
    assert schedule_key(b_double, CROSSOVER_START, weights) != key


def test_without_a_home_folder_the_schedule_is_designed_and_not_kept(b_double, designs, monkeypatch, tmp_path) -> None:
    monkeypatch.setattr(high_speed_chain, "entry_path", lambda kind, key: None)
    ChainStabilitySteer(b_double, CROSSOVER_START)
    _again(b_double)
    assert len(designs) == 2 and not (tmp_path / "stability").exists()


def test_a_key_has_no_lossy_text() -> None:
    assert exact_text(0.1) == (0.1).hex() and exact_text(np.float64(0.1)) == exact_text(0.1)
    with pytest.raises(TypeError, match="no exact text for a dict"):
        exact_text({"a": 1.0})
