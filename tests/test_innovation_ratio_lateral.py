"""``innovation_ratio_from``: ``ρ`` of eq (5) (:mod:`sensor.fusion_std`) from the lateral innovation given the rest.

* :func:`~sensor.fusion_std.lateral_nis` against closed forms: a diagonal ``S`` gives ``ν_y²/S_yy``; a correlated
  3×3 case worked by hand gives 8/3; it equals ``(S⁻¹ν)_y² / (S⁻¹)_yy`` (the Schur complement's other form) and does
  not change with the units of the other two components; over Gaussian draws its mean is 1 (χ²₁).
* In the filter the option moves ``ρ`` alone: the estimate, the state and its covariance are those of the default
  to the bit, the ``increments`` and ``biases`` terms scale with ``ρ`` and the other terms do not move; ``ρ/3`` is
  the floored mean of the accepted motions' lateral NIS (each capped at a third of the gate) over the window.
  Unset or ``"all"``, the filter is the default's bit for bit.

A value outside the allowed ones is refused as ``tests/test_innovation_ratio_rear.py`` checks for all three.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import sensor.fusion as fusion
from sensor.fusion import MIN_INNOVATION_RATIO, STD_PARTS, FusedVisoOt, FusionNoise
from sensor.fusion_std import lateral_nis
from tests.test_fusion import CAMERA, EVERY, PARAMS, drive_with_truth, run


def test_lateral_nis_closed_forms() -> None:
    s = np.diag([0.3, 4.0, 7.0])
    assert lateral_nis(np.array([5.0, 2.0, -3.0]), s) == pytest.approx(1.0, rel=1e-12)  # 2² / 4
    # by hand: S_rr⁻¹·S_ry = (2/4, 1/2), ν_y|r = 2 − (0.5·1 − 0.5·1) = 2, S_y|r = 3 − (2·0.5 + 1·0.5) = 1.5
    s = np.array([[4.0, 2.0, 0.0], [2.0, 3.0, 1.0], [0.0, 1.0, 2.0]])
    nu = np.array([1.0, 2.0, -1.0])
    assert lateral_nis(nu, s) == pytest.approx(8.0 / 3.0, rel=1e-12)
    rng = np.random.default_rng(3)
    for _ in range(20):
        a = rng.normal(size=(3, 3))
        s = a @ a.T + 0.1 * np.eye(3)
        nu = rng.normal(size=3)
        inverse = np.linalg.inv(s)
        expected = (inverse @ nu)[1] ** 2 / inverse[1, 1]
        assert lateral_nis(nu, s) == pytest.approx(expected, rel=1e-9)
        d = np.diag([rng.uniform(0.01, 100.0), 1.0, rng.uniform(0.01, 100.0)])  # the other two's units
        assert lateral_nis(d @ nu, d @ s @ d) == pytest.approx(expected, rel=1e-9)
        assert lateral_nis(nu, s) <= float(nu @ inverse @ nu) * (1.0 + 1e-12)  # a part of the 3-D NIS


def test_lateral_nis_is_chi2_one() -> None:
    rng = np.random.default_rng(7)
    a = np.array([[2.0, 0.0, 0.0], [1.5, 0.4, 0.0], [0.3, 0.9, 0.2]])
    s = a @ a.T
    draws = rng.normal(size=(20000, 3)) @ a.T
    mean = np.mean([lateral_nis(nu, s) for nu in draws])
    assert mean == pytest.approx(1.0, abs=0.05)  # χ²₁: the mean of 20000 has a std of 0.01


@pytest.fixture(scope="module")
def filters() -> dict[str, tuple[FusedVisoOt, np.ndarray, np.ndarray, list[float]]]:
    r_m, w_m, incs, _ = drive_with_truth(n=600, slip=0.0)  # 12 s: a straight, then the turn's entry
    # the odometry's error: white, 4 mm and 0.1 mrad a frame, against a covariance of 2 mm and 0.1 mrad (before
    # the filter's scale): every motion taken, and the two ratios apart and above the floor
    errors = np.random.default_rng(11).normal(size=(len(incs) // EVERY + 1, 3)) * (4e-3, 4e-3, 1e-4)
    covariance = np.diag([1e-8, 1e-8, 1e-8, 4e-6, 4e-6, 4e-6])
    taken: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]] = []
    update = fusion.gated_update

    def recorded(x, p, h, innovation, r, gate, refuse):
        out = update(x, p, h, innovation, r, gate, refuse)
        taken.append((h, p, innovation, r, out[3]))
        return out

    out = {}
    for name, noise in (
        ("default", FusionNoise()),
        ("all", FusionNoise(innovation_ratio_from="all")),
        ("lateral", FusionNoise(innovation_ratio_from="lateral")),
    ):
        taken.clear()
        fusion.gated_update = recorded
        try:
            fused = FusedVisoOt(PARAMS, CAMERA, noise)
            est, std, _ = run(fused, r_m, w_m, incs, frame_error=errors, covariance=covariance)
        finally:
            fusion.gated_update = update
        lateral = [lateral_nis(nu, h @ p @ h.T + r) for h, p, nu, r, used in taken if used]
        out[name] = (fused, np.asarray(est, dtype=float), np.asarray(std, dtype=float), lateral)
    return out


def test_the_default_is_all_to_the_bit(filters) -> None:
    default, same = filters["default"], filters["all"]
    assert np.isfinite(default[1]).sum() > 50  # estimates were made
    assert np.array_equal(default[1], same[1], equal_nan=True)
    assert np.array_equal(default[2], same[2], equal_nan=True)
    assert default[0].innovation_ratio == same[0].innovation_ratio
    assert default[0].std_parts == same[0].std_parts


def test_lateral_moves_rho_alone(filters) -> None:
    default, lateral = filters["default"], filters["lateral"]
    assert np.array_equal(default[1], lateral[1], equal_nan=True)  # the estimate does not move
    assert np.array_equal(default[0].state, lateral[0].state)
    assert np.array_equal(default[0].covariance, lateral[0].covariance)
    window = lateral[3][-FusionNoise().innovation_window :]
    assert len(window) == FusionNoise().innovation_window  # the window is full
    gate = FusionNoise().gate
    expected = max(MIN_INNOVATION_RATIO, float(np.mean([min(3.0 * v, gate) for v in window])) / 3.0)
    assert lateral[0].innovation_ratio == pytest.approx(expected, rel=1e-12)
    assert lateral[0].rejected == 0 and min(lateral[0].innovation_ratio, default[0].innovation_ratio) > 0.3
    assert not math.isclose(lateral[0].innovation_ratio, default[0].innovation_ratio, rel_tol=0.05)
    ratio = lateral[0].innovation_ratio / default[0].innovation_ratio
    parts, moved = default[0].std_parts, lateral[0].std_parts
    for part in STD_PARTS:
        if part in ("increments", "biases"):
            assert parts[part] > 0.0
            assert moved[part] == pytest.approx(ratio * parts[part], rel=1e-12), part
        else:
            assert moved[part] == parts[part], part
