"""The following unit's persisting error as a consider parameter of the fused filter's std
(sensor/fusion_consider.py, ``coupling_persisting_error``)."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from scenarios.config import ConfigError, validate_config
from sensor.camera import StereoRig
from sensor.fusion import STD_PARTS, FusedVisoOt, FusionNoise, TractorSignals
from sensor.fusion_consider import NoConsider, PersistingReference, Transition
from sensor.fusion_coupling import CouplingMeasurement
from sensor.fusion_noise import PersistingReferenceError, SideRigFusion
from vehicle_model.errors import InputError
from vehicle_model.geometry import ChainPose
from vehicle_model.presets import VEHICLE_PRESETS

DT, EVERY, SPEED = 0.02, 5, 5.0  # control period [s], ticks per frame, forward speed [m/s]
R_C = 1e-4  # the reference's per-frame variance on each axis [m², m², rad²]


def _constant(share: float) -> PersistingReferenceError:
    """A persisting error that does not fade over any test (beyond the field's range, which is the settings')."""
    return PersistingReferenceError.model_construct(share=share, correlation_time_s=1e12)


def test_the_consider_moments_of_a_random_constant_are_the_closed_form():
    """A random constant ``x`` (three states, no dynamics) measured ``n`` times by a reference ``z = x + σ_c·ν + v``
    with the filter's own gains: the estimate is the information-weighted mean, every frame's weight ``w = P_n/r``,
    so the error ``ν`` leaves is ``σ_c·w·Σ_j ν_j`` with the variance ``σ_c²·w²·Σ_j Σ_l φ^|j−l|`` and the cross-moment
    with the last ``ν`` ``σ_c·w·Σ_j φ^(n−j)`` ((P1)–(P2); to 1e-9 relative), for a fading and a constant error."""
    r, p0, n, frame = 4e-4, 1e-2, 12, 0.1
    for tau in (0.3, 1e12):
        error = PersistingReferenceError.model_construct(share=0.2, correlation_time_s=tau)
        consider = PersistingReference(3, error)
        p = p0
        for k in range(n):
            if k:  # the frame's time since the last one, no dynamics
                consider.frame(Transition(np.eye(3), frame))
            coupling = CouplingMeasurement(0, np.zeros(3), np.eye(3) * r)
            consider.reference(np.eye(3) * p, coupling, 0.0, 16.3, True)
            p = 1.0 / (1.0 / p + 1.0 / r)
        phi = math.exp(-frame / tau)
        sigma, w = 0.2 * math.sqrt(r), p / r
        lags = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
        variance = sigma**2 * w**2 * float(np.sum(phi**lags))
        cross = sigma * w * float(np.sum(phi ** np.arange(n)))
        assert consider.pi[1, 1] == pytest.approx(variance, rel=1e-9)
        assert consider.c[1] == pytest.approx(cross, rel=1e-9)
        assert consider.pi[0, 0] == consider.pi[2, 2] == 0.0  # only the lateral row is injected


def test_the_reference_scale_is_taken_out_of_the_persisting_std():
    """``σ_c`` is the share of the reference's per-frame std before ``k_c``: a reference taken at ``k_c`` = 4 with
    the same per-frame error injects ``K_c·σ_c``, ``K_c`` of its own (wider) covariance (to 1e-12 relative)."""
    error = PersistingReferenceError(share=0.1, correlation_time_s=5.0)
    p = np.eye(3) * 1e-3
    for scale in (1.0, 4.0):
        consider = PersistingReference(3, error)
        consider.reference(p, CouplingMeasurement(0, np.zeros(3), np.eye(3) * R_C * scale, scale), 0.0, 16.3, True)
        gain = 1e-3 / (1e-3 + R_C * scale)
        assert consider.c[1] == pytest.approx(0.1 * math.sqrt(R_C) * gain, rel=1e-12)


@functools.lru_cache(maxsize=8)
def _drive(error: PersistingReferenceError | None, shift: float = 0.0, reference: bool = True) -> tuple:
    """A side rig's filter on a straight at ``SPEED``, its camera exact, with a following unit's measurement every
    frame (``R_C`` on each axis) whose lateral component is off by ``shift`` times its persisting std; per tick the
    estimate, std, std parts, state and covariance, and the consider's own std."""
    params = VEHICLE_PRESETS["au-b-double"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275, unit=1, station=-4.0)
    side = SideRigFusion(
        vo_axial_flow=0.05, vo_axial_scale=0.04, coupling_reference=True, coupling_persisting_error=error
    )
    fused = FusedVisoOt(params, rig.camera_in_trailer("left", params), FusionNoise(side_rig=side))
    rows, last = [], None
    step = SPEED * DT * EVERY
    offset = shift * (0.0 if error is None else error.share) * math.sqrt(R_C)
    for k in range(200):
        fused.propagate(k, DT, 0.0, SPEED, None, TractorSignals(SPEED, 0.0, 0.0))
        if k % EVERY == 0:
            world = rig.camera_in_world(params, ChainPose(SPEED * k * DT, 0.0, 0.0, (0.0, 0.0)), "left")
            if last is not None:
                coupling = None
                if reference:
                    coupling = CouplingMeasurement(k - EVERY, np.array([step, offset, 0.0]), np.eye(3) * R_C)
                fused.measure(k, np.linalg.inv(last) @ world, np.eye(6) * 1e-6, coupling=coupling)
            last = world
        now = fused._history[-1]
        persisting = fused._consider.variance(
            now.transition, now.x[:3], fused._starts, fused._ends, fused.follow_point_offset
        )
        estimate = math.nan if fused.estimate is None else fused.estimate
        parts = [fused.std_parts[p] for p in STD_PARTS]
        rows.append((estimate, fused.std, *parts, *fused.state, *fused.covariance.ravel(), persisting))
    return np.array(rows), fused


def test_off_the_filter_keeps_no_moments_and_on_only_its_std_changes():
    """Off (the default): no consider moments and no transitions are kept. On: the estimate, the state and its
    covariance are those off to the bit on every tick; the std is at least off's, wider where references were taken;
    without any reference taken, the std too is off's to the bit."""
    off, filt = _drive(None)
    assert isinstance(filt._consider, NoConsider) and not hasattr(filt._consider, "pi")
    assert all(t.transition is None for t in filt._history)
    on, _ = _drive(PersistingReferenceError(share=0.1, correlation_time_s=5.0))
    read = np.isfinite(off[:, 0])
    assert np.sum(read) > 50 and off.shape == on.shape
    np.testing.assert_array_equal(on[:, 0], off[:, 0])  # the estimate (NaN where none)
    np.testing.assert_array_equal(on[:, 2 + len(STD_PARTS) : -1], off[:, 2 + len(STD_PARTS) : -1])  # state, P
    assert np.all(on[read, 1] >= off[read, 1]) and np.mean(on[read, 1] > off[read, 1]) > 0.9
    others = [2 + i for i, p in enumerate(STD_PARTS) if p != "biases"]
    np.testing.assert_array_equal(on[:, others], off[:, others])
    alone, _ = _drive(PersistingReferenceError(share=0.1, correlation_time_s=5.0), reference=False)
    plain, _ = _drive(None, reference=False)
    np.testing.assert_array_equal(alone[:, :-1], plain[:, :-1])


def test_a_constant_persisting_error_moves_the_estimate_by_the_consider_std():
    """With a persisting error that does not fade, (P3) is the off-tracking's sensitivity to it: shifting every
    reference's lateral component by its persisting std moves the estimate by the consider's std (the filter is
    linear in its measurements). To 8 % where the std is above a tenth of its peak, 5 % on the mean: eq (4)'s
    ``g`` counts the increment the follow point lies in whole or not at all, one of the sixteen ahead of it."""
    error = _constant(0.1)
    base, _ = _drive(error)
    moved, _ = _drive(error, shift=1.0)
    change, predicted = np.abs(moved[:, 0] - base[:, 0]), np.sqrt(base[:, -1])
    live = np.isfinite(base[:, 0]) & np.isfinite(moved[:, 0])
    live &= predicted > 0.1 * predicted[live].max()
    assert predicted.max() > 1e-4 and np.sum(live) > 30
    np.testing.assert_allclose(change[live], predicted[live], rtol=0.08)
    assert np.mean(change[live]) == pytest.approx(np.mean(predicted[live]), rel=0.05)


@pytest.mark.parametrize(
    ("field", "value"),
    [("share", 0.0), ("share", 1.5), ("correlation_time_s", 0.0), ("correlation_time_s", 601.0)],
)
def test_a_bad_persisting_error_is_refused_naming_the_field_and_range(field, value):
    """A run's ``fusion.side_rig.coupling_persisting_error`` outside its range is a configuration error (exit 2)
    naming the dotted field, before any work."""
    good = {"share": 0.1, "correlation_time_s": 5.0}
    data = {"fusion": {"side_rig": {"coupling_persisting_error": {**good, field: value}}}}
    with pytest.raises(ConfigError) as refused:
        validate_config(data)
    assert isinstance(refused.value, InputError)
    assert f"fusion.side_rig.coupling_persisting_error.{field}" in str(refused.value)
    assert validate_config({"fusion": {"side_rig": {"coupling_persisting_error": good}}}).fusion.side_rig
