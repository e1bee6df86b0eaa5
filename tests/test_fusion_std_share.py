"""Eq (4') of sensor/fusion_std.py: the biases reach the off-tracking's std only through the share of each
increment's error that a following unit's measurement left in it (``coupling_bias_share``)."""

from __future__ import annotations

import functools
import math

import numpy as np

from sensor.camera import StereoRig
from sensor.fusion import FusedVisoOt, FusionNoise, TractorSignals
from sensor.fusion_coupling import CouplingMeasurement
from sensor.fusion_model import gated_update
from sensor.fusion_noise import SideRigFusion
from sensor.fusion_std import IncrementWindow, path_effects, reference_share
from vehicle_model.geometry import ChainPose
from vehicle_model.presets import VEHICLE_PRESETS

DT, EVERY, SPEED = 0.02, 5, 5.0  # control period [s], ticks per frame, forward speed [m/s]


def _covariance(seed: int, n: int) -> np.ndarray:
    a = np.random.default_rng(seed).normal(size=(n, n))
    return a @ a.T * 1e-4 + np.eye(n) * 1e-6


def test_the_share_is_what_the_update_left_of_the_prior_error():
    """``P⁺·P⁻⁻¹`` of the increment after an ``H = [I₃ 0]`` update is ``R·S⁻¹`` (to 1e-9 relative); a reference
    without error leaves none of the prior's (under 1e-6), one refused leaves all of it (the identity exactly)."""
    p = _covariance(0, 7)
    h = np.hstack([np.eye(3), np.zeros((3, 4))])
    for r, expected in ((_covariance(1, 3), None), (np.eye(3) * 1e-14, np.zeros((3, 3)))):
        _, post, _, used = gated_update(np.zeros(7), p, h, np.zeros(3), r, 1e6, True)
        assert used
        share = reference_share(p[:3, :3], post[:3, :3])
        if expected is None:
            expected = r @ np.linalg.inv(p[:3, :3] + r)
            np.testing.assert_allclose(share, expected, rtol=1e-9, atol=1e-12)
        else:
            assert np.max(np.abs(share)) < 1e-6
    np.testing.assert_array_equal(reference_share(p[:3, :3], p[:3, :3].copy()), np.eye(3))


def _window(n: int, shares: np.ndarray | None) -> IncrementWindow:
    """``n`` increments of 1 m curving left, ending at the anchor."""
    heading = np.linspace(-0.3, 0.0, n + 1)
    xy = np.cumsum(np.column_stack([np.cos(heading), np.sin(heading)]), axis=0)
    xy -= xy[-1]
    starts = np.column_stack([xy[:-1], heading[:-1]])
    covs = np.array([_covariance(k, 3) for k in range(n)]).reshape(n, 3, 3)
    return IncrementWindow(starts, xy[1:], covs, np.full(n, 0.2), np.zeros(n), shares)


def test_the_path_effects_take_the_biases_through_the_share():
    """With every share the identity the sums are those without shares to the bit; with every share zero (each
    increment the reference's alone) ``G``, ``A_z`` and ``A_f`` are the current increment's alone; the independent
    part is unchanged either way."""
    n = 12
    args = (np.array([0.5, 0.01, 0.02]), _covariance(9, 3), 0.1)
    rest = (8.0, 1.5, np.array([0.1, -0.4]), np.array([0.0, 1.0]), np.array([-4.0, 1.3, 1.0]))
    plain = path_effects(*args, _window(n, None), *rest)
    same = path_effects(*args, _window(n, np.tile(np.eye(3), (n, 1, 1))), *rest)
    none = path_effects(*args, _window(n, np.zeros((n, 3, 3))), *rest)
    alone = path_effects(*args, _window(0, None), *rest)
    np.testing.assert_array_equal(same.coherent, plain.coherent)
    assert (same.independent, same.axial, same.cross, same.lever) == (
        plain.independent,
        plain.axial,
        plain.cross,
        plain.lever,
    )
    np.testing.assert_array_equal(none.coherent, alone.coherent)
    assert (none.axial, none.cross) == (alone.axial, alone.cross)
    assert none.independent == plain.independent
    assert np.max(np.abs(plain.coherent[:2] - alone.coherent[:2])) > 0.5  # the window's share is not negligible


@functools.lru_cache(maxsize=4)
def _drive(share: bool, reference: float | None) -> tuple[tuple[float, ...], FusedVisoOt]:
    """A side rig's filter on a straight at ``SPEED``, its camera exact, with a following unit's measurement of the
    exact increment every frame at ``reference`` times the identity covariance (``None``: none); the std every
    tick after the follow point, and the filter."""
    params = VEHICLE_PRESETS["au-b-double"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275, unit=1, station=-4.0)
    side = SideRigFusion(vo_axial_flow=0.05, vo_axial_scale=0.04, coupling_reference=True, coupling_bias_share=share)
    fused = FusedVisoOt(params, rig.camera_in_trailer("left", params), FusionNoise(side_rig=side))
    stds, last = [], None
    step = SPEED * DT * EVERY
    for k in range(250):
        fused.propagate(k, DT, 0.0, SPEED, None, TractorSignals(SPEED, 0.0, 0.0))
        if k % EVERY == 0:
            world = rig.camera_in_world(params, ChainPose(SPEED * k * DT, 0.0, 0.0, (0.0, 0.0)), "left")
            if last is not None:
                coupling = None
                if reference is not None:
                    coupling = CouplingMeasurement(k - EVERY, np.array([step, 0.0, 0.0]), np.eye(3) * reference)
                fused.measure(k, np.linalg.inv(last) @ world, np.eye(6) * 1e-6, coupling=coupling)
            last = world
        if fused.estimate is not None:
            stds.append(fused.std)
    return tuple(stds), fused


def test_without_a_reference_the_std_is_as_before_and_an_exact_one_leaves_no_share():
    """No following measurement: the std with ``coupling_bias_share`` on is the std without it to the bit, every
    increment's share the identity. A reference a hundred times tighter than the camera (0.01 against 1 mm): every
    committed increment keeps under 5 % of its prior error, and the std differs from the camera-sensitivity one."""
    (plain, _), (same, fused) = _drive(False, None), _drive(True, None)
    assert len(plain) > 100 and same == plain
    np.testing.assert_array_equal(fused._shares, np.tile(np.eye(3), (len(fused._shares), 1, 1)))
    (tight, fused), (camera, _) = _drive(True, 1e-10), _drive(False, 1e-10)
    assert len(fused._shares) > 10 and np.max(np.abs(fused._shares)) < 0.05
    assert tight != camera and math.isfinite(tight[-1])
