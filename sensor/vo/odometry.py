"""Stereo visual odometry in the manner of VISO2-S (Geiger, Ziegler & Stiller 2011; libviso2).

:class:`StereoOdometry` keeps the features of the previous stereo pair; each call of
:meth:`StereoOdometry.process` detects the features of the new pair, matches the four images in a
circle, buckets the matches and estimates the frame-to-frame motion by 3-point RANSAC and
Gauss–Newton on the stereo reprojection error (docs/visual_odometry.md §1; de Saxe & Cebon 2018 §2.1).

Output convention (docs/visual_odometry.md §10): ``motion`` is libviso2's Tr_delta, p_t = Tr_delta·p_{t−1}, which
maps a point from the previous left-camera frame into the current left-camera frame (OpenCV axes:
x right, y down, z forward; metres). ``camera_motion`` = inv(Tr_delta) is the current left camera's
pose in the previous left camera's frame; chaining ``pose = pose @ camera_motion`` integrates the
trajectory.

Quality (:mod:`sensor.vo.quality`): a motion that libviso2 would accept is still refused
(``valid=False``, ``code`` saying why) when it has fewer than ``quality_min_inliers`` inliers, an RMS
reprojection error above ``quality_max_residual`` or a Gauss–Newton covariance above
``quality_max_translation_sigma`` / ``quality_max_rotation_sigma``. The measured values travel with
every result that reached the motion estimation (``residual_px``, ``covariance``), refused or not.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from sensor.vo.config import VOConfig
from sensor.vo.disparity_offset import MatchCorrection
from sensor.vo.features import ImageFeatures, extract_features
from sensor.vo.kalman import MotionKalmanFilter
from sensor.vo.masks import mask_features
from sensor.vo.match_columns import U1C, U2C, V1C, V2C
from sensor.vo.matching import match_frames
from sensor.vo.motion import estimate_motion, params_to_transform, transform_to_params
from sensor.vo.quality import MotionQuality, motion_quality, quality_failure
from vehicle_model.rigid import invert_rigid

__all__ = ["StereoOdometry", "VOResult"]


class _Clock:
    """Wall-clock and thread CPU time of one instant [s]."""

    __slots__ = ("cpu", "wall")

    def __init__(self) -> None:
        self.wall = time.perf_counter()
        self.cpu = time.thread_time()


def _timings(t0: _Clock, t1: _Clock, t2: _Clock, t3: _Clock) -> dict[str, float]:
    """The stage times of a :class:`VOResult` from the instants between its stages."""
    return {
        "time_features": t1.wall - t0.wall,
        "time_matching": t2.wall - t1.wall,
        "time_motion": t3.wall - t2.wall,
        "time_total": t3.wall - t0.wall,
        "cpu_features": t1.cpu - t0.cpu,
        "cpu_matching": t2.cpu - t1.cpu,
        "cpu_motion": t3.cpu - t2.cpu,
    }


@dataclass(frozen=True, eq=False)
class VOResult:
    """Result of one :meth:`StereoOdometry.process` call.

    Attributes
    ----------
    valid : bool
        True when a motion was estimated. False on the first frame, after a reset and for any failed
        frame (too few matches or inliers, no convergence); then ``motion`` is None — unlike
        libviso2, no stale motion is returned.
    motion : numpy.ndarray | None
        4×4 Tr_delta [m]: previous-left-camera coordinates → current-left-camera coordinates.
    n_matches : int
        Matches after outlier removal and bucketing (the input of the motion estimation).
    n_inliers : int
        RANSAC inliers among them (0 when the estimation was not reached).
    time_features, time_matching, time_motion, time_total : float
        Wall-clock time [s] of detection/description, matching (incl. bucketing and refinement),
        motion estimation (incl. the quality checks) and the whole call.
    cpu_features, cpu_matching, cpu_motion : float
        The same stages in CPU time of the calling thread [s] (``time.thread_time``).
    matches : numpy.ndarray
        (n_matches, 8) positions (u1p, v1p, u2p, v2p, u1c, v1c, u2c, v2c) [px].
    inliers : numpy.ndarray
        Boolean inlier mask over ``matches``.
    reason : str
        Why the frame is not valid ("" when valid), in words with the measured value.
    code : str
        Short code of the failure, a key of :data:`sensor.vo.quality.VO_REASONS` ("" when valid;
        also "" for a failure made by hand without one).
    residual_px : float
        RMS unweighted 4-D reprojection error of the inliers [px] (NaN when no motion was refined).
    covariance : numpy.ndarray | None
        6×6 Gauss–Newton covariance of (rx, ry, rz, tx, ty, tz) of Tr_delta [rad², m²] (None when no
        motion was refined).
    """

    valid: bool
    motion: np.ndarray | None
    n_matches: int
    n_inliers: int
    time_features: float
    time_matching: float
    time_motion: float
    time_total: float
    cpu_features: float = 0.0
    cpu_matching: float = 0.0
    cpu_motion: float = 0.0
    matches: np.ndarray = field(default_factory=lambda: np.empty((0, 8)), repr=False)
    inliers: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=bool), repr=False)
    reason: str = ""
    code: str = ""
    residual_px: float = float("nan")
    covariance: np.ndarray | None = field(default=None, repr=False)

    @property
    def translation_sigma_m(self) -> float:
        """Translation standard deviation in its worst direction [m per frame] (NaN if unknown)."""
        return MotionQuality(self.n_inliers, self.residual_px, self.covariance).translation_sigma_m

    @property
    def rotation_sigma_rad(self) -> float:
        """Rotation standard deviation about its worst axis [rad per frame] (NaN if unknown)."""
        return MotionQuality(self.n_inliers, self.residual_px, self.covariance).rotation_sigma_rad

    @property
    def stereo_matches(self) -> np.ndarray:
        """The current pair's stereo matches: (n_matches, 4) read-only (u_l, v_l, u_r, v_r) [px].

        The current-left and current-right columns of ``matches`` (rows as in ``inliers``): what online
        stereo self-calibration (:mod:`sensor.vo.self_calibration`) reads. Empty on the first frame.
        """
        out = self.matches[:, [U1C, V1C, U2C, V2C]] if self.matches.shape[0] else np.empty((0, 4))
        out.setflags(write=False)
        return out

    @property
    def camera_motion(self) -> np.ndarray | None:
        """inv(Tr_delta): the current left camera's pose in the previous left camera's frame."""
        if self.motion is None:
            return None
        return invert_rigid(self.motion)


class StereoOdometry:
    """Frame-to-frame stereo visual odometry (VISO2-S).

    Parameters
    ----------
    config : VOConfig
        Calibration and parameters.
    seed : int | numpy.random.Generator
        Seed of the run's random generator (bucketing and RANSAC samples), or a generator to draw
        from. With an int seed, :meth:`reset` restarts the same random stream, so a reprocessed
        sequence gives identical output.
    match_correction : MatchCorrection, optional
        Corrects each frame's matches before the motion is estimated from them (e.g. the right camera's yaw,
        :class:`sensor.vo.disparity_offset.RoadDisparityOffset`) and adds its own uncertainty to the accepted
        motion's covariance; the result's ``matches`` stay as matched. None: the matches as they are.

    Examples
    --------
    >>> vo = StereoOdometry(config, seed=0)          # doctest: +SKIP
    >>> for left, right in pairs:                    # doctest: +SKIP
    ...     result = vo.process(left, right)
    ...     if result.valid:
    ...         pose = pose @ result.camera_motion
    """

    def __init__(
        self, config: VOConfig, seed: int | np.random.Generator = 0, match_correction: MatchCorrection | None = None
    ) -> None:
        if not isinstance(config, VOConfig):
            raise TypeError(f"config must be a VOConfig, got {type(config).__name__}")
        self.config = config
        self._seed = seed
        self.match_correction = match_correction
        self._kalman = MotionKalmanFilter(config) if config.kalman_smoothing else None
        self.reset()

    def reset(self) -> None:
        """Forget the previous pair, the motion prior and the Kalman state; restart the random stream."""
        self._rng = self._seed if isinstance(self._seed, np.random.Generator) else np.random.default_rng(self._seed)
        self._previous: tuple[ImageFeatures, ImageFeatures] | None = None
        self._prior: np.ndarray | None = None
        if self._kalman is not None:
            self._kalman.reset()
        if self.match_correction is not None:
            self.match_correction.reset()

    def scale_prior(self, ratio: float) -> None:
        """Stretch the next frame's motion prior to an interval ``ratio`` times the last one.

        The constant-velocity prior (docs/visual_odometry.md §5) is the last frame's motion; a recording with uneven
        frame times or a dropped frame moves further (or less) in its next interval. The prior's six parameters
        θ = (rx, ry, rz, tx, ty, tz) are scaled by ``ratio`` — constant velocity in time rather than per frame
        (first order in the rotation). Nothing changes without a prior or with ``ratio`` 1.
        """
        if not (math.isfinite(ratio) and ratio > 0.0):
            raise ValueError(f"ratio must be a finite number > 0, got {ratio!r}")
        if self._prior is not None and ratio != 1.0:
            self._prior = params_to_transform(ratio * transform_to_params(self._prior))

    def process(
        self, left: np.ndarray, right: np.ndarray, masks: tuple[np.ndarray | None, np.ndarray | None] | None = None
    ) -> VOResult:
        """Estimate the motion from the previous stereo pair to this one.

        Parameters
        ----------
        left, right : numpy.ndarray
            Rectified (H, W) uint8 images of the left and right camera.
        masks : (numpy.ndarray or None, numpy.ndarray or None), optional
            ``(H, W)`` bool masks of the left and right image, True where no feature may be taken
            (:mod:`sensor.vo.masks`); None: every feature.

        Returns
        -------
        VOResult
            ``valid=False`` with ``motion=None`` on the first frame and for failed or refused frames
            (too few matches or inliers, no convergence, residual or covariance too large). Unlike
            libviso2, which returns the stale previous motion after a failure, nothing is guessed; the
            caller decides how to bridge the gap.
        """
        if left.shape != right.shape:
            raise ValueError(f"left and right images differ in shape: {left.shape} vs {right.shape}")
        cfg = self.config
        t0 = _Clock()
        current = (extract_features(left, cfg), extract_features(right, cfg))
        if masks is not None:
            current = (mask_features(current[0], masks[0]), mask_features(current[1], masks[1]))
        t1 = _Clock()
        previous, self._previous = self._previous, current
        if previous is None or previous[0].shape != current[0].shape:
            self._prior = None
            return self._failed("no previous stereo pair (of this image size)", t0, t1, t1, code="no_previous_frame")

        xy = match_frames(previous, current, cfg, self._rng, self._prior).matches
        correction = self.match_correction
        used = xy if correction is None else correction.correct(xy)  # the recorded matches stay as matched
        t2 = _Clock()
        estimate = estimate_motion(used, cfg, self._rng)
        quality = MotionQuality(estimate.n_inliers)
        code, reason = estimate.code or "vo_failed", estimate.reason
        if estimate.valid and estimate.params is not None:
            quality = motion_quality(estimate.params, used, estimate.inliers, cfg)
            code, reason = quality_failure(quality, cfg)
            if not code and correction is not None and quality.covariance is not None:
                # after the acceptance: the correction's own uncertainty widens the accepted motion's covariance
                extra = correction.motion_covariance(estimate.params, used, estimate.inliers, cfg)
                quality = MotionQuality(quality.n_inliers, quality.residual_px, quality.covariance + extra)
        if code:
            self._prior = None
            if self._kalman is not None:
                self._kalman.predict()
            return self._failed(reason, t0, t1, t2, xy, estimate.inliers, code, quality)
        motion = estimate.motion
        self._prior = motion  # constant-velocity prior of the next frame's matching (docs/visual_odometry.md §5)
        if self._kalman is not None and estimate.params is not None:
            motion = params_to_transform(self._kalman.update(estimate.params))
        t3 = _Clock()
        return VOResult(
            valid=True,
            motion=motion,
            n_matches=xy.shape[0],
            n_inliers=estimate.n_inliers,
            **_timings(t0, t1, t2, t3),
            matches=xy,
            inliers=estimate.inliers,
            residual_px=quality.residual_px,
            covariance=quality.covariance,
        )

    @staticmethod
    def _failed(
        reason: str,
        t0: _Clock,
        t1: _Clock,
        t2: _Clock,
        xy: np.ndarray | None = None,
        inliers: np.ndarray | None = None,
        code: str = "",
        quality: MotionQuality | None = None,
    ) -> VOResult:
        t3 = _Clock()
        xy = np.empty((0, 8)) if xy is None else xy
        inliers = np.zeros(xy.shape[0], dtype=bool) if inliers is None else inliers
        return VOResult(
            valid=False,
            motion=None,
            n_matches=xy.shape[0],
            n_inliers=int(inliers.sum()),
            **_timings(t0, t1, t2, t3),
            matches=xy,
            inliers=inliers,
            reason=reason,
            code=code,
            residual_px=quality.residual_px if quality is not None else float("nan"),
            covariance=quality.covariance if quality is not None else None,
        )
