"""How well one frame's motion is supported: inliers, reprojection residual, Gauss–Newton covariance.

libviso2 accepts any motion with 6 inliers and a converged refinement (docs/visual_odometry.md §11). That
lets through motions that are numerically fine but physically meaningless: 19 noisy inliers, a
baseline so short that the depths are guesses, a right camera so misaligned that only a handful of
accidental matches survive. This module measures the support of an estimate so that
:class:`~sensor.vo.odometry.StereoOdometry` can refuse it with a reason.

Measures (all over the final RANSAC inliers, at the refined parameters θ̂):

* ``residual_px`` — RMS of the *unweighted* 4-D stereo reprojection error,
  ``sqrt(mean_i ‖(u1c, v1c, u2c, v2c)_i − π(R·P_i + t)‖²)``, the quantity the inlier threshold
  (2 px) bounds per match.
* ``covariance`` — the Gauss–Newton estimate of the parameter covariance,
  ``Σ = σ̂²·(JᵀJ)⁻¹`` with the weighted Jacobian J (4n × 6) and ``σ̂² = ‖r‖²/(4n − 6)`` from the
  weighted residuals r (the weights cancel in the scale). Its translation block gives
  ``translation_sigma_m`` (square root of the largest eigenvalue: the worst direction) and its
  rotation block ``rotation_sigma_rad``. It assumes independent pixel errors and so is optimistic
  for correlated (systematic) errors; it is a floor of the true uncertainty, which is what a
  rejection threshold needs. It also takes the reweighting's weights w for inverse noise levels.
  With ``VOConfig.covariance_model="sandwich"`` the covariance is instead that of the same weighted
  estimate under pixel noise of one level σ_k per image coordinate k ∈ (u1c, v1c, u2c, v2c), the
  weights only the estimator's choice (the sandwich form of White 1980, Econometrica 48(4), 817–838):
  ``Σ = N⁻¹·(Σ_k σ̂_k²·J_kᵀ W² J_k)·N⁻¹`` with ``N = JᵀJ`` of the weighted rows, ``J_k`` the weighted
  rows of coordinate k, ``W = diag(w)`` and ``σ̂_k² = 4·‖r_k‖²/(4n − 6)`` from the unweighted
  residuals of coordinate k. With unit weights and equal ``‖r_k‖`` it is ``σ̂²·(JᵀJ)⁻¹``.

Reason codes of a refused frame are the keys of :data:`VO_REASONS`. :data:`REJECTION_REASONS` is the
whole table of the camera estimator — these, VISO-OT's plausibility failures and the reasons for a
missing estimate (:mod:`sensor.viso_ot`) — and :data:`QUALITY_COLUMNS` the names of a frame's quality
measures (:class:`sensor.frame_odometry.CameraFrame`). Importing this module is light (numpy,
no OpenCV): result writers may read the tables without loading the odometry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sensor.viso_ot import ESTIMATE_REASONS, PLAUSIBILITY_REASONS, STEP_COLUMNS
from sensor.vo.config import VOConfig
from sensor.vo.motion import residuals_and_jacobian, triangulate

__all__ = [
    "QUALITY_COLUMNS",
    "REJECTION_REASONS",
    "VO_REASONS",
    "MotionQuality",
    "motion_quality",
    "quality_failure",
]


def _default(name: str) -> float:
    """Default value of a :class:`VOConfig` field (the thresholds quoted in the reason sentences)."""
    return VOConfig.model_fields[name].default  # type: ignore[no-any-return]


#: Reason codes of a frame without a motion, with one sentence each (thresholds: the defaults).
VO_REASONS: dict[str, str] = {
    "no_previous_frame": "there is no previous stereo pair to measure the motion against (first frame or reset)",
    "too_few_matches": "fewer than 6 stereo matches survived the circular matching and the outlier removal",
    "too_few_inliers": (f"fewer than {_default('quality_min_inliers')} inlier matches support the motion"),
    "not_converged": "the Gauss-Newton refinement of the motion did not converge",
    "residual_too_large": (
        f"the RMS reprojection error of the inliers exceeds {_default('quality_max_residual'):g} px"
    ),
    "motion_uncertain": (
        "the Gauss-Newton covariance of the motion is too large (translation standard deviation above "
        f"{1e3 * _default('quality_max_translation_sigma'):g} mm or rotation above "
        f"{math.degrees(_default('quality_max_rotation_sigma')):.2g}° per frame)"
    ),
}

#: Every reason code of a camera frame whose motion was not accepted, and of a missing estimate, with one
#: sentence each. The order is fixed (a code's index in ``list(REJECTION_REASONS)`` may be stored):
#: odometry failures, VISO-OT's plausibility failures, then the reasons for a missing estimate.
REJECTION_REASONS: dict[str, str] = {
    "vo_failed": "the visual odometry reported a failed frame without a reason",
    **VO_REASONS,
    **PLAUSIBILITY_REASONS,
    **ESTIMATE_REASONS,
}

#: Names of a camera frame's quality measures (SI units; NaN where not applicable): matches and inliers
#: of the motion estimation, the inlier ratio, the inliers' RMS reprojection error, the Gauss–Newton
#: standard deviations of the frame's translation and rotation (worst direction), and the rates the step
#: implies for the trailer (kingpin speed, yaw rate, pitch/roll rate, vertical speed of the camera).
QUALITY_COLUMNS: tuple[str, ...] = (
    "matches",
    "inliers",
    "inlier_ratio",
    "residual_px",
    "translation_sigma_m",
    "rotation_sigma_rad",
    *STEP_COLUMNS,
)


@dataclass(frozen=True, eq=False)
class MotionQuality:
    """Support of one motion estimate.

    Attributes
    ----------
    n_inliers : int
        Inliers of the final refinement.
    residual_px : float
        RMS unweighted 4-D reprojection error of the inliers [px]; NaN without an estimate.
    covariance : numpy.ndarray | None
        6×6 covariance of θ = (rx, ry, rz, tx, ty, tz) [rad², m²]; None without an estimate,
        ``inf`` entries when the normal matrix is singular.
    """

    n_inliers: int
    residual_px: float = math.nan
    covariance: np.ndarray | None = None

    @property
    def translation_sigma_m(self) -> float:
        """Standard deviation of the translation in its worst direction [m per frame] (NaN if unknown)."""
        return _worst_sigma(self.covariance, slice(3, 6))

    @property
    def rotation_sigma_rad(self) -> float:
        """Standard deviation of the rotation about its worst axis [rad per frame] (NaN if unknown)."""
        return _worst_sigma(self.covariance, slice(0, 3))


def _worst_sigma(covariance: np.ndarray | None, block: slice) -> float:
    if covariance is None:
        return math.nan
    sub = covariance[block, block]
    if not np.all(np.isfinite(sub)):
        return math.inf
    return float(math.sqrt(max(float(np.linalg.eigvalsh(0.5 * (sub + sub.T)).max()), 0.0)))


def motion_quality(params: np.ndarray, xy: np.ndarray, inliers: np.ndarray, config: VOConfig) -> MotionQuality:
    """Residual and Gauss–Newton covariance of a motion over its inliers.

    Parameters
    ----------
    params : numpy.ndarray
        Refined θ = (rx, ry, rz, tx, ty, tz) of Tr_delta.
    xy : numpy.ndarray
        (N, 8) matches the motion was estimated from.
    inliers : numpy.ndarray
        Boolean mask of the inliers over ``xy``.
    config : VOConfig
        Calibration (and whether observations are reweighted, as in the estimation).

    Returns
    -------
    MotionQuality
        See the module notes for the definitions.
    """
    sel = np.flatnonzero(inliers)
    n = sel.shape[0]
    if n == 0:
        return MotionQuality(0)
    points = triangulate(xy[sel], config)
    obs = xy[sel, 4:8]
    ones = np.ones(n)
    # Unweighted residuals for the RMS error; weighted ones (as in the estimation) for the covariance.
    plain, _ = residuals_and_jacobian(params[None], points[None], obs[None], ones[None], config)
    residual = float(math.sqrt(np.mean(np.sum(plain[0] ** 2, axis=1))))
    if config.reweighting:
        weights = 1.0 / (np.abs(obs[:, 0] - config.cu) / abs(config.cu) + 0.05)
    else:
        weights = ones
    res, jac = residuals_and_jacobian(params[None], points[None], obs[None], weights[None], config)
    j = jac[0].reshape(-1, 6)
    dof = j.shape[0] - 6
    if dof <= 0:
        return MotionQuality(n, residual, np.full((6, 6), np.inf))
    sigma2 = float(np.sum(res**2)) / dof
    normal = j.T @ j
    try:
        cov = sigma2 * np.linalg.inv(normal)
        if config.covariance_model == "sandwich":
            cov = _sandwich(np.linalg.inv(normal), jac[0], plain[0], weights, dof)
    except np.linalg.LinAlgError:
        cov = np.full((6, 6), np.inf)
    if not np.all(np.isfinite(cov)) or np.linalg.cond(normal) > 1e14:
        cov = np.full((6, 6), np.inf)
    return MotionQuality(n, residual, cov)


def _sandwich(inverse: np.ndarray, jac: np.ndarray, plain: np.ndarray, weights: np.ndarray, dof: int) -> np.ndarray:
    """``N⁻¹·(Σ_k σ̂_k²·J_kᵀ W² J_k)·N⁻¹`` of the module notes: ``inverse`` N⁻¹, ``jac`` the (n, 4, 6) weighted
    rows, ``plain`` the (n, 4) unweighted residuals, ``weights`` w (n), ``dof`` 4n − 6."""
    meat = np.zeros((6, 6))
    for k in range(4):
        rows = jac[:, k, :]
        scale = 4.0 * float(plain[:, k] @ plain[:, k]) / dof
        meat += scale * (rows.T * weights**2) @ rows
    return inverse @ meat @ inverse  # type: ignore[no-any-return]


def quality_failure(quality: MotionQuality, config: VOConfig) -> tuple[str, str]:
    """The first quality threshold a motion fails, as (code, message); ``("", "")`` when it passes.

    Parameters
    ----------
    quality : MotionQuality
        Support of the motion.
    config : VOConfig
        Thresholds ``quality_min_inliers``, ``quality_max_residual``, ``quality_max_translation_sigma``
        and ``quality_max_rotation_sigma``.

    Returns
    -------
    tuple[str, str]
        A key of :data:`VO_REASONS` and a message with the measured value.
    """
    if quality.n_inliers < config.quality_min_inliers:
        return "too_few_inliers", f"too few inliers ({quality.n_inliers} < {config.quality_min_inliers})"
    if not quality.residual_px <= config.quality_max_residual:
        return "residual_too_large", (
            f"RMS reprojection error {quality.residual_px:.3g} px > {config.quality_max_residual:g} px"
        )
    t_sigma, r_sigma = quality.translation_sigma_m, quality.rotation_sigma_rad
    if not t_sigma <= config.quality_max_translation_sigma:
        return "motion_uncertain", (
            f"translation standard deviation {t_sigma:.3g} m > {config.quality_max_translation_sigma:g} m"
        )
    if not r_sigma <= config.quality_max_rotation_sigma:
        return "motion_uncertain", (
            f"rotation standard deviation {r_sigma:.3g} rad > {config.quality_max_rotation_sigma:g} rad"
        )
    return "", ""
