"""Whether the odometry's coupled translation holds while the tyres scrub: the frames' own evidence.

(K5) of :mod:`sensor.fusion_slip` takes a frame's coupled translation ``κ·(c_x, c_y)`` of eq (3)
(:mod:`sensor.fusion_model`) with ``1 − D`` at the scrub demand ``D``: the coupling is assumed to give way to the
scrubbing tyres. ``scrub_coupling_kept`` takes it whole instead. Which of the two is right depends on the turn
(docs/field_bias.md §6.8, §7.20): on the catalogue's left-hand circles the coupling held through the scrub, on the
figure-of-eight's right-hand loop it did not. With ``scrub_coupling_evidence`` the filter weighs the two against
each other on every frame taken under a demand, as two hypotheses of one measurement model (a two-model
multiple-model filter, Bar-Shalom, Li & Kirubarajan 2001, §11.6, with one shared state):

(S1) Each frame's innovation ``ν_j = z − H_j·x`` and its covariance ``S_j = H_j·P·H_jᵀ + R`` under the coupled
     hypothesis (``j = c``: the coupled column ``x_Δx·κ·(c_x, c_y)·(1 − r·D)`` of ``β_ψ`` whole) and the released one
     (``j = r``: that column times ``1 − D``), the other columns of ``H`` those the filter builds; its likelihood
     ``L_j = N(ν_j; 0, S_j)`` over the frame's three channels (the yaw row is the same in both, so what separates
     them is the lateral motion given the frame's own yaw–translation covariance).
(S2) The weight ``w`` of the coupled hypothesis, first mixed by the switching probability ``q``
     (``scrub_coupling_switch``) a frame, ``w⁻ = (1 − q)·w + q·(1 − w)``, then ``w = w⁻·L_c / (w⁻·L_c + (1 − w⁻)·L_r)``;
     it starts at ½ and is held in ``[q, 1 − q]``. Frames without a demand carry no evidence (``H_c = H_r``), nor do
     frames the gate refuses under both hypotheses.
(S3) The frame's coupled translation is taken with ``w + (1 − w)·(1 − D)``: the expected yield of (K5) under the
     two hypotheses (1 where the coupling holds, ``1 − D`` where it gives way). The weight of (S2) is the one before
     the frame, so a frame's own motion does not choose the model it is taken with.

Off (the default) the yield is (K5)'s or, with ``scrub_coupling_kept``, 1, and nothing is weighed.
"""

from __future__ import annotations

import math

import numpy as np

from .fusion_model import BPSI
from .fusion_noise import FusionNoise
from .fusion_slip import scrub_coupling_yield

__all__ = ["CouplingEvidence"]

START_WEIGHT = 0.5
"""(S2): the coupled hypothesis's weight before any frame under a demand."""


def _log_likelihood(innovation: np.ndarray, covariance: np.ndarray) -> tuple[float, float]:
    """``log N(ν; 0, S)`` (less the constant) and the normalised innovation squared ``νᵀ·S⁻¹·ν``."""
    sign, log_det = np.linalg.slogdet(covariance)
    nis = float(innovation @ np.linalg.solve(covariance, innovation))
    if sign <= 0.0 or not math.isfinite(nis):
        return -math.inf, math.inf
    return -0.5 * (nis + log_det), nis


class CouplingEvidence:
    """(S1)–(S3) of the module notes: the weight of the coupled hypothesis and the yield it gives a frame.

    Parameters
    ----------
    noise
        The filter's settings: ``scrub_coupling_evidence`` on weighs, ``scrub_coupling_switch`` is ``q`` of (S2);
        off, :meth:`factor` is :func:`~sensor.fusion_slip.scrub_coupling_yield` and :meth:`weigh` does nothing.
    """

    def __init__(self, noise: FusionNoise) -> None:
        self.noise = noise
        self.on = bool(noise.scrub_coupling_evidence)
        self.weight = START_WEIGHT
        self.log_ratio = 0.0  # (S1): the last weighed frame's log L_c − log L_r
        self._factor = 1.0
        self._demand = 0.0

    def factor(self, demand: float) -> float:
        """The share of the frame's coupled translation taken at the scrub demand ``demand``: (S3) when on,
        otherwise :func:`~sensor.fusion_slip.scrub_coupling_yield`."""
        if not self.on or demand <= 0.0:
            return scrub_coupling_yield(self.noise, demand)
        self._demand = demand
        self._factor = self.weight + (1.0 - self.weight) * (1.0 - demand)  # (S3)
        return self._factor

    def weigh(self, x: np.ndarray, p: np.ndarray, h: np.ndarray, innovation: np.ndarray, r: np.ndarray) -> None:
        """(S1)–(S2) on the frame just built: ``h`` the filter's 3×n measurement matrix with the coupled column at
        the :meth:`factor` it returned, ``innovation`` ``z − h·x`` (its yaw wrapped), ``r`` the frame's 3×3."""
        if not self.on or self._demand <= 0.0:
            return
        demand, self._demand = self._demand, 0.0
        column = h[:2, BPSI] / self._factor  # the coupled column whole (S1); the factor is at least q·D > 0
        logs, gated = [], 0
        for share in (1.0, 1.0 - demand):  # (S1): coupled, released
            hj = h.copy()
            hj[:2, BPSI] = column * share
            nu = innovation - (hj - h) @ x
            log_l, nis = _log_likelihood(nu, hj @ p @ hj.T + r)
            logs.append(log_l)
            gated += nis > self.noise.gate
        if gated == 2 or not all(math.isfinite(v) for v in logs):
            return
        q = self.noise.scrub_coupling_switch
        prior = (1.0 - q) * self.weight + q * (1.0 - self.weight)  # (S2)
        self.log_ratio = logs[0] - logs[1]
        odds = math.log(prior / (1.0 - prior)) + self.log_ratio
        weight = 1.0 / (1.0 + math.exp(-odds)) if odds > -700.0 else 0.0
        self.weight = min(max(weight, q), 1.0 - q)
