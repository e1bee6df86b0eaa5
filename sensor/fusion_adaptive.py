"""The camera's covariance sized by the ground's roughness the rig measures itself: each frame's tilt.

On rough ground a camera frame whose trailer pitches or rolls errs laterally far more than the odometry's
Gauss–Newton covariance says (the tilt moves the ground under a camera mounted metres above it), while frames over
level stretches of the same ground err as on smooth ground. The odometry measures the tilt itself: the angle ``θ``
between the unit's vertical axis before and after the frame, from the frame's own rotation (as
:meth:`~sensor.viso_ot.VisoOtEstimator.step_measures` gives it as a rate). With ``vo_tilt_reference`` ``θ₀`` set,
the factor on the odometry's covariance grows with it, between today's ``vo_covariance_scale`` ``s₀`` (the floor)
and ``vo_tilt_max_factor`` ``f_max`` times that (the ceiling)::

    s(θ) = s₀ · min(f_max, max(1, (θ/θ₀)²))                                                          (V1)

(docs/fusion.md eq (V1)): a lateral error growing as a lever times the tilt, ``(θ/θ₀)²`` the variance it adds
relative to the frame's own where it dominates. ``θ₀`` 0 (the default) is off: ``s₀`` for every frame, the
covariance of :func:`~sensor.fusion_model.camera_increment` unchanged to the bit.
"""

from __future__ import annotations

import math

import numpy as np

from .fusion_noise import FusionNoise

__all__ = ["covariance_scale", "frame_tilt"]


def frame_tilt(mount_rotation: np.ndarray, camera_motion: np.ndarray) -> float:
    """The unit's tilt over one frame [rad]: the angle between its vertical axis before and after the motion.

    Parameters
    ----------
    mount_rotation
        3×3 rotation of the camera's axes into the unit's (:attr:`~sensor.viso_ot.VisoOtEstimator.mount_rotation`).
    camera_motion
        4×4 camera motion of the frame (as :meth:`~sensor.fusion.FusedVisoOt.measure` takes it).

    Returns
    -------
    float
        ``acos`` of the vertical component of the unit's vertical axis after the rotation, in ``[0, π]``.
    """
    r = np.asarray(mount_rotation, dtype=float)
    rot = r @ np.asarray(camera_motion, dtype=float)[:3, :3] @ r.T  # the unit's rotation over the frame
    return math.acos(min(1.0, max(-1.0, float(rot[2, 2]))))


def covariance_scale(noise: FusionNoise, mount_rotation: np.ndarray, camera_motion: np.ndarray) -> float:
    """The factor ``s`` of eq (V1) on the odometry's covariance for one frame.

    Parameters
    ----------
    noise
        The filter's settings: ``vo_covariance_scale`` ``s₀``,
        ``vo_tilt_reference`` ``θ₀`` [rad] (0: off) and ``vo_tilt_max_factor`` ``f_max``.
    mount_rotation, camera_motion
        As :func:`frame_tilt`.

    Returns
    -------
    float
        ``s₀`` itself (the same float) when ``θ₀`` is 0, else ``s(θ)`` of (V1), in ``[s₀, f_max·s₀]``.
    """
    floor = noise.vo_covariance_scale
    if noise.vo_tilt_reference <= 0.0:
        return floor
    ratio = frame_tilt(mount_rotation, camera_motion) / noise.vo_tilt_reference
    return floor * min(noise.vo_tilt_max_factor, max(1.0, ratio * ratio))  # docs/fusion.md eq (V1)
