"""Stereo visual odometry in the manner of VISO2-S (Geiger, Ziegler & Stiller 2011, libviso2).

Public API: :class:`VOConfig` (parameters, libviso2 defaults), :class:`StereoOdometry`
(``process(left, right) -> VOResult``, ``reset()``) and :class:`VOResult`. The building blocks live in
:mod:`sensor.vo.features` (detection, descriptors), :mod:`sensor.vo.matching` (circular matching of two
stereo pairs) with its stages :mod:`sensor.vo.prior_ranges`, :mod:`sensor.vo.outliers`,
:mod:`sensor.vo.bucketing`, :mod:`sensor.vo.refinement` and :mod:`sensor.vo.gradient_refinement` (match array
columns in :mod:`sensor.vo.match_columns`), :mod:`sensor.vo.motion` and :mod:`sensor.vo.kalman`; the tests'
``vo_synthetic`` makes test data with exact ground truth. The hot loops are compiled with
numba (:mod:`sensor.vo.jit`, cached on disk): :mod:`sensor.vo.kernels_features`,
:mod:`sensor.vo.kernels_search` and :mod:`sensor.vo.kernels_circle` (the candidate search and the
circle), :mod:`sensor.vo.kernels_match` (positions, Delaunay support, refinement) and
:mod:`sensor.vo.kernels_motion` (Gauss–Newton, RANSAC). The speed is measured by ``offtrack bench vo``
(:mod:`scenarios.bench.vo`).

This is a re-implementation from the algorithm's description (``docs/visual_odometry.md``),
not a port: no libviso2 code is used. Where it knowingly differs from libviso2:

* A failed frame returns ``valid=False`` and no motion; libviso2 keeps returning the stale previous
  motion. After a failure the next frame is matched without the motion prior.
* Non-maximum suppression keeps strict local extrema (ties broken by a fixed pattern) instead of
  reproducing the block algorithm's tie behaviour.
* Stereo steps only consider candidates with u_left ≥ u_right (libviso2 checks the sign after the
  circle closes).
* The Delaunay outlier check of the dense pass sees pixel-grid positions (it runs before the
  refinement; libviso2 refines first); an edge must be consistent in both disparities and the flow.
  Bucketing precedes the refinement, which gives the same result as refining first.
* The refinement's 16-byte descriptor (du at 12, dv at 4 offsets of the 5×5 window) follows the
  description, not libviso2's exact layout; OpenCV rounds the Sobel scaling where libviso2 shifts.
* Random choices (bucketing, RANSAC samples) come from the run's ``numpy.random.Generator``.
* The optional constant-acceleration Kalman smoothing (StereoScan paper) is not in libviso2.
* A motion libviso2 would accept is refused when it is poorly supported (too few inliers, large
  residual or covariance; :mod:`sensor.vo.quality`).

:class:`StereoOdometry` and :class:`VOResult` are loaded on first access (they pull in OpenCV), so that
``sensor.vo.quality``'s tables and ``sensor.vo.config`` import without it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from sensor.vo.config import VOConfig

if TYPE_CHECKING:
    from sensor.vo.odometry import StereoOdometry, VOResult

__all__ = ["StereoOdometry", "VOConfig", "VOResult"]


def __getattr__(name: str) -> Any:
    """Load the odometry (OpenCV, SciPy) on first use, so that light submodules stay light to import."""
    if name in ("StereoOdometry", "VOResult"):
        from sensor.vo import odometry

        return getattr(odometry, name)
    raise AttributeError(f"module 'sensor.vo' has no attribute {name!r}")
