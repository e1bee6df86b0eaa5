"""The lasting part of eq (3)'s coupling: its ratio to the frames' own, estimated online.

Eq (3) of :mod:`sensor.fusion_model` couples to the odometry's lasting yaw error ``β_ψ`` the translation ``κ·c``:
``c`` the frame's own regression of translation error on yaw error (its covariance), ``κ`` = ``vo_bias_coupling``, a
factor measured frame by frame. A camera's lasting error need not keep the frames' proportion (docs/field_bias.md
§7.48: frame by frame 24–26 m of lateral per radian of yaw, over a run 15–18 m). With ``vo_coupling_learned`` the
lasting part is taken at ``ρ·κ·c``, the ratio ``ρ`` estimated from the frames.

Each frame used measures ``ρ`` against the filter's references for the two directions: the camera's yaw against the
gyro's heading (``δψ = z_ψ − Δψ̂``, which is ``d·β_ψ`` plus the frame's noise) and its lateral step against the zero-slip
kinematics' (``δy = z_y − y_k``, ``y_k`` of (K1) over the frame, :func:`sensor.fusion_slip.kinematic_lateral_step`).
The frame's noise keeps the frames' proportion ``g = κ·c_y`` (that is what ``κ`` was measured on), so taking
``g·(δψ − d·β̂_ψ)`` off the lateral leaves the lasting lateral error and noise uncorrelated with the yaw's::

    ℓ = δy − g·(δψ − d·β̂_ψ) = ρ·a + n,    a = d·β̂_ψ·g                                              (L1)

(``d`` the distance since the anchor, ``β̂_ψ`` the prior estimate at the frame). ``ρ`` is the weighted least-squares
slope of ``ℓ`` on ``a`` with a Gaussian prior ``ρ ~ N(1, σ_ρ²)`` (``σ_ρ`` = ``vo_coupling_prior``, by default the
coupling's stated uncertainty: eq (3)'s proportion until the frames say otherwise), the frames forgotten over the
distance ``D`` = ``vo_coupling_memory``::

    N ← f·N + (1 − f)/σ_ρ² + a·ℓ/s²,   M ← f·M + (1 − f)/σ_ρ² + a²/s²,   f = exp(−|d|/D),
    ρ̂ = min(ρ_max, max(0, N/M)),   N = M = 1/σ_ρ² at the start                                     (L2)

(Bayesian linear regression with exponential forgetting, e.g. Ljung & Söderström 1983, *Theory and Practice of
Recursive Identification*, §2.2; the prior's weight ``1/σ_ρ²`` is not forgotten). ``s²`` is ``n``'s variance: the
frame's lateral variance given its yaw, ``R_yy − R_yψ²/R_ψψ``, and the kinematics' over the frame, ``(σ_k·T)²``
(σ_k of (K2), ``T`` the frame interval). The next frame's motion is taken with::

    z = (Δx, Δy, Δψ) + d·β_ψ·(ρ̂·κ·c_x, ρ̂·κ·c_y, 1)                                                   (L3)

and the std's coupling terms (eq (5)) with the same lever. ``ρ`` is found only as well as the kinematics' lateral is
known: their own slip enters ``ℓ`` as a lasting error of the lateral the camera is measured against (the tractor's
tyres on a wet yard's circle: docs/field_bias.md §7.53). Off (the default) the coupling is eq (3)'s, the same array.
"""

from __future__ import annotations

import math

import numpy as np

from .fusion_model import BPSI
from .fusion_noise import FusionNoise

__all__ = ["RATIO_MAX", "CouplingRatio"]

RATIO_MAX = 2.0
"""``ρ_max`` of (L2): the lasting coupling at most twice the default's."""


class CouplingRatio:
    """``ρ`` of (L1)–(L3): the lasting part of eq (3)'s coupling as a multiple of the frames' ``κ·c``.

    Parameters
    ----------
    noise
        The filter's settings: ``vo_coupling_learned`` (off: :meth:`coupled` gives the coupling back as it is and
        :meth:`observe` keeps nothing), ``vo_coupling_memory`` ``D`` [m] and ``vo_coupling_prior`` ``σ_ρ``.

    Attributes
    ----------
    ratio : float
        ``ρ̂`` for the next frame, in ``[0, RATIO_MAX]`` (1 while off or before the first frame).
    """

    def __init__(self, noise: FusionNoise) -> None:
        self.on = noise.vo_coupling_learned
        self.memory = noise.vo_coupling_memory
        self._prior = 1.0 / noise.vo_coupling_prior**2
        self._sums = [self._prior, self._prior]  # N and M of (L2)
        self._lever = math.nan  # g = κ·c_y of the last frame's coupling
        self.ratio = 1.0

    def coupled(self, coupling: np.ndarray) -> np.ndarray:
        """The frame's coupling ``κ·c`` of eq (3) (2,) as the motion is taken with it: ``ρ̂·κ·c`` of (L3), or the
        same array while off."""
        if not self.on:
            return coupling
        self._lever = float(coupling[1])
        return self.ratio * coupling

    def observe(self, z: np.ndarray, x: np.ndarray, r: np.ndarray, kinematic_y: float | None, spread: float) -> None:
        """Take one frame into (L2): its increment ``z`` (3,) and covariance ``r`` (3×3), the prior state ``x`` at the
        frame, the kinematics' lateral step ``kinematic_y`` [m] over it (``None``: none, nothing taken) and their
        standard deviation over the frame ``spread`` = σ_k·T [m] (NaN: none known, 0 taken)."""
        if not self.on or kinematic_y is None or not math.isfinite(self._lever) or r[2, 2] <= 0.0:
            return
        d, g = float(x[0]), self._lever
        lasting = d * float(x[BPSI])
        a = lasting * g
        ell = (float(z[1]) - kinematic_y) - g * (math.remainder(float(z[2] - x[2]), 2.0 * math.pi) - lasting)  # (L1)
        variance = float(r[1, 1] - r[1, 2] ** 2 / r[2, 2]) + (spread**2 if math.isfinite(spread) else 0.0)
        if variance <= 0.0:
            return
        f = math.exp(-abs(d) / self.memory)
        n, m = self._sums
        n = f * n + (1.0 - f) * self._prior + a * ell / variance
        m = f * m + (1.0 - f) * self._prior + a * a / variance
        self._sums = [n, m]
        self.ratio = min(RATIO_MAX, max(0.0, n / m))  # (L2)
