"""Whether the coupled translation holds while the tyres scrub, from the frames (``fusion.scrub_coupling_evidence``).

(S1)–(S3) of :mod:`sensor.fusion_scrub_signal`. The filter of tests/test_fusion_limits.py drives straight, every fifth
tick a camera frame whose odometry turns 1 mrad/m more than the unit, with (``coupled``) or without eq (3)'s coupled
translation of that yaw error; the scrub demand injected, full from half-way. Where the frames carry the coupled
translation the evidence keeps it (the estimate the kept setting's), where they do not it releases it (the
default's) — a constant weight could do only one of the two.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensor.camera import StereoRig
from sensor.fusion import FusedVisoOt, FusionNoise
from sensor.fusion_scrub_signal import CouplingEvidence
from sensor.fusion_slip import scrub_coupling_yield
from vehicle_model.presets import VEHICLE_PRESETS

DT, SPEED, TICKS, SWITCH = 0.02, 4.2, 600, 300
RUN = {"scrub_slip_angle": 0.04, "scrub_bias_release": 0.7}
"""The scrub settings of a run's configuration."""
LATE = slice(340, None)  # from about a second of frames after the demand went full


@pytest.fixture(scope="module")
def lst():
    return VEHICLE_PRESETS["lst"]()


def _camera_motion(increment: np.ndarray, camera_in_trailer: np.ndarray) -> np.ndarray:
    """The camera's motion ``T_prev←curr`` for a kingpin increment ``(dx, dy, dψ)`` (inverse of eqs (1)–(2))."""
    t = np.eye(4)
    c, s = math.cos(increment[2]), math.sin(increment[2])
    t[:2, :2] = [[c, -s], [s, c]]
    t[:2, 3] = increment[:2]
    return np.linalg.inv(camera_in_trailer) @ t @ camera_in_trailer


def _run(params, noise: FusionNoise, coupled: bool) -> tuple[np.ndarray, list[float]]:
    """The estimate per tick (the true off-tracking is 0) and the evidence's weight after each frame."""
    camera = StereoRig.from_degrees(psi_c2v_deg=180.0).camera_in_trailer("left", params)
    fused = FusedVisoOt(params, camera, noise)
    demand = [0.0]
    fused._scrub = lambda *signals: demand[0]  # the demand of (K5), injected
    covariance = np.eye(6) * 1e-8
    covariance[1, 1] = covariance[3, 3] = 1e-6
    covariance[1, 3] = covariance[3, 1] = 0.9e-6
    step = 5 * DT * SPEED
    _, r = fused.measurement(_camera_motion(np.array([step, 0.0, 0.0]), camera), covariance)
    kappa = noise.vo_bias_coupling * r[:2, 2] / r[2, 2] if coupled else np.zeros(2)  # κ·(c_x, c_y) of eq (3)
    error = 1e-3 * step  # [rad] a frame
    motion = _camera_motion(np.array([step + kappa[0] * error, kappa[1] * error, error]), camera)
    out, weights = [], []
    for k in range(TICKS):
        demand[0] = 1.0 if k >= SWITCH else 0.0
        fused.propagate(k, DT, 0.0, SPEED, np.zeros(fused.steer_weights.size))
        if k and k % 5 == 0:
            fused.measure(k, motion, covariance)
            weights.append(fused._signal.weight)
        out.append(math.nan if fused.estimate is None else fused.estimate)
    return np.array(out), weights


def test_off_the_factor_is_the_settings_yield_and_nothing_is_weighed() -> None:
    for kept in (False, True):
        noise = FusionNoise(**RUN, scrub_coupling_kept=kept)
        evidence = CouplingEvidence(noise)
        for demand in np.linspace(0.0, 1.0, 11):
            assert evidence.factor(float(demand)) == scrub_coupling_yield(noise, float(demand))
        evidence.weigh(np.ones(7), np.eye(7), np.ones((3, 7)), np.ones(3), np.eye(3))
        assert evidence.weight == 0.5 and evidence.log_ratio == 0.0
    assert FusionNoise().scrub_coupling_evidence is False


def test_the_switch_is_bounded() -> None:
    with pytest.raises(ValueError, match="scrub_coupling_switch"):
        FusionNoise(scrub_coupling_switch=0.0)
    with pytest.raises(ValueError, match="scrub_coupling_switch"):
        FusionNoise(scrub_coupling_switch=0.6)


@pytest.mark.parametrize("coupled", [True, False])
def test_the_evidence_keeps_the_coupling_where_the_frames_carry_it(lst, coupled: bool) -> None:
    default, _ = _run(lst, FusionNoise(**RUN), coupled)
    kept, _ = _run(lst, FusionNoise(**RUN, scrub_coupling_kept=True), coupled)
    evidence, weights = _run(lst, FusionNoise(**RUN, scrub_coupling_evidence=True), coupled)
    # before the demand the three are one filter, to the bit
    assert np.array_equal(evidence[:SWITCH], default[:SWITCH], equal_nan=True)
    gap = np.max(np.abs(kept[LATE] - default[LATE]))
    assert gap > 0.02  # [m]: the two settings part under the demand
    right, wrong = (kept, default) if coupled else (default, kept)
    # within 0.25 of the settings' gap of the right one on every late tick, and nearer it than the wrong one
    assert np.max(np.abs(evidence[LATE] - right[LATE])) <= 0.25 * gap
    assert np.mean(np.abs(evidence[LATE] - right[LATE])) < np.mean(np.abs(evidence[LATE] - wrong[LATE]))
    assert (weights[-1] > 0.9) if coupled else (weights[-1] < 0.1)
