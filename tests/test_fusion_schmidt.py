"""The following unit's measurement taken with the Schmidt–Kalman gain of its persisting error
(sensor/fusion_schmidt.py, ``coupling_persisting_error.gain``).

The gain on hand-made moments: the filter's own gain where nothing persists, the least total error covariance among
gains otherwise, and the two parts of the error carried apart so that they sum to the Schmidt–Kalman covariance. The
setting off by default and, off, the filter's reference update the filter's own to the bit. On a straight where the
follower's camera is off across its motion by the same amount in every frame for 10 s: with the gain the lead's
off-tracking stays with its own (exact) camera and its std covers its error; without the persisting error in the
filter at all the lead takes the follower's error and its std does not cover it; with it in the std alone the std
covers it but the error is the same.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from lead_follower_straight import DT, PARAMS, REAR_CAMERA, SIDE, SIDE_RIG, drive_straight
from pydantic import ValidationError

from scenarios.configuration.sections import FusionConfig
from scenarios.loop.following_camera import FollowingCamera
from sensor.fusion import FusedVisoOt, FusionNoise
from sensor.fusion_consider import NoConsider, PersistingReference
from sensor.fusion_coupling import CouplingMeasurement, CouplingReference, coupled_update
from sensor.fusion_model import gated_update
from sensor.fusion_noise import PersistingReferenceError
from sensor.fusion_schmidt import schmidt_update

WRONG = (500, 1000)  # the ticks [10 s, 20 s) the follower's camera is off
REAR_ERROR = 2e-3  # [m] its error across its motion in every frame there (a fifth of its per-frame lateral std)
PERSISTING = {"share": 0.5, "correlation_time_s": 10.0}


def _moments(rng: np.random.Generator, n: int = 6) -> tuple[np.ndarray, ...]:
    """A covariance ``P``, the consider moments ``Π`` and ``c`` (jointly a covariance with ``ν``'s unit variance)."""
    a = rng.normal(size=(n, n))
    p = a @ a.T * 1e-3 + np.eye(n) * 1e-4
    b = rng.normal(size=(n + 1, n + 1))
    joint = b @ b.T * 1e-3
    joint /= joint[n, n]  # ν of unit variance
    return p, joint[:n, :n], joint[:n, n]


def _total(p: np.ndarray, pi: np.ndarray, c: np.ndarray, k: np.ndarray, r: np.ndarray, sigma: float) -> np.ndarray:
    """The error's covariance after the update with the gain ``k``: its white part and its persisting part (P2)."""
    n = len(p)
    a = np.eye(n) - k @ np.hstack([np.eye(3), np.zeros((3, n - 3))])
    m = sigma * k[:, 1]
    return a @ p @ a.T + k @ r @ k.T + a @ pi @ a.T + np.outer(a @ c, m) + np.outer(m, a @ c) + np.outer(m, m)


def test_without_a_persisting_error_the_gain_is_the_filters_own() -> None:
    """``Π`` and ``c`` zero and ``σ_c`` zero: the state and covariance those of the filter's own update (1e-12
    relative), on both sides of the gate; refused beyond it where asked, the state and ``P`` given back."""
    rng = np.random.default_rng(3)
    p, _, _ = _moments(rng)
    x = rng.normal(size=6) * 0.01
    r = np.diag([4e-4, 3e-4, 1e-6])
    h = np.hstack([np.eye(3), np.zeros((3, 3))])
    for z in (x[:3] + 0.01, x[:3] + 1.0):  # inside and beyond the gate
        plain = gated_update(x, p, h, z - x[:3], r, 16.3, False)
        schmidt = schmidt_update(x, p, (np.zeros((6, 6)), np.zeros(6)), z, r, 0.0, 16.3, False)
        np.testing.assert_allclose(schmidt[0], plain[0], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(schmidt[1], plain[1], rtol=1e-9, atol=1e-15)
        assert schmidt[2] == pytest.approx(plain[2], rel=1e-12) and schmidt[3]
    refused = schmidt_update(x, p, (np.zeros((6, 6)), np.zeros(6)), x[:3] + 1.0, r, 0.0, 16.3, True)
    assert refused[3] is False and refused[4] is None
    assert refused[0] is x and refused[1] is p


def test_the_gain_leaves_the_least_error_and_its_parts_sum_to_the_schmidt_covariance() -> None:
    """With persisting moments: the white part (S4) plus the persisting part (P2) is ``P + Π − K·S·Kᵀ`` (1e-10
    relative), and every other gain (the filter's own among them) leaves a larger total error variance."""
    rng = np.random.default_rng(7)
    r = np.diag([4e-4, 3e-4, 1e-6])
    sigma = 0.012
    for _ in range(5):
        p, pi, c = _moments(rng)
        x = rng.normal(size=6) * 0.01
        _, p_white, _, used, k = schmidt_update(x, p, (pi, c), x[:3] + 0.005, r, sigma, 1e6, False)
        assert used and k is not None
        total = _total(p, pi, c, k, r, sigma)
        h = np.hstack([np.eye(3), np.zeros((3, 3))])
        e_y = np.array([0.0, 1.0, 0.0])
        cross = sigma * np.outer(c[:3], e_y)
        s = h @ (p + pi) @ h.T - cross - cross.T + sigma**2 * np.outer(e_y, e_y) + r
        np.testing.assert_allclose(total, p + pi - k @ s @ k.T, rtol=1e-10, atol=1e-14)
        a = np.eye(6) - k @ h
        np.testing.assert_allclose(p_white, a @ p @ a.T + k @ r @ k.T, rtol=1e-12, atol=1e-16)  # (S4)
        own = p @ h.T @ np.linalg.inv(h @ p @ h.T + r)
        best = np.trace(total)
        assert np.trace(_total(p, pi, c, own, r, sigma)) > best
        for _ in range(20):
            other = k + rng.normal(size=k.shape) * 1e-3
            assert np.trace(_total(p, pi, c, other, r, sigma)) > best


def test_off_by_default_and_off_the_reference_update_is_the_filters_own_to_the_bit() -> None:
    """Unset ``gain`` is off; ``NoConsider`` and a persisting error without the gain take the reference with
    :func:`~sensor.fusion_coupling.coupled_update`, the moments as the std alone carried them, to the bit; a bad
    value is refused naming the field."""
    assert PersistingReferenceError(**PERSISTING).gain is False
    assert FusionConfig().side_rig.coupling_persisting_error is None
    rng = np.random.default_rng(11)
    p, _, _ = _moments(rng)
    x = rng.normal(size=6) * 0.01
    coupling = CouplingMeasurement(0, x[:3] + 0.004, np.diag([4e-4, 3e-4, 1e-6]))
    expected = coupled_update(x, p, coupling, 16.3, True)
    for consider in (NoConsider(), PersistingReference(6, PersistingReferenceError(**PERSISTING))):
        got = consider.coupled(x, p, coupling, 16.3, True)
        np.testing.assert_array_equal(got[0], expected[0])
        np.testing.assert_array_equal(got[1], expected[1])
        assert got[2:] == expected[2:]
    alone = PersistingReference(6, PersistingReferenceError(**PERSISTING))
    alone.reference(p, coupling, expected[2], 16.3, True)
    np.testing.assert_array_equal(alone.pi, consider.pi)
    np.testing.assert_array_equal(alone.c, consider.c)
    with pytest.raises(ValidationError, match="gain"):
        PersistingReferenceError(**PERSISTING, gain="sometimes")


def _drive(persisting: PersistingReferenceError | None) -> tuple[np.ndarray, ...]:
    """The lead's fused error and std on the straight of :func:`lead_follower_straight.drive_straight`, the follower's
    camera off by :data:`REAR_ERROR` in every frame of :data:`WRONG`, and the ticks' times [s]."""
    noise = FusionNoise(side_rig=SIDE.replace(coupling_persisting_error=persisting))
    fused = FusedVisoOt(PARAMS, SIDE_RIG.camera_in_trailer("left", PARAMS), noise)
    follower = SimpleNamespace(released=[], camera_in_trailer=REAR_CAMERA)
    following = FollowingCamera(CouplingReference(PARAMS, 1, 2, REAR_CAMERA, fused.noise), follower)
    return drive_straight(fused, following, follower, WRONG, REAR_ERROR)


def test_a_reference_whose_error_persists_is_not_taken_for_the_leads_path() -> None:
    """The follower's camera off by 2 mm a frame across its motion for 10 s (100 frames; its per-frame lateral std
    about 10 mm, so each frame alone is within it). The lead's own camera is exact, so its raw error is 0. With the
    gain (``u`` 0.5, ``τ_c`` 10 s) the lead's fused error stays under 1.5 mm and within 2σ on every tick from the
    error's start, its mean std under 5 mm; without the persisting error the lead takes the follower's (over 1 cm)
    and its std covers under 60 % of the same ticks; with it in the std alone the error is the same to the bit and
    the std covers it only by being ten times the gain's."""
    gained, gained_std, times = _drive(PersistingReferenceError(**PERSISTING, gain=True))
    plain, plain_std, plain_times = _drive(None)
    alone, alone_std, _ = _drive(PersistingReferenceError(**PERSISTING))
    np.testing.assert_array_equal(times, plain_times)
    late = times >= WRONG[0] * DT
    assert np.max(np.abs(gained)) < 0.0015
    assert np.all(np.abs(gained[late]) <= 2.0 * gained_std[late])
    assert np.mean(gained_std[late]) < 0.005
    assert np.max(np.abs(plain[late])) > 0.01
    assert np.mean(np.abs(plain[late]) <= 2.0 * plain_std[late]) < 0.6
    np.testing.assert_array_equal(alone, plain)
    assert np.mean(alone_std[late]) > 10.0 * np.mean(gained_std[late])
    assert math.isfinite(float(np.max(gained_std)))
