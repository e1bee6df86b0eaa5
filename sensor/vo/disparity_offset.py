"""The stereo pair's disparity offset (the right camera's relative yaw) from the road in each frame.

A right camera turned by a yaw ``ψ`` about its optical centre moves every right-image point by
``−f·ψ·(1 + x²)`` (first order; ``x = (u − c_u)/f``; (SC1) of :mod:`sensor.vo.self_calibration`, the axes of the
paper's eq (9)), so a match's disparity is ``f·B/Z + f·ψ·(1 + x_r²)``: a near-constant offset that looks exactly like
a change of depth. A mount that twists with the lateral acceleration changes it from frame to frame, which the
odometry reads as motion along the optical axis, and a constant part changes the scale of that motion.

Measurement (per frame, no truth)
---------------------------------
The road plane ``n·X = h`` in the left camera's axes (``n`` the downward unit normal, ``h`` the mounting height)
predicts the disparity of a road point seen on the left ray ``p_l = (x_l, y_l, 1)``::

    d_plane = f·B·(n·p_l)/h                                                       (DO1)

which is affine in (u, v). A constant offset does not change the plane's slope in the image but its distance,
which the mounting height fixes; so each road match measures ``ψ`` by ``d − d_plane = f·ψ·(1 + x_r²)``.
Matches are road points when ``d_plane`` is at least ``min_road_disparity_px`` and ``d`` lies within
``road_tolerance·d_plane`` of it (a relative height tolerance: kerbs, crops and bodies stand out). The frame's
``ψ`` is the Huber-weighted least-squares fit (Huber 1981; a few IRLS passes on residuals scaled by their MAD)
and its variance the fit's ``s²/Σ w·a²`` with ``s`` the robust scale, floored at ``noise_px``.

What it cannot tell apart: an error of the plane itself. A tilt ``ε`` of the camera towards the road (its pitch
for a side camera, the unit's roll; its roll is harmless) moves ``n·p_l`` by ``ε`` at the image centre, the same
as an offset ``f·B·ε/h``; the estimate is therefore of the offset *relative to the mounting pose*, and a body
that rolls in a turn needs its roll given (not modelled here: the road plane is the mount's).

Filter
------
A scalar Kalman filter of a random walk per frame (``walk_deg`` per frame) from a zero start of
``prior_std_deg``: predict ``P += q²``, update with the frame's measurement. A frame with fewer than
``min_road_points`` road matches gives no measurement (``reason``: ``too_few_road_points``) and the prediction
stands.

Correction
----------
:func:`correct_right_yaw` removes a yaw from the right-image columns of the odometry's matches
(``u_r + f·ψ·(1 + x_r²)``, and ``v_r − f·ψ·x_r·y_r`` of (SC2)); the previous pair's columns with the estimate of
its own frame, the current pair's with this frame's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from pydantic import Field

from vehicle_model.settings import Settings

from .config import VOConfig
from .self_calibration import MAD_SIGMA, RoadPlane, huber_weight, road_matches

__all__ = [
    "DISPARITY_OFFSET_COLUMNS",
    "DisparityOffsetEstimate",
    "DisparityOffsetSettings",
    "MatchCorrection",
    "RoadDisparityOffset",
    "correct_right_yaw",
    "measure_road_yaw",
]

DISPARITY_OFFSET_COLUMNS: tuple[str, ...] = ("yaw_deg", "sigma_deg", "measured_deg", "road_points")
"""Per frame: the filtered right-camera yaw [°] and its std [°], the frame's own measurement [°] (NaN without one)
and the road matches it used."""


class MatchCorrection(Protocol):
    """What :class:`sensor.vo.StereoOdometry` asks of a correction of its matches."""

    def correct(self, xy: np.ndarray) -> np.ndarray:
        """The frame's (N, 8) matches corrected (called once per frame, in order)."""
        ...

    def reset(self) -> None:
        """Forget the frames before."""
        ...

    def motion_covariance(
        self, params: np.ndarray, xy: np.ndarray, inliers: np.ndarray, config: VOConfig
    ) -> np.ndarray:
        """The 6×6 covariance the correction's own uncertainty adds to the motion ``params`` fitted to ``xy``."""
        ...


class DisparityOffsetSettings(Settings):
    """Parameters of :class:`RoadDisparityOffset`, each with its range and the reason for it.

    Attributes
    ----------
    walk_deg : float
        Random walk of the yaw per frame [°] (how fast the filter follows a twist).
    prior_std_deg : float
        Standard deviation of the zero start [°].
    min_road_points : int
        Fewer road matches: no measurement this frame.
    road_tolerance : float
        Relative disparity (height) tolerance of a road point.
    min_road_disparity_px : float
        Smallest plane disparity of a road point [px].
    noise_px : float
        Floor of the robust residual scale [px].
    huber_k : float
        Huber threshold in scales.
    irls_iterations : int
        IRLS passes per frame.
    max_yaw_deg : float
        Measurements beyond ± this are refused (``implausible``) [°].
    """

    walk_deg: float = Field(
        0.005, gt=0.0, le=0.5, description="[°/frame] random walk; 0.5° a frame is no longer a mount's twist"
    )
    prior_std_deg: float = Field(0.2, gt=0.0, le=5.0, description="[°] std of the zero start")
    min_road_points: int = Field(30, ge=5, le=2000, description="road matches needed for a measurement")
    road_tolerance: float = Field(
        0.05, gt=0.0, le=0.5, description="relative height tolerance of a road point; 0.5 takes kerbs for road"
    )
    min_road_disparity_px: float = Field(
        4.0, ge=0.5, le=200.0, description="[px] far road points below this are too uncertain to classify"
    )
    noise_px: float = Field(0.1, ge=0.01, le=5.0, description="[px] floor of the residual scale")
    huber_k: float = Field(1.345, ge=0.5, le=10.0, description="Huber threshold in scales; 1.345 is 95 % efficient")
    irls_iterations: int = Field(3, ge=1, le=20, description="IRLS passes per frame")
    max_yaw_deg: float = Field(1.0, gt=0.0, le=10.0, description="[°] larger measurements are refused")


@dataclass(frozen=True)
class DisparityOffsetEstimate:
    """One frame of :meth:`RoadDisparityOffset.update`.

    Attributes
    ----------
    yaw, sigma : float
        Filtered right-camera yaw and its standard deviation after the frame [rad].
    measured : float
        The frame's own measurement [rad] (NaN without one).
    road_points : int
        Road matches used.
    reason : str
        Why there is no measurement ("" with one): ``too_few_road_points`` or ``implausible``.
    """

    yaw: float
    sigma: float
    measured: float = math.nan
    road_points: int = 0
    reason: str = ""

    def record(self) -> dict[str, float]:
        """The :data:`DISPARITY_OFFSET_COLUMNS` of this frame (angles in degrees)."""
        return {
            "yaw_deg": math.degrees(self.yaw),
            "sigma_deg": math.degrees(self.sigma),
            "measured_deg": math.degrees(self.measured),
            "road_points": float(self.road_points),
        }


def measure_road_yaw(
    matches: np.ndarray, k: np.ndarray, baseline: float, plane: RoadPlane, settings: DisparityOffsetSettings
) -> tuple[float, float, int]:
    """One frame's right-camera yaw from its road matches ((DO1); module docstring).

    Parameters
    ----------
    matches : numpy.ndarray
        (n, 4) stereo matches (u_l, v_l, u_r, v_r) [px] of rectified images with camera matrix ``k``.
    k : numpy.ndarray
        3×3 camera matrix.
    baseline : float
        Stereo baseline [m].
    plane : RoadPlane
        The road plane in left-camera axes (its lateral window is not used).
    settings : DisparityOffsetSettings
        Road-point tolerances and the robust fit's parameters.

    Returns
    -------
    yaw, sigma : float
        The measured yaw and its standard deviation [rad]; NaN with fewer than ``min_road_points`` road matches.
    road_points : int
        Road matches found.
    """
    m = np.asarray(matches, dtype=float).reshape(-1, 4)
    f, cu = float(k[0, 0]), float(k[0, 2])
    xr = (m[:, 2] - cu) / f
    z, road, _ = road_matches(m, k, baseline, plane, settings.min_road_disparity_px, settings.road_tolerance)  # (DO1)
    n = int(road.sum())
    if n < settings.min_road_points:
        return math.nan, math.nan, n
    a, z = f * (1.0 + xr[road] ** 2), z[road]
    yaw = float(np.sum(a * z) / np.sum(a * a))
    w = np.ones(n)
    scale = settings.noise_px
    for _ in range(settings.irls_iterations):
        r = z - a * yaw
        scale = max(settings.noise_px, MAD_SIGMA * float(np.median(np.abs(r - np.median(r)))))
        w = huber_weight(r / scale, settings.huber_k)
        yaw = float(np.sum(w * a * z) / np.sum(w * a * a))
    sigma = scale / math.sqrt(float(np.sum(w * a * a)))
    return yaw, sigma, n


def correct_right_yaw(xy: np.ndarray, f: float, cu: float, cv: float, yaw_previous: float, yaw: float) -> np.ndarray:
    """The odometry's matches with a right-camera yaw removed (module docstring, "Correction").

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 8) matches (u1p, v1p, u2p, v2p, u1c, v1c, u2c, v2c) [px].
    f, cu, cv : float
        Focal length and principal point [px].
    yaw_previous, yaw : float
        The yaw of the previous pair and of the current pair [rad].

    Returns
    -------
    numpy.ndarray
        A corrected copy.
    """
    out = np.array(xy, dtype=float, copy=True)
    for u_col, v_col, psi in ((2, 3, yaw_previous), (6, 7, yaw)):
        if psi == 0.0:
            continue
        x, y = (out[:, u_col] - cu) / f, (out[:, v_col] - cv) / f
        out[:, u_col] += f * psi * (1.0 + x**2)  # (SC1) inverted
        out[:, v_col] -= f * psi * x * y  # (SC2) inverted
    return out


class RoadDisparityOffset:
    """The right camera's yaw relative to the left, frame by frame from the road (module docstring).

    Parameters
    ----------
    k : numpy.ndarray
        3×3 camera matrix of the odometry's (rectified) images.
    baseline : float
        Stereo baseline [m].
    plane : RoadPlane
        The road plane in the left camera's axes (:meth:`RoadPlane.from_camera_pose` of the mount).
    settings : DisparityOffsetSettings
        Parameters.
    """

    def __init__(
        self, k: np.ndarray, baseline: float, plane: RoadPlane, settings: DisparityOffsetSettings | None = None
    ) -> None:
        self.k = np.asarray(k, dtype=float)
        if self.k.shape != (3, 3):
            raise ValueError("k must be a 3×3 camera matrix")
        if not (math.isfinite(baseline) and baseline > 0.0):
            raise ValueError(f"baseline = {baseline!r} must be a finite length > 0 m")
        if not (math.isfinite(plane.height) and plane.height > 0.0):
            raise ValueError(f"the road plane's height = {plane.height!r} must be > 0 m (the camera above the road)")
        self.baseline = float(baseline)
        self.plane = plane
        self.settings = DisparityOffsetSettings() if settings is None else settings
        self.reset()

    def reset(self) -> None:
        """Back to the zero start; no previous pair."""
        self.yaw = 0.0
        self.variance = math.radians(self.settings.prior_std_deg) ** 2
        self.previous_yaw: float | None = None
        self.last = DisparityOffsetEstimate(0.0, math.sqrt(self.variance), reason="too_few_road_points")

    def update(self, stereo_matches: np.ndarray) -> DisparityOffsetEstimate:
        """Predict, then take this frame's road measurement if it has one ((DO1), the filter)."""
        s = self.settings
        self.variance += math.radians(s.walk_deg) ** 2
        yaw, sigma, n = measure_road_yaw(stereo_matches, self.k, self.baseline, self.plane, s)
        reason = ""
        if not math.isfinite(yaw):
            reason = "too_few_road_points"
        elif abs(yaw) > math.radians(s.max_yaw_deg) or not math.isfinite(sigma):
            reason = "implausible"
        if reason:
            self.last = DisparityOffsetEstimate(self.yaw, math.sqrt(self.variance), math.nan, n, reason)
            return self.last
        gain = self.variance / (self.variance + sigma**2)
        self.yaw += gain * (yaw - self.yaw)
        self.variance *= 1.0 - gain
        self.last = DisparityOffsetEstimate(self.yaw, math.sqrt(self.variance), yaw, n)
        return self.last

    def correct(self, xy: np.ndarray) -> np.ndarray:
        """Update with the current pair of ``xy`` (its columns 4–7) and remove the yaw from its right columns:
        the previous pair's with the estimate of its own frame, the current pair's with this frame's."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 8)
        estimate = self.update(xy[:, 4:8])
        previous = estimate.yaw if self.previous_yaw is None else self.previous_yaw
        self.previous_yaw = estimate.yaw
        f, cu, cv = float(self.k[0, 0]), float(self.k[0, 2]), float(self.k[1, 2])
        return correct_right_yaw(xy, f, cu, cv, previous, estimate.yaw)

    def motion_covariance(
        self, params: np.ndarray, xy: np.ndarray, inliers: np.ndarray, config: VOConfig
    ) -> np.ndarray:
        """The covariance the estimate's own uncertainty adds to the motion fitted to the corrected ``xy``.

        Two parts, each the Gauss–Newton step ``Δθ = (JᵀJ)⁻¹·Jᵀ·Δr`` of the inliers' stereo reprojection residuals
        (weighted as in the estimation) when the right columns move by the estimate's standard deviation ``σ``: an
        error common to both pairs (both move; it scales the depths, and so the motion), and one of this frame
        alone (the current pair moves; a change of depth between the frames). The result is ``Σ Δθ·Δθᵀ``.
        """
        from .motion import residuals_and_jacobian, triangulate  # the compiled kernels: only where motion is estimated

        sel = np.flatnonzero(np.asarray(inliers, dtype=bool))
        sigma = self.last.sigma
        if sel.size < 3 or not (math.isfinite(sigma) and sigma > 0.0):
            return np.zeros((6, 6))
        f, cu, cv = float(self.k[0, 0]), float(self.k[0, 2]), float(self.k[1, 2])
        base = np.asarray(xy, dtype=float)[sel]
        obs = base[:, 4:8]
        weights = np.ones(sel.size)
        if config.reweighting:  # as in the estimation (sensor.vo.quality.motion_quality)
            weights = 1.0 / (np.abs(obs[:, 0] - config.cu) / abs(config.cu) + 0.05)
        theta = np.asarray(params, dtype=float)[None]
        r0, jac = residuals_and_jacobian(theta, triangulate(base, config)[None], obs[None], weights[None], config)
        j = jac[0].reshape(-1, 6)
        normal = j.T @ j
        out = np.zeros((6, 6))
        for previous in (sigma, 0.0):  # common to both pairs; this frame's alone
            moved = correct_right_yaw(base, f, cu, cv, previous, sigma)
            r1, _ = residuals_and_jacobian(
                theta, triangulate(moved, config)[None], moved[None, :, 4:8], weights[None], config
            )
            try:
                step = np.linalg.solve(normal, j.T @ (r1[0] - r0[0]).reshape(-1))
            except np.linalg.LinAlgError:
                return np.zeros((6, 6))
            out += np.outer(step, step)
        return out
