"""Parameters of the stereo visual odometry (VISO2-S style).

Every default is libviso2's (``Matcher::parameters``, ``VisualOdometry::bucketing`` and
``VisualOdometryStereo::parameters``; docs/visual_odometry.md §2). The calibration (``f``, ``cu``, ``cv``,
``baseline``) has no meaningful default and must be given. Pixel quantities are in pixels of the
full-resolution, rectified image; lengths are in metres.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field

from vehicle_model.settings import Count, Flag, Real, Settings

CovarianceModel = Literal["gauss_newton", "sandwich"]
"""The form of a motion's covariance (:func:`sensor.vo.quality.motion_quality`; :class:`VOConfig`'s
``covariance_model``)."""

GradientRefinement = Literal["off", "lucas_kanade", "lucas_kanade_affine"]
"""The refinement of the matched positions on the grey images (:mod:`sensor.vo.gradient_refinement`;
:class:`VOConfig`'s ``gradient_refinement``)."""

__all__ = ["CovarianceModel", "GradientRefinement", "VOConfig"]

#: Largest ``nms_n`` accepted: the detector breaks ties between equal filter responses with a
#: sub-integer offset pattern whose period is 2·max(nms_n, 10) + 1, which must stay resolvable in float32.
MAX_NMS_N = 10


class VOConfig(Settings):
    """Typed, validated parameters of :class:`sensor.vo.StereoOdometry` (a :class:`vehicle_model.settings.Settings`).

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
    max_disparity : int or None
        Largest disparity [full-resolution px] the stereo steps of the first pass search; ``None``: the flow
        steps' :attr:`search_radius`, as libviso2. A feature whose disparity exceeds it is never matched (nor by
        the second pass, whose ranges come from the first pass's matches), so a rig whose nearest features lie
        closer than ``f·baseline / search_radius`` — a wide baseline, a side camera's near scenery — sees only
        its far features (:func:`sensor.field_optics.road_disparity_search`).
    outlier_disp_tolerance : float
        Delaunay outlier removal: disparity consistency along an edge [px]. libviso2: 5.
    outlier_flow_tolerance : float
        Delaunay outlier removal: flow consistency |Δdu| + |Δdv| along an edge [px]. libviso2: 5.
    multi_stage : bool
        Sparse first pass whose matches bound the search ranges of the dense second pass. libviso2: on.
    half_resolution : bool
        Detect and match on the 2×2 box-downsampled image, refine at full resolution. libviso2: on.
    refinement : int
        0 none, 1 pixel (5×5 relocation), 2 sub-pixel (a fit over a 7×7 cost). libviso2: 1.
    subpixel : {"parabola", "equiangular"}
        The sub-pixel fit of ``refinement=2`` through the cost at the minimum and its neighbours: libviso2's
        parabola, or a symmetric V (equiangular lines; Shimizu & Okutomi 2005), the shape of a sum of absolute
        differences near its minimum. A parabola through a V pulls the vertex towards the nearer integer
        ("pixel locking"); the V does not (docs/visual_odometry.md §8). Default "parabola".
    subpixel_search : {"pixel", "half_pixel"}
        Where ``refinement=2`` looks for the minimum: on whole pixels, the fit in u through the minimum's row and in v
        through its column (libviso2's), or on a grid of half pixels of bilinearly interpolated Sobel responses, the
        fits through the half-pixel neighbours and once more at the other coordinate's fitted position
        (:mod:`sensor.vo.kernels_refine_half`): where a match's true row falls between two pixel rows, a whole
        row's cost on an oblique edge can be lowest a pixel along the edge. Default "pixel".
    gradient_refinement : {"off", "lucas_kanade", "lucas_kanade_affine"}
        After the refinement, ``"lucas_kanade"`` moves the 1p, 2p and 2c positions once more, to the minimum of the
        squared grey-level differences of a window around the fixed 1c position, solved by Gauss–Newton iterations
        on the grey images (Lucas & Kanade 1981; :mod:`sensor.vo.gradient_refinement`): no grid of candidate
        positions for the sub-pixel estimate to be drawn towards. It assumes one exposure for the four images.
        ``"lucas_kanade_affine"`` lets each window's grey levels differ from the 1c window's by a gain and an offset
        of their own, solved with the displacement (the gain and offset projected out; Baker, Gross & Matthews
        2003), so that an exposure, a vignetting or a camera's gain of its own does not move the position.
        Default "off" (libviso2's positions).
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
    covariance_model : {"gauss_newton", "sandwich"}
        The motion's covariance (:func:`sensor.vo.quality.motion_quality`): ``"gauss_newton"`` (default),
        ``σ̂²·(JᵀJ)⁻¹`` of the weighted rows, which takes the reweighting's weights for inverse noise levels;
        ``"sandwich"``, the covariance of the same weighted estimate under pixel noise of one level per image
        coordinate (u and v of the current left and right image), each from its own unweighted residuals, with
        the weights as the estimator's choice only. Default "gauss_newton".
    kalman_smoothing : bool
        Constant-acceleration Kalman filter on the six per-frame motion parameters (mentioned in the
        StereoScan paper, absent from libviso2). Default off.
    kalman_rotation_process_std, kalman_translation_process_std : float
        Process noise: standard deviation of the per-frame change of the motion's acceleration
        [rad/frame³ and m/frame³ — "per frame" because the filter runs at the camera rate].
    kalman_rotation_measurement_std, kalman_translation_measurement_std : float
        Measurement noise of one VO estimate [rad and m per frame].
    """

    f: Real = Field(gt=0.0)
    cu: Real = Field(gt=0.0, description="> 0: the reweighting divides by it")
    cv: Real = Field(gt=0.0)
    baseline: Real = Field(gt=0.0)
    nms_n: Count = Field(3, ge=1, le=MAX_NMS_N)
    nms_tau: Count = Field(50, ge=0)
    match_binsize: Count = Field(50, ge=1)
    match_radius: Count = Field(200, ge=2)
    match_disp_tolerance: Count = Field(2, ge=0)
    max_disparity: Count | None = Field(None, ge=1, description="[px]; None: the search radius (libviso2)")
    outlier_disp_tolerance: Real = Field(5.0, gt=0.0)
    outlier_flow_tolerance: Real = Field(5.0, gt=0.0)
    multi_stage: Flag = True
    half_resolution: Flag = True
    refinement: Count = Field(1, ge=0, le=2)
    subpixel: Literal["parabola", "equiangular"] = "parabola"
    subpixel_search: Literal["pixel", "half_pixel"] = "pixel"
    gradient_refinement: GradientRefinement = "off"
    bucket_width: Real = Field(50.0, gt=0.0)
    bucket_height: Real = Field(50.0, gt=0.0)
    bucket_max_features: Count = Field(2, ge=1)
    ransac_iters: Count = Field(200, ge=1)
    inlier_threshold: Real = Field(2.0, gt=0.0)
    reweighting: Flag = True
    min_inliers: Count = Field(6, ge=3, description="a 6-DoF motion needs 3 points")
    quality_min_inliers: Count = Field(30, ge=0)
    quality_max_residual: Real = Field(1.75, gt=0.0)
    quality_max_translation_sigma: Real = Field(0.03, gt=0.0)
    quality_max_rotation_sigma: Real = Field(0.004, gt=0.0)
    covariance_model: CovarianceModel = "gauss_newton"
    kalman_smoothing: Flag = False
    kalman_rotation_process_std: Real = Field(1e-4, gt=0.0)
    kalman_translation_process_std: Real = Field(1e-3, gt=0.0)
    kalman_rotation_measurement_std: Real = Field(5e-4, gt=0.0)
    kalman_translation_measurement_std: Real = Field(5e-3, gt=0.0)

    # ------------------------------------------------------------------ derived values
    @property
    def scale(self) -> int:
        """Full-resolution pixels per detection pixel: 2 with ``half_resolution``, else 1."""
        return 2 if self.half_resolution else 1

    @property
    def nms_n_sparse(self) -> int:
        """NMS radius of the sparse first-pass features: 3·n, capped at max(n, 10) (docs/visual_odometry.md §3)."""
        n = 3 * self.nms_n
        return max(self.nms_n, 10) if n > 10 else n

    @property
    def search_radius(self) -> int:
        """Effective flow search radius [full-resolution px]: libviso2 halves it at half resolution."""
        return self.match_radius // 2 if self.half_resolution else self.match_radius

    @property
    def stereo_search_radius(self) -> int:
        """Largest disparity the first pass's stereo steps search [full-resolution px]: :attr:`max_disparity`, or
        the flow steps' :attr:`search_radius`."""
        return self.search_radius if self.max_disparity is None else self.max_disparity

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
