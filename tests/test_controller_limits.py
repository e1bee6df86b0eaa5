"""The trailer steering at its limits: the share of the path beyond the steering's reach in a run's metrics."""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.run.metrics import steering_reach


def test_steering_reach_is_the_share_of_the_distance_driven_after_warm_up():
    # 11 ticks along x; the kingpin drives 1 m a tick for the first five steps, 3 m a tick after; warm-up: tick 0.
    x = np.concatenate([np.arange(6.0), 5.0 + 3.0 * np.arange(1, 6)])
    flag = np.zeros(11)
    flag[7:9] = 1.0  # two ticks of 3 m each beyond reach
    settled = np.arange(11) >= 1
    reach = steering_reach({"kingpin_x": x, "kingpin_y": np.zeros(11), "trailer_beyond_reach": flag}, settled)
    assert reach == {"share_of_path": pytest.approx(6.0 / 20.0, abs=1e-12), "distance_m": pytest.approx(6.0)}
    # An unsteered run has no such column: no field.
    assert steering_reach({"kingpin_x": x, "kingpin_y": np.zeros(11)}, settled) is None
