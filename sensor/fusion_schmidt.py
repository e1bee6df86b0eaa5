"""The following unit's measurement taken with the Schmidt–Kalman (consider) gain of its persisting error.

:mod:`sensor.fusion_consider` holds the part of a following unit's measurement error ((C1)–(C2) of
:mod:`sensor.fusion_coupling`) that persists over frames as a consider parameter ``ν`` of the off-tracking's std: a
first-order Gauss–Markov lateral error ``σ_c·ν`` of each reference ((P1) there), whose effect ``ξ`` on the filter's
state error it carries with the filter's own gains, as the moments ``Π = E[ξ·ξᵀ]`` and ``c = E[ξ·ν]`` ((P2)). The
filter's gains there are those of a reference taken as white, so a reference whose error persists teaches the states
(and through them the path) as much as one whose error averages out. The Schmidt–Kalman filter (Schmidt 1966,
"Application of state-space methods to navigation problems", Advances in Control Systems 3; Zanetti & D'Souza 2013,
"Recursive implementations of the consider filter", AAS 12-619; Woodbury & Junkins 2010) takes the same consider
parameter into the gain: the gain that minimises the state error's covariance given the cross-covariance of the state
with ``ν``, without estimating ``ν``. This module computes that gain for the reference's update.

The reference ``z = H_c·x + σ_c·ν·e_y + v`` (``H_c = [I₃ 0]``, ``e_y`` its lateral row, ``v`` white of covariance
``R_c``, ``ν`` of unit variance), the state error ``e = x̂ − x`` with the covariance ``P + Π`` (``P`` the filter's, the
part of its error the white noises make, and ``Π`` the part ``ν`` made, uncorrelated with it) and ``E[e·ν] = c``. The
innovation ``y = z − H_c·x̂ = −H_c·e + σ_c·ν·e_y + v`` then has the covariance and the cross-covariance with the error::

    S = H_c·(P + Π)·H_cᵀ − σ_c·(H_c·c·e_yᵀ + e_y·cᵀ·H_cᵀ) + σ_c²·e_y·e_yᵀ + R_c                          (S1)
    M = (P + Π)·H_cᵀ − σ_c·c·e_yᵀ                                                                         (S2)

and the update ``x̂ ← x̂ + K·y``, whose error is ``(I − K·H_c)·e + K·(σ_c·ν·e_y + v)``, has the least covariance at::

    K = M·S⁻¹                                                                                             (S3)

(the Schmidt–Kalman gain of Zanetti & D'Souza 2013, with the white and the persisting parts of the error apart; the
filter's own gain ``P·H_cᵀ·(H_c·P·H_cᵀ + R_c)⁻¹`` where ``Π`` and ``c`` are zero, as before the first reference). ``ν``
itself is not estimated: it is the consider parameter, and the next reference's ``ν`` is the same process faded by
``exp(−Δt/τ_c)``, which (P2) of :mod:`sensor.fusion_consider` keeps in ``c``. The error's two parts are then carried
apart, each once::

    P ← (I − K·H_c)·P·(I − K·H_c)ᵀ + K·R_c·Kᵀ                                                             (S4)

(Joseph's form, which holds for any gain: the white noises' part alone), and ``Π``, ``c`` by (P2) with this ``K`` and
the injection ``m = σ_c·K·e_y``. Their sum is the Schmidt–Kalman filter's covariance ``P + Π − K·S·Kᵀ``. So the
off-tracking's std, eq (5) of :mod:`sensor.fusion_std` from ``P`` plus (P3) of :mod:`sensor.fusion_consider` from
``Π``, counts the persisting error once: ``P`` does not hold it and ``Π`` holds nothing else. The gate is that of
:func:`~sensor.fusion_model.gated_update` on ``S`` of (S1): beyond it the reference is refused, or taken with ``R_c``
inflated by the normalised innovation squared over the gate in (S1) and (S4).

Only the reference's update takes the gain: it is the measurement that carries ``ν``. The camera's motion and the
zero-slip rows keep the filter's own gains, through which (P2) carries ``Π`` and ``c`` as before (a consider
covariance analysis of those updates: their gains do not take ``Π`` into account, which the full Schmidt–Kalman filter
would). With ``gain`` off (``fusion.side_rig.coupling_persisting_error.gain``, false by default) the reference is
taken with the filter's own gain and the filter is as without this module to the bit.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["schmidt_update"]


def schmidt_update(
    x: np.ndarray,
    p: np.ndarray,
    moments: tuple[np.ndarray, np.ndarray],
    increment: np.ndarray,
    covariance: np.ndarray,
    sigma: float,
    gate: float,
    refuse: bool,
) -> tuple[np.ndarray, np.ndarray, float, bool, np.ndarray | None]:
    """(S1)–(S4) of the module notes: the reference's update with the Schmidt–Kalman gain.

    Parameters
    ----------
    x, p
        The filter's state (``Δ`` first) and its covariance ``P`` (the white noises' part of its error).
    moments
        ``(Π, c)``: the covariance of the state error's part the persisting error made and its cross-covariance with
        the persisting error ``ν`` at this reference (:class:`~sensor.fusion_consider.PersistingReference`).
    increment
        The reference's ``(dx, dy, dψ)`` of the unit's kingpin [m, m, rad].
    covariance
        Its 3×3 covariance ``R_c`` (white).
    sigma
        ``σ_c`` [m]: the persisting error's std on the reference's lateral axis.
    gate
        The normalised innovation squared beyond which the reference is refused or softened.
    refuse
        Refuse a reference beyond the gate (else take it with ``R_c`` inflated so that it sits on the gate).

    Returns
    -------
    tuple
        ``(x, P, nis, used, K)``: the state and ``P`` after the update ((S3), (S4)), the normalised innovation
        squared against (S1), whether the reference was taken, and the gain (``None`` where refused).
    """
    n = len(x)
    pi, c = np.asarray(moments[0], dtype=float), np.asarray(moments[1], dtype=float)
    h = np.hstack([np.eye(3), np.zeros((3, n - 3))])
    innovation = np.asarray(increment, dtype=float) - x[:3]
    innovation[2] = math.remainder(innovation[2], 2.0 * math.pi)
    e_y = np.array([0.0, 1.0, 0.0])
    total = p + pi
    cross = sigma * np.outer(c[:3], e_y)  # σ_c·H_c·c·e_yᵀ
    prior = h @ total @ h.T - cross - cross.T + sigma * sigma * np.outer(e_y, e_y)  # (S1) less R_c
    r = np.asarray(covariance, dtype=float)
    nis = float(innovation @ np.linalg.solve(prior + r, innovation))
    if nis > gate and refuse:
        return x, p, nis, False, None
    if nis > gate:
        r = r * (nis / gate)
    m = total @ h.T - sigma * np.outer(c, e_y)  # (S2)
    k = np.linalg.solve(prior + r, m.T).T  # (S3)
    a = np.eye(n) - k @ h
    p = a @ p @ a.T + k @ r @ k.T  # (S4)
    return x + k @ innovation, 0.5 * (p + p.T), nis, True, k
