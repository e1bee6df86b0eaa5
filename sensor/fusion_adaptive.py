"""The camera's covariance sized by what the filter measures of it: the camera motions' recent innovations.

The odometry's Gauss–Newton covariance times ``vo_covariance_scale`` ``s₀`` is a floor of the camera motion's
error; on rough ground the motions err by more than it says, on smooth ground by about what it says. Each motion's
normalised innovation squared against the covariance the filter had before any growth,
``ν_k = yᵀ (H P Hᵀ + R_k)⁻¹ y`` (``R_k`` the motion's covariance at ``s₀``, ``y`` its innovation, refused motions
included), is a χ²₃ draw where ``R_k`` is right and that times ``m`` where it is ``m`` times too small (``H P Hᵀ``
small beside it). So with ``vo_covariance_adaptive`` each motion's covariance is taken times::

    m_k = min(f_max, max(1, median(ν_{k−N}, …, ν_{k−1}) / med χ²₃))                                  (V1)

(docs/fusion.md eq (V1)): the median over the ``N`` = ``vo_adaptive_window`` motions before it (the motion itself is
not among them: a motion does not widen its own covariance; the median, so a few wild motions do not widen the
rest), ``med χ²₃`` = 2.366 the median of a χ²₃ variable, ``f_max`` = ``vo_adaptive_max_factor``; 1 (the covariance at
``s₀``, the floor) until ``N`` motions have been seen. Where ``H P Hᵀ`` is not small beside ``R_k`` the median
under-states ``m`` (the prediction's share of ``ν`` is not widened): it errs towards the covariance at ``s₀``. Off
(the default) the covariance is the one at ``s₀``, the same array.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from .fusion_noise import FusionNoise

__all__ = ["CHI2_3_MEDIAN", "AdaptiveCovariance"]

CHI2_3_MEDIAN = 2.3659738843753377
"""The median of a χ²₃ variable (``scipy.stats.chi2(3).median()``)."""


class AdaptiveCovariance:
    """The factor ``m`` of eq (V1) on each camera motion's covariance, from the motions before it.

    Parameters
    ----------
    noise
        The filter's settings: ``vo_covariance_adaptive`` (off: :meth:`scaled` gives the covariance back as it is),
        ``vo_adaptive_window`` ``N`` and ``vo_adaptive_max_factor`` ``f_max``.

    Attributes
    ----------
    factor : float
        ``m`` for the next motion, in ``[1, f_max]`` (1 while off or before ``N`` motions).
    """

    def __init__(self, noise: FusionNoise) -> None:
        self.on = noise.vo_covariance_adaptive
        self.max_factor = noise.vo_adaptive_max_factor
        self._nis: deque[float] = deque(maxlen=noise.vo_adaptive_window)
        self.factor = 1.0

    def scaled(self, r: np.ndarray) -> np.ndarray:
        """The covariance ``r`` (3×3, at ``vo_covariance_scale``) the motion is taken with: ``m·r``, or ``r`` itself
        while off."""
        return self.factor * r if self.on else r

    def observe(self, h: np.ndarray, p: np.ndarray, innovation: np.ndarray, r: np.ndarray) -> None:
        """Take one motion's innovation ``innovation`` (3) against the prediction's covariance ``p`` through ``h``
        (3×n) and its covariance ``r`` at ``vo_covariance_scale``, used or refused; ``m`` of (V1) for the next."""
        if not self.on:
            return
        s = h @ p @ h.T + r
        self._nis.append(float(innovation @ np.linalg.solve(s, innovation)))
        if len(self._nis) == self._nis.maxlen:  # docs/fusion.md eq (V1)
            self.factor = min(self.max_factor, max(1.0, float(np.median(self._nis)) / CHI2_3_MEDIAN))
