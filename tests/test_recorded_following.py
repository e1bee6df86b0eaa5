"""A following unit's recorded frames as the reference of a side rig's offline filter (scenarios/recorded/following.py).

A B-double swings through a turn (every articulation changing, no unit moving as its tyres would let it); the rear
trailer's rear rig sees its exact camera motions, kept as a recording's trace is, on the lead's clock with a
constant offset well within the synchronisation tolerance. Each following frame released on the lead's frame row of
the same instant gives, through the loop's following camera, the lead's exact kingpin increment over the frame; a
frame missing from the follower's recording gives none, and the frame after it starts at the missing frame's
predecessor, not at the lead's anchor, so a filter takes none there either.
"""

from __future__ import annotations

import itertools
import math
from types import SimpleNamespace

import numpy as np
import pytest

from scenarios.config import FusionConfig
from scenarios.loop.following_camera import filter_yaw_bias, following_camera
from scenarios.recorded.following import FollowerTrace, following_reference
from sensor.camera import StereoRig
from sensor.fusion_model import BPSI, relative_pose
from vehicle_model.geometry import ChainPose, unit_frame
from vehicle_model.presets import VEHICLE_PRESETS

PERIOD = 0.1  # frame interval [s]
OFFSET = 0.002  # the follower's frames' offset on the shared clock [s] (within a tenth of the period)
T0 = 5.0  # the lead recording's first frame on the shared clock [s]


def _pose(t: float) -> ChainPose:
    angles = tuple(0.2 * math.sin(0.7 * t + k) + 0.05 * k for k in range(2))
    return ChainPose(3.0 * t + 0.4 * math.sin(t), 0.5 * t * t, 0.3 * t + 0.2 * math.sin(1.3 * t), angles)


def _reference(
    missing: int | None, offset: float = OFFSET, fusion: FusionConfig | None = None, scrub: tuple[float, float] = ()
):
    """The lead's reference over 12 frames with a signals' row between each two (the follower's frame ``missing``
    not recorded, its frames ``offset`` after the lead's), the lead's rows and the B-double. ``scrub``: the follower's
    filter's scrub demand and off-tracking std at every frame (its ``β̂_ψ`` 0); empty: no follower filter."""
    params = VEHICLE_PRESETS["au-b-double"]()
    rear = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
    camera = rear.camera_in_trailer("left", params)
    frames = np.arange(12) * PERIOD
    times = np.sort(np.concatenate([frames, frames[:-1] + PERIOD / 2]))  # a signals' row between frames
    slots = np.where(np.isin(times, frames), np.searchsorted(frames, times), -1)
    follower = SimpleNamespace(rig=SimpleNamespace(unit=2, params=params), camera_in_trailer=camera, signals=None)
    trace = FollowerTrace(follower)
    fused = None
    if scrub:
        state, covariance = np.zeros(BPSI + 1), np.eye(BPSI + 1) * 1e-12
        fused = SimpleNamespace(state=state, covariance=covariance, frame_scrub_demand=scrub[0], std=scrub[1])
    last = None
    for k, t in enumerate(frames):
        world = rear.camera_in_world(params, _pose(t), "left")
        if last is not None and k != missing:
            motion = np.linalg.inv(last) @ world
            frame = SimpleNamespace(valid=True, vo=SimpleNamespace(camera_motion=motion, covariance=None))
            trace.add(T0 + t + offset, frame, fused)
        elif k == 0:
            trace.add(T0 + t + offset, SimpleNamespace(valid=False, vo=None), fused)
        if k != missing:
            last = world
    angles = np.array([_pose(t).angles for t in times])
    signals = {"articulation": angles[:, 0], "articulation2": angles[:, 1]}
    lead = SimpleNamespace(
        rig=SimpleNamespace(unit=1, params=params), recording=SimpleNamespace(t0=T0, times=frames), signals=None
    )
    reference = following_reference(lead, {2: trace}, times, slots, signals, fusion or FusionConfig())
    return reference, times, slots, params


def _measurements(reference, times, slots):
    found = {}
    for row in range(times.size):
        reference.observe(row)
        if slots[row] >= 0:
            found[row] = reference.take(row)
    return found


def test_each_following_frame_gives_the_leads_exact_increment_over_the_same_frame() -> None:
    reference, times, slots, params = _reference(missing=None)
    assert reference is not None and reference.follower == 2 and reference.matched == 12
    found = _measurements(reference, times, slots)
    rows = np.flatnonzero(slots >= 0)
    assert found[rows[0]] is None  # the first frame has no interval
    for previous, row in itertools.pairwise(rows):
        measurement = found[row]
        assert measurement is not None and measurement.start_tick == previous
        (pa, ha), (pb, hb) = (unit_frame(params, _pose(times[r]), 1) for r in (previous, row))
        truth = relative_pose(np.array([*pa, ha]), np.array([*pb, hb]))
        # the transport is exact on the rigid bodies' motion (1e-9 m, rad); the covariance a positive 3×3
        np.testing.assert_allclose(measurement.increment, truth, rtol=0.0, atol=1e-9)
        assert np.all(np.linalg.eigvalsh(measurement.covariance) > 0.0)
    assert reference.following.measurements == rows.size - 1


def test_the_recorded_reference_takes_the_side_rigs_covariance_scale() -> None:
    """``fusion.side_rig.coupling_covariance_scale`` reaches an offline reference as it does a run's: each
    measurement's covariance exactly that many times the unscaled one, its increment unchanged."""
    plain, times, slots, _ = _reference(missing=None)
    scaled, *_ = _reference(missing=None, fusion=FusionConfig(side_rig={"coupling_covariance_scale": 4.0}))
    assert plain is not None and scaled is not None
    found, wide = _measurements(plain, times, slots), _measurements(scaled, times, slots)
    rows = [row for row, m in found.items() if m is not None]
    assert rows and all(wide[row] is not None for row in rows)
    for row in rows:
        np.testing.assert_array_equal(wide[row].increment, found[row].increment)
        np.testing.assert_allclose(wide[row].covariance, 4.0 * found[row].covariance, rtol=1e-12, atol=0.0)


def test_the_recorded_reference_takes_the_followers_scrub_share_as_a_run_does() -> None:
    """(C4), on by default: each offline measurement's lateral variance is the one with the setting off plus the
    recorded follower's ``D·σ_f²`` (1e-12 relative), every other entry and the increment unchanged; at ``D`` = 0 the
    two are equal to the bit."""
    demand, std = 0.6, 0.07
    on, times, slots, _ = _reference(missing=None, scrub=(demand, std))
    off_fusion = FusionConfig(side_rig={"coupling_follower_share": False})
    off, *_ = _reference(missing=None, fusion=off_fusion, scrub=(demand, std))
    rolling, *_ = _reference(missing=None, scrub=(0.0, std))
    rolling_off, *_ = _reference(missing=None, fusion=off_fusion, scrub=(0.0, std))
    assert on is not None and off is not None and rolling is not None and rolling_off is not None
    found_on, found_off = _measurements(on, times, slots), _measurements(off, times, slots)
    found_rolling, found_rolling_off = _measurements(rolling, times, slots), _measurements(rolling_off, times, slots)
    rows = [row for row, m in found_off.items() if m is not None]
    assert len(rows) == 11
    for row in rows:
        widened, plain = found_on[row].covariance, found_off[row].covariance
        np.testing.assert_array_equal(found_on[row].increment, found_off[row].increment)
        assert widened[1, 1] == pytest.approx(plain[1, 1] + demand * std**2, rel=1e-12)
        mask = np.ones(widened.shape, dtype=bool)
        mask[1, 1] = False
        np.testing.assert_array_equal(widened[mask], plain[mask])
        np.testing.assert_array_equal(found_rolling[row].covariance, found_rolling_off[row].covariance)


def test_a_missing_following_frame_gives_no_measurement_at_the_leads_anchor() -> None:
    missing = 5
    reference, times, slots, _ = _reference(missing=missing)
    assert reference is not None and reference.matched == 11
    found = _measurements(reference, times, slots)
    rows = np.flatnonzero(slots >= 0)
    assert found[rows[missing]] is None
    after = found[rows[missing + 1]]
    # the frame after the gap spans it: it starts on the frame before the missing one, not at the lead's anchor
    assert after is not None and after.start_tick == rows[missing - 1]
    assert all(found[rows[k]] is not None and found[rows[k]].start_tick == rows[k - 1] for k in (2, 4, 8, 11))


def test_a_follower_off_the_shared_instant_or_across_its_unit_gives_no_reference() -> None:
    # frames a third of a period apart are not the same instant: none is released, no measurement is made
    reference, times, slots, params = _reference(missing=None, offset=PERIOD / 3)
    assert reference is not None and reference.matched == 0
    assert all(found is None for found in _measurements(reference, times, slots).values())
    # a side rig behind has the lead's own axial errors: not a reference
    side = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275, unit=2, station=-4.0)
    unit = SimpleNamespace(rig=SimpleNamespace(unit=2, params=params), camera_in_trailer=None, signals=None)
    unit.camera_in_trailer = side.camera_in_trailer("left", params)
    lead = SimpleNamespace(rig=SimpleNamespace(unit=1, params=params), recording=SimpleNamespace(t0=T0, times=times))
    signals = {"articulation": np.zeros(times.size), "articulation2": np.zeros(times.size)}
    assert following_reference(lead, {2: FollowerTrace(unit)}, times, slots, signals, FusionConfig()) is None


def test_the_loops_following_camera_reads_the_followers_filter_when_asked() -> None:
    """The run's follower yaw error (C0) comes from the follower's fused participant looked up when a frame is
    measured (it may be built after the lead's), as the offline trace keeps it: ``β̂_ψ``, its variance and the scrub
    demand of its last frame."""
    params = VEHICLE_PRESETS["au-b-double"]()
    rear = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
    cameras: dict = {"viso_ot3": SimpleNamespace(camera_in_trailer=rear.camera_in_trailer("left", params), released=[])}
    lead = following_camera(params, 1, cameras, FusionConfig(), "planar")
    assert lead is not None and lead.yaw_bias is not None and lead.yaw_bias() is None  # no follower filter yet
    state, covariance = np.arange(12.0), np.diag(np.arange(12.0) + 1.0)
    fused = SimpleNamespace(state=state, covariance=covariance, frame_scrub_demand=0.25)
    cameras["viso_ot_fused3"] = SimpleNamespace(filter=fused)
    assert lead.yaw_bias() == (state[BPSI], covariance[BPSI, BPSI], 0.25)
    assert filter_yaw_bias(cameras["viso_ot_fused3"].filter) == lead.yaw_bias()
