"""Parameters of the stereo visual odometry (VISO2-S style).

Every default is libviso2's (``Matcher::parameters``, ``VisualOdometry::bucketing`` and
``VisualOdometryStereo::parameters``; viso2s reference §1.1). The calibration (``f``, ``cu``, ``cv``,
``baseline``) has no meaningful default and must be given. Pixel quantities are in pixels of the
full-resolution, rectified image; lengths are in metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

__all__ = ["VOConfig"]

#: Largest ``nms_n`` accepted: the detector breaks ties between equal filter responses with a
#: sub-integer offset pattern whose period is 2·max(nms_n, 10) + 1, which must stay resolvable in float32.
MAX_NMS_N = 10


@dataclass(frozen=True)
class VOConfig:
    """Typed, validated parameters of :class:`sensor.vo.StereoOdometry`.

    Parameters
    ----------
    f : float
        Focal length [px] of the rectified pair (both cameras).
    cu, cv : float
        Principal point [px] (column, row), pixel centres at integer coordinates.
    baseline : float
        Stereo baseline [m]; the right camera sits at +baseline along the left camera's x axis.
    nms_n : int
        Non-maximum suppression radius [px, detection resolution]: extrema are strict within a
        (2n+1)² window, so two features of one class are more than n px apart. libviso2: 3.
    nms_tau : int
        Feature threshold on the filter response, |response| ≥ tau. libviso2: 50.
    match_binsize : int
        Bin size [px] of the prior search-range statistics (pooled over 3×3 bins). libviso2: 50.
    match_radius : int
        Search radius [px] of the flow steps without a prior. As in libviso2 it is halved
        internally when ``half_resolution`` is on (so the default searches ±100 px). libviso2: 200.
    match_disp_tolerance : int
        Row tolerance [px] of the stereo (left↔right) steps, |Δv| ≤ tolerance. libviso2: 2.
    outlier_disp_tolerance : float
        Delaunay outlier removal: disparity consistency along an edge [px]. libviso2: 5.
    outlier_flow_tolerance : float
        Delaunay outlier removal: flow consistency |Δdu| + |Δdv| along an edge [px]. libviso2: 5.
    multi_stage : bool
        Sparse first pass whose matches bound the search ranges of the dense second pass. libviso2: on.
    half_resolution : bool
        Detect and match on the 2×2 box-downsampled image, refine at full resolution. libviso2: on.
    refinement : int
        0 none, 1 pixel (5×5 relocation), 2 sub-pixel (parabolic fit over a 7×7 cost). libviso2: 1.
    bucket_width, bucket_height : float
        Bucket size [px] of the final match selection. libviso2: 50 × 50.
    bucket_max_features : int
        Matches kept per bucket (random choice). libviso2: 2.
    ransac_iters : int
        RANSAC hypotheses (3-point samples). libviso2: 200 (the StereoScan paper used 50).
    inlier_threshold : float
        Inlier threshold [px] on the unweighted 4-D stereo reprojection error. libviso2: 2.0.
    reweighting : bool
        Down-weight observations far from the principal column, w = 1/(|u − cu|/|cu| + 0.05).
        libviso2: on.
    min_inliers : int
        Fewer inliers than this is a failed frame. libviso2: 6.
    quality_min_inliers : int
        Fewer inliers than this is a motion too poorly supported to use (not in libviso2; see
        :mod:`sensor.vo.quality`). Default 30: ideal rendered frames have 130–300 inliers (50–140
        with side-facing cameras on a 2.5 m baseline), while with fewer than about 30 a few wrong
        matches that pass the 2 px test pull the motion visibly (``noise_std`` = 50: 10–31
        inliers and a 0.5 m off-tracking error).
    quality_max_residual : float
        Largest RMS unweighted 4-D reprojection error [px] of the inliers. Default 1.75 px: ideal
        frames show 0.9–1.3 px (pixel refinement on the half-resolution grid), at most 1.55 px on a
        2.5 m side-camera baseline; errors spread uniformly over the 2 px inlier ball give 1.63 px,
        so a set near 2 px is the tail of a spread of bad matches, not a motion.
    quality_max_translation_sigma : float
        Largest translation standard deviation [m per frame] from the Gauss–Newton covariance
        σ̂²·(JᵀJ)⁻¹ (worst direction). Default 0.03 m: the ~24 frames (10 Hz, 5 m/s) over a 12 m
        trailer add up as a random walk to ``σ·√24``, which must stay within the 0.15 m maximum
        off-tracking error. Ideal frames: 1.5–5 mm (14 mm with a 2.5 m side baseline); a 0.01 m
        baseline gives 17–160 m.
    quality_max_rotation_sigma : float
        Largest rotation standard deviation [rad per frame] from the covariance (worst axis).
        Default 0.004 rad (0.23°): a heading random walk over N frames of a trailer length L
        moves the far end of the path by ``σ·L·√(N/3)`` ≈ 34·σ for L = 12 m, N = 24, again
        against 0.15 m. Ideal frames: 0.1–0.6 mrad.
    kalman_smoothing : bool
        Constant-acceleration Kalman filter on the six per-frame motion parameters (mentioned in the
        StereoScan paper, absent from libviso2). Default off.
    kalman_rotation_process_std, kalman_translation_process_std : float
        Process noise: standard deviation of the per-frame change of the motion's acceleration
        [rad/frame³ and m/frame³ — "per frame" because the filter runs at the camera rate].
    kalman_rotation_measurement_std, kalman_translation_measurement_std : float
        Measurement noise of one VO estimate [rad and m per frame].
    """

    f: float
    cu: float
    cv: float
    baseline: float
    nms_n: int = 3
    nms_tau: int = 50
    match_binsize: int = 50
    match_radius: int = 200
    match_disp_tolerance: int = 2
    outlier_disp_tolerance: float = 5.0
    outlier_flow_tolerance: float = 5.0
    multi_stage: bool = True
    half_resolution: bool = True
    refinement: int = 1
    bucket_width: float = 50.0
    bucket_height: float = 50.0
    bucket_max_features: int = 2
    ransac_iters: int = 200
    inlier_threshold: float = 2.0
    reweighting: bool = True
    min_inliers: int = 6
    quality_min_inliers: int = 30
    quality_max_residual: float = 1.75
    quality_max_translation_sigma: float = 0.03
    quality_max_rotation_sigma: float = 0.004
    kalman_smoothing: bool = False
    kalman_rotation_process_std: float = 1e-4
    kalman_translation_process_std: float = 1e-3
    kalman_rotation_measurement_std: float = 5e-4
    kalman_translation_measurement_std: float = 5e-3

    def __post_init__(self) -> None:
        errors: list[str] = []
        spec = {f.name: f.type for f in fields(self)}
        for name, kind in spec.items():
            value = getattr(self, name)
            if kind == "bool":
                if value not in (0, 1) or isinstance(value, float):
                    errors.append(f"{name} must be a bool (or 0/1), got {value!r}")
                else:
                    object.__setattr__(self, name, bool(value))
            elif kind == "int":
                if isinstance(value, bool) or not isinstance(value, int):
                    errors.append(f"{name} must be an int, got {value!r}")
            else:
                if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                    errors.append(f"{name} must be a finite number, got {value!r}")
        if errors:
            raise ValueError("invalid VOConfig: " + "; ".join(errors))

        def check(ok: bool, message: str) -> None:
            if not ok:
                errors.append(message)

        check(self.f > 0, f"f must be > 0 px, got {self.f}")
        check(self.cu > 0, f"cu must be > 0 px (reweighting divides by it), got {self.cu}")
        check(self.cv > 0, f"cv must be > 0 px, got {self.cv}")
        check(self.baseline > 0, f"baseline must be > 0 m, got {self.baseline}")
        check(1 <= self.nms_n <= MAX_NMS_N, f"nms_n must be in [1, {MAX_NMS_N}] px, got {self.nms_n}")
        check(self.nms_tau >= 0, f"nms_tau must be ≥ 0, got {self.nms_tau}")
        check(self.match_binsize >= 1, f"match_binsize must be ≥ 1 px, got {self.match_binsize}")
        check(self.match_radius >= 2, f"match_radius must be ≥ 2 px, got {self.match_radius}")
        check(self.match_disp_tolerance >= 0, f"match_disp_tolerance must be ≥ 0 px, got {self.match_disp_tolerance}")
        check(
            self.outlier_disp_tolerance > 0, f"outlier_disp_tolerance must be > 0 px, got {self.outlier_disp_tolerance}"
        )
        check(
            self.outlier_flow_tolerance > 0, f"outlier_flow_tolerance must be > 0 px, got {self.outlier_flow_tolerance}"
        )
        check(self.refinement in (0, 1, 2), f"refinement must be 0, 1 or 2, got {self.refinement}")
        check(self.bucket_width > 0, f"bucket_width must be > 0 px, got {self.bucket_width}")
        check(self.bucket_height > 0, f"bucket_height must be > 0 px, got {self.bucket_height}")
        check(self.bucket_max_features >= 1, f"bucket_max_features must be ≥ 1, got {self.bucket_max_features}")
        check(self.ransac_iters >= 1, f"ransac_iters must be ≥ 1, got {self.ransac_iters}")
        check(self.inlier_threshold > 0, f"inlier_threshold must be > 0 px, got {self.inlier_threshold}")
        check(self.min_inliers >= 3, f"min_inliers must be ≥ 3 (a 6-DoF motion needs 3 points), got {self.min_inliers}")
        check(self.quality_min_inliers >= 0, f"quality_min_inliers must be ≥ 0, got {self.quality_min_inliers}")
        for name in (
            "quality_max_residual",
            "quality_max_translation_sigma",
            "quality_max_rotation_sigma",
            "kalman_rotation_process_std",
            "kalman_translation_process_std",
            "kalman_rotation_measurement_std",
            "kalman_translation_measurement_std",
        ):
            check(getattr(self, name) > 0, f"{name} must be > 0, got {getattr(self, name)}")
        if errors:
            raise ValueError("invalid VOConfig: " + "; ".join(errors))

    # ------------------------------------------------------------------ derived values
    @property
    def scale(self) -> int:
        """Full-resolution pixels per detection pixel: 2 with ``half_resolution``, else 1."""
        return 2 if self.half_resolution else 1

    @property
    def nms_n_sparse(self) -> int:
        """NMS radius of the sparse first-pass features: 3·n, capped at max(n, 10) (reference §1.2)."""
        n = 3 * self.nms_n
        return max(self.nms_n, 10) if n > 10 else n

    @property
    def search_radius(self) -> int:
        """Effective flow search radius [full-resolution px]: libviso2 halves it at half resolution."""
        return self.match_radius // 2 if self.half_resolution else self.match_radius

    @classmethod
    def from_horizontal_fov(
        cls, width: int, height: int, horizontal_fov: float, baseline: float, **overrides: object
    ) -> VOConfig:
        """Pinhole calibration from the image size and horizontal field of view.

        Parameters
        ----------
        width, height : int
            Image size [px].
        horizontal_fov : float
            Full horizontal field of view [rad].
        baseline : float
            Stereo baseline [m].
        **overrides
            Any other :class:`VOConfig` field.

        Returns
        -------
        VOConfig
            With f = (width/2)/tan(fov/2) and the principal point at the image centre
            ((width−1)/2, (height−1)/2) in the pixel-centre convention.
        """
        if not (0 < horizontal_fov < math.pi):
            raise ValueError(f"horizontal_fov must be in (0, π) rad, got {horizontal_fov}")
        if width < 2 or height < 2:
            raise ValueError(f"image size must be at least 2×2 px, got {width}×{height}")
        f = 0.5 * width / math.tan(0.5 * horizontal_fov)
        return cls(f=f, cu=0.5 * (width - 1), cv=0.5 * (height - 1), baseline=baseline, **overrides)  # type: ignore[arg-type]
