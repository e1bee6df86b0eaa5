"""(C4) of sensor/fusion_coupling_share.py: the following unit's measurement's lateral variance widened by the
follower's own off-tracking variance in the share ``D`` of its scrub (``fusion.side_rig.coupling_follower_share``).

The function on hand-made covariances; the setting on by default and, set ``false``, the loop's reference bit for bit
as without it, the follower's filter not even asked; and the lead's filter on a straight where the follower's camera
is off across its motion while its axles are at their lock (``D`` = 1): with the setting the lead's off-tracking
stays with its own (exact) camera and its std covers its error; without it the lead takes the follower's error.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from lead_follower_straight import DT, PARAMS, REAR_CAMERA, SIDE, SIDE_RIG, drive_straight
from pydantic import ValidationError

from scenarios.configuration.sections import FusionConfig
from scenarios.loop.following_camera import FollowingCamera, following_camera
from sensor.fusion import FusedVisoOt, FusionNoise
from sensor.fusion_coupling import CouplingReference
from sensor.fusion_coupling_share import follower_shared
from sensor.fusion_noise import SideRigFusion
from vehicle_model.errors import InputError

R_C = np.array([[2e-4, 1e-5, 3e-6], [1e-5, 1.5e-4, -2e-6], [3e-6, -2e-6, 1.6e-6]])  # a (C2) covariance

LOCK = (500, 1000)  # the ticks [10 s, 20 s) the follower's axles are at their lock (D = 1)
REAR_ERROR = 5e-3  # [m] the follower camera's error across its motion in every frame while at lock
FOLLOWER_STD = (0.03, 0.10)  # [m] the follower's off-tracking std rolling and at lock, as its filter gives it


def test_the_function_widens_the_lateral_variance_by_the_share_of_the_followers() -> None:
    """``R_c + D·σ_f²·e_y·e_yᵀ`` to 1e-15 relative; every other entry to the bit; ``D`` = 0 and an unknown ``D`` or
    ``σ_f`` leave ``R_c`` to the bit; the argument is not changed; bad ``D`` or ``σ_f`` refused naming them."""
    before = R_C.copy()
    for demand in (0.0, 0.3, 1.0):
        widened = follower_shared(R_C, demand, 0.08)
        expected = R_C.copy()
        expected[1, 1] += demand * 0.08**2
        np.testing.assert_allclose(widened, expected, rtol=1e-15, atol=0.0)
        mask = np.ones((3, 3), dtype=bool)
        mask[1, 1] = False
        np.testing.assert_array_equal(widened[mask], R_C[mask])
    np.testing.assert_array_equal(follower_shared(R_C, 0.0, 0.08), R_C)
    np.testing.assert_array_equal(follower_shared(R_C, math.nan, 0.08), R_C)
    np.testing.assert_array_equal(follower_shared(R_C, 1.0, math.nan), R_C)
    np.testing.assert_array_equal(R_C, before)
    for demand, std, field in ((1.2, 0.1, "demand"), (-0.1, 0.1, "demand"), (0.5, -0.1, "follower_std")):
        with pytest.raises(InputError, match=field):
            follower_shared(R_C, demand, std)


def test_the_setting_is_the_references_on_by_default_and_reaches_the_loop() -> None:
    """Unset by default, which is on; ``false`` turns it off; it is not among the filter's settings; the loop's
    reference takes it; a bad value is refused naming the field."""
    assert FusionConfig().side_rig.coupling_follower_share is None
    assert FusionConfig().side_rig.reference_follower_share
    assert not FusionConfig(side_rig={"coupling_follower_share": False}).side_rig.reference_follower_share
    side = SIDE.replace(coupling_follower_share=True)
    assert "coupling_follower_share" not in side.given()
    cameras = {"viso_ot3": SimpleNamespace(camera_in_trailer=REAR_CAMERA, released=[])}
    noise = FusionNoise(side_rig=side).for_camera((0.0, 1.0))
    assert following_camera(PARAMS, 1, cameras, noise, "planar").reference.follower_share
    off = FusionNoise(side_rig=SIDE.replace(coupling_follower_share=False)).for_camera((0.0, 1.0))
    assert not following_camera(PARAMS, 1, cameras, off, "planar").reference.follower_share
    with pytest.raises(ValidationError, match="coupling_follower_share"):
        SideRigFusion(coupling_follower_share="sometimes")


def _follower(k: int) -> tuple[float, float]:
    """The follower's filter's scrub demand ``D`` and off-tracking std at tick ``k``: at its lock in :data:`LOCK`."""
    at_lock = LOCK[0] <= k < LOCK[1]
    return (1.0, FOLLOWER_STD[1]) if at_lock else (0.0, FOLLOWER_STD[0])


def _drive(share: bool, asked: list[int] | None = None, given: bool = True) -> tuple[np.ndarray, ...]:
    """The lead's fused error and std on the straight of :func:`lead_follower_straight.drive_straight`, the follower's
    camera off by :data:`REAR_ERROR` in every frame of :data:`LOCK`, and the ticks' times [s]. ``asked`` collects the
    ticks the follower's demand was asked on; ``given`` False: the following camera built without it."""
    noise = FusionNoise(side_rig=SIDE.replace(coupling_follower_share=share))
    fused = FusedVisoOt(PARAMS, SIDE_RIG.camera_in_trailer("left", PARAMS), noise)
    follower = SimpleNamespace(released=[], camera_in_trailer=REAR_CAMERA)
    reference = CouplingReference(PARAMS, 1, 2, REAR_CAMERA, fused.noise, follower_share=share)
    tick = [0]

    def scrub() -> tuple[float, float]:
        if asked is not None:
            asked.append(tick[0])
        return _follower(tick[0])

    def at_tick(k: int) -> None:
        tick[0] = k

    following = FollowingCamera(reference, follower, scrub=scrub if given else None)
    return drive_straight(fused, following, follower, LOCK, REAR_ERROR, at_tick)


def test_a_reference_wrong_while_the_follower_is_at_lock_is_not_taken_for_the_leads_path() -> None:
    """The follower's camera off by 5 mm a frame across its motion through its 10 s at lock (100 frames), its filter
    giving ``D`` = 1 and a 0.10 m std there. The lead's own camera is exact, so its raw off-tracking error is 0.
    With (C4) the lead's fused error stays under 2 mm over the run and within 2σ on every tick from the lock's start;
    without it the lead takes the follower's error (over 2.5 cm by the lock's end) and its std covers under 60 % of
    the same ticks."""
    shared, shared_std, times = _drive(True)
    plain, plain_std, plain_times = _drive(False)
    np.testing.assert_array_equal(times, plain_times)
    late = times >= LOCK[0] * DT
    assert np.max(np.abs(shared)) < 0.002
    assert np.all(np.abs(shared[late]) <= 2.0 * shared_std[late])
    assert np.max(np.abs(plain[late])) > 0.025
    assert np.mean(np.abs(plain[late]) <= 2.0 * plain_std[late]) < 0.6


def test_turned_off_the_loops_reference_is_unchanged_to_the_bit() -> None:
    """With the setting off the follower's filter is not asked for its demand (no (C3) either) and the lead's filter
    runs as with a following camera that has no way to ask it, to the bit; with it the follower is asked."""
    asked: list[int] = []
    plain, plain_std, _ = _drive(False, asked)
    assert asked == []
    errors, stds, _ = _drive(False, given=False)
    np.testing.assert_array_equal(plain, errors)
    np.testing.assert_array_equal(plain_std, stds)
    reference = CouplingReference(PARAMS, 1, 2, REAR_CAMERA, FusionNoise())
    assert reference.follower_share is False and reference.shared(R_C, 1.0, 0.1) is R_C
    _drive(True, asked)
    assert len(asked) > 100
