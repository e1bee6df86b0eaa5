"""The odometry's coupled translation kept while the tyres scrub (``fusion.scrub_coupling_kept``).

(K5) of :mod:`sensor.fusion_slip` takes a frame's coupled translation (eq (3) of :mod:`sensor.fusion_model`) with
``1 − D`` at the scrub demand ``D``; kept, only (K6)'s ``1 − r·D`` acts on the coupled correction. The filter of
tests/test_fusion_limits.py drives straight with camera frames that carry a 1 mrad/m odometry yaw error and its coupled
translation, the demand injected: full from half-way.
"""

from __future__ import annotations

import numpy as np
import pytest

from sensor.fusion import FusionNoise
from sensor.fusion_slip import scrub_coupling_applied, scrub_coupling_yield
from tests.test_fusion_limits import _with_coupled_yaw_error
from vehicle_model.presets import VEHICLE_PRESETS

RUN = {"scrub_slip_angle": 0.04, "scrub_bias_release": 0.7}
"""The scrub settings of a run's configuration."""


@pytest.fixture(scope="module")
def lst():
    return VEHICLE_PRESETS["lst"]()


def test_the_coupling_yields_to_the_demand_unless_kept() -> None:
    default, kept = FusionNoise(**RUN), FusionNoise(**RUN, scrub_coupling_kept=True)
    assert FusionNoise().scrub_coupling_kept is False
    for demand in np.linspace(0.0, 1.0, 11):
        d = float(demand)
        assert scrub_coupling_yield(default, d) == 1.0 - d and scrub_coupling_yield(kept, d) == 1.0
        # the share applied: (1 − r·D)·(1 − D) as before, (1 − r·D) kept
        assert scrub_coupling_applied(default, d) == (1.0 - 0.7 * d) * (1.0 - d)
        assert scrub_coupling_applied(kept, d) == pytest.approx(1.0 - 0.7 * d, abs=1e-15)


def test_kept_the_scrub_leaves_out_only_the_released_share(lst) -> None:
    # Without a release, the kept coupling makes a full demand change nothing in the estimate (to the bit); with the
    # run's release r = 0.7 the estimate's departure from the rolling filter's is 0.7 of the default's at most.
    no_release = FusionNoise(scrub_slip_angle=0.04, scrub_coupling_kept=True)
    rolling = _with_coupled_yaw_error(lst, no_release, switch=10**9)
    scrubbing = _with_coupled_yaw_error(lst, no_release, switch=300)
    assert np.array_equal(scrubbing[:, 0], rolling[:, 0], equal_nan=True)
    late = slice(320, None)
    rolling = _with_coupled_yaw_error(lst, FusionNoise(**RUN), switch=10**9)
    default = _with_coupled_yaw_error(lst, FusionNoise(**RUN), switch=300)[late, 0] - rolling[late, 0]
    kept = _with_coupled_yaw_error(lst, FusionNoise(**RUN, scrub_coupling_kept=True), switch=300)[late, 0]
    kept = kept - rolling[late, 0]
    assert np.max(np.abs(default)) > 0.04  # [m]: the default leaves the coupled correction out
    assert np.max(np.abs(kept)) <= 0.75 * np.max(np.abs(default))
    assert np.max(np.abs(kept)) > 0.0  # (K6) still releases its share
