"""VISO-OT: trailer off-tracking from the stereo camera's visual odometry (de Saxe & Cebon 2018, §2.2).

Each camera frame the visual odometry gives the left camera's motion since the previous frame,
``camera_motion = T_prev←curr`` (OpenCV camera axes: x right, y down, z forward). The estimator

1. rotates the camera translation into the trailer frame with the camera-to-vehicle mounting
   (eq (1); the paper's ψ_c2v, measured clockwise from the trailer's forward axis, is the special
   case of a level camera: ``R(−ψ_c2v)`` in ISO terms),
2. takes the yaw change of the trailer about the vertical from the camera's rotation,
3. moves the increment from the camera to the kingpin with the lever arm (eq (2):
   ``Δp_kingpin = Δp_camera + (R(Δψ) − I)·(p_kingpin − p_camera)``; for a camera ``a`` behind the
   kingpin on the centre line this is the paper's ``a·[cos Δψ − 1, sin Δψ]`` in ISO order), and
4. feeds the shared :class:`~vehicle_model.offtracking.OfftrackingBuffer` (eqs (3)–(7)).

Failed frames: a frame without a valid motion is bridged with the last valid motion (a
constant-velocity prediction over one camera period); after ``max_consecutive_failures`` failed
frames in a row the path can no longer be trusted and the buffer is cleared, so the estimator
reports no estimate until one trailer length has again been driven. The buffer is never fed a
guess beyond that.
"""

from __future__ import annotations

import math

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.offtracking import OfftrackingBuffer
from vehicle_model.parameters import VehicleParams


class VisoOtEstimator:
    """Off-tracking from visual odometry of a trailer-mounted camera.

    Parameters
    ----------
    params
        Vehicle parameters (the follow point).
    camera_in_trailer
        4×4 pose ``T_trailer←camera`` of the camera whose motion the odometry reports (the left
        camera), trailer frame ISO (origin on the ground below the kingpin, x forward, y left,
        z up), camera axes OpenCV.
    max_consecutive_failures
        Failed frames bridged by prediction before the buffer is cleared.
    """

    def __init__(self, params: VehicleParams, camera_in_trailer: np.ndarray, max_consecutive_failures: int = 3) -> None:
        t = np.asarray(camera_in_trailer, dtype=float)
        if t.shape != (4, 4) or not np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-9):
            raise InputError("camera_in_trailer must be a 4×4 rigid transform (orthonormal rotation)")
        if max_consecutive_failures < 0:
            raise InputError("max_consecutive_failures must be ≥ 0")
        self.mount_rotation = t[:3, :3]
        self.camera_position = t[:2, 3].copy()  # camera in trailer axes, kingpin at the origin
        self.buffer = OfftrackingBuffer(params.follow_point_offset)
        self.max_consecutive_failures = max_consecutive_failures
        self.failures_in_a_row = 0
        self.frames = 0
        self.failed_frames = 0
        self._last_increment: tuple[float, float, float] | None = None

    def reset(self) -> None:
        """Forget the path and the failure history."""
        self.buffer.reset()
        self.failures_in_a_row = 0
        self._last_increment = None

    def kingpin_increment(self, camera_motion: np.ndarray) -> tuple[float, float, float]:
        """Kingpin increment ``(dx, dy, dψ)`` in the previous trailer frame from one camera motion."""
        m = np.asarray(camera_motion, dtype=float)
        r_mount = self.mount_rotation
        # de Saxe & Cebon 2018, eq (1), generalised to any mounting: camera-frame translation into trailer axes.
        d_camera = (r_mount @ m[:3, 3])[:2]
        # Trailer rotation over the frame, in trailer axes; its yaw about the vertical is Δψ.
        rot = r_mount @ m[:3, :3] @ r_mount.T
        dpsi = math.atan2(rot[1, 0], rot[0, 0])
        # de Saxe & Cebon 2018, eq (2): lever arm from the camera to the kingpin (at the origin).
        c, s = math.cos(dpsi), math.sin(dpsi)
        lever = -self.camera_position
        d_kingpin = d_camera + np.array([c * lever[0] - s * lever[1], s * lever[0] + c * lever[1]]) - lever
        return float(d_kingpin[0]), float(d_kingpin[1]), dpsi

    def update(self, camera_motion: np.ndarray | None) -> float | None:
        """Feed one camera frame's motion (``None`` for a failed frame); return the estimate or ``None``."""
        self.frames += 1
        if camera_motion is None or not np.all(np.isfinite(camera_motion)):
            self.failed_frames += 1
            self.failures_in_a_row += 1
            if self._last_increment is None or self.failures_in_a_row > self.max_consecutive_failures:
                self.reset()
                return None
            self.buffer.push(*self._last_increment)  # constant-velocity bridge over one frame
            return self.buffer.offtracking()
        self.failures_in_a_row = 0
        increment = self.kingpin_increment(camera_motion)
        self._last_increment = increment
        self.buffer.push(*increment)
        return self.buffer.offtracking()
