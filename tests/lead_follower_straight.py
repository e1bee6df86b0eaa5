"""A B-double's lead trailer driven on a straight with its follower's camera as the coupling reference, the
follower's camera off by a set amount across its motion in a window of frames: the scene the coupling reference's
tests (the follower share (C4), the Schmidt–Kalman gain) run their filters through."""

from __future__ import annotations

from collections.abc import Callable
from types import SimpleNamespace

import numpy as np

from scenarios.loop.following_camera import FollowingCamera
from sensor.camera import StereoRig
from sensor.fusion import FusedVisoOt, TractorSignals
from sensor.fusion_noise import SideRigFusion
from vehicle_model.geometry import ChainPose, unit_frame
from vehicle_model.offtracking import OfftrackingBuffer, increments_from_poses
from vehicle_model.presets import VEHICLE_PRESETS

PARAMS = VEHICLE_PRESETS["au-b-double"]()
SIDE_RIG = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275, unit=1, station=-4.0)
REAR_RIG = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
REAR_CAMERA = REAR_RIG.camera_in_trailer("left", PARAMS)
SIDE = SideRigFusion(kinematic_rear_point="speed_compensated", kinematic_error_model="state", coupling_reference=True)

DT, EVERY, SPEED = 0.02, 5, 5.0  # control period [s], ticks a frame, forward speed [m/s]
TICKS = 1500  # 30 s


def _shot(tick: int, motion: np.ndarray) -> SimpleNamespace:
    vo = SimpleNamespace(camera_motion=motion, covariance=np.eye(6) * 1e-8)
    return SimpleNamespace(tick=tick, frame=SimpleNamespace(valid=True, vo=vo))


def drive_straight(
    fused: FusedVisoOt,
    following: FollowingCamera,
    follower: SimpleNamespace,
    wrong: tuple[int, int],
    rear_error: float,
    at_tick: Callable[[int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The lead unit's filter ``fused`` on a straight at :data:`SPEED` (no slip: the truth's off-tracking is 0 and the
    lead's own camera exact), ``follower``'s camera (its ``released`` frames, taken by ``following``) off by
    ``rear_error`` [m] across its motion in every frame of the ticks ``wrong``; ``at_tick(k)`` is called first at
    every tick. Returns the lead's fused error and std at every tick with an estimate, and the ticks' times [s]."""
    truth = OfftrackingBuffer(PARAMS.follow_point_offset_of(1))
    errors, stds, times, previous, last = [], [], [], None, None
    for k in range(TICKS):
        if at_tick is not None:
            at_tick(k)
        pose = ChainPose(SPEED * k * DT, 0.0, 0.0, (0.0, 0.0))
        frame = unit_frame(PARAMS, pose, 1)
        if previous is not None:
            truth.push(*increments_from_poses(np.vstack([previous[0], frame[0]]), np.array([previous[1], frame[1]]))[0])
        previous = frame
        fused.propagate(k, DT, 0.0, SPEED, None, TractorSignals(SPEED, 0.0, 0.0))
        follower.released, own = [], None
        if k % EVERY == 0:
            worlds = (SIDE_RIG.camera_in_world(PARAMS, pose, "left"), REAR_RIG.camera_in_world(PARAMS, pose, "left"))
            if last is not None:
                own = np.linalg.inv(last[0]) @ worlds[0]
                rear = np.linalg.inv(last[1]) @ worlds[1]
                if wrong[0] <= k < wrong[1]:
                    rear[0, 3] += rear_error  # across the follower camera's motion, the same in every frame
                follower.released = [_shot(k, rear)]
            last = worlds
        following.observe(k, {"articulation": np.zeros(1), "rear_articulation": np.zeros(1)})
        if own is not None:
            fused.measure(k, own, np.eye(6) * 1e-6, coupling=following.take(k))
        value = truth.offtracking()
        if fused.estimate is not None and value is not None:
            errors.append(fused.estimate - value)
            stds.append(fused.std)
            times.append(k * DT)
    return np.array(errors), np.array(stds), np.array(times)
