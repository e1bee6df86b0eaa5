"""The following unit's persisting error in the off-tracking's std: a consider parameter carried by the filter's gains.

A following unit's measurement of the lead's kingpin increment ((C1)–(C2) of :mod:`sensor.fusion_coupling`) is
taken by the fused filter as white from frame to frame. Part of its lateral error is not: it persists over seconds
(docs/field_bias.md §7.12), and the filter, whose states ``s_f``, ``s_z``, ``v_s`` and biases learn from every
reference it takes, carries that part into the path through what the states learn from it. No term of eq (5) of
:mod:`sensor.fusion_std` holds it. This module holds it as a *consider parameter* (Schmidt 1966, the Schmidt–Kalman
"consider" filter; Woodbury & Junkins 2010; Zanetti & D'Souza 2013, AAS 12-619): an error the filter neither
estimates nor lets change its gains, whose effect on the estimate's error is propagated with the filter's own
transitions and gains (a consider covariance analysis: the Schmidt–Kalman filter would also change the gains; this
one leaves the estimate as it is and widens the std).

The persisting error. Each reference's lateral component ``z_y`` (in the lead's axes at the frame's start) carries
``σ_c·ν`` beside its white error, ``ν`` a first-order Gauss–Markov process of unit variance in time with the
correlation time ``τ_c`` (``correlation_time_s``), ``σ_c = u·sqrt(R_c,yy / k_c)`` (``u`` = ``share``, ``R_c / k_c``
the reference's per-frame covariance before the factor of (C2))::

    ν(t + Δt) = φ·ν(t) + sqrt(1 − φ²)·w,   φ = exp(−Δt/τ_c)                                              (P1)

The error it leaves. Let ``ξ`` be the part of the filter's state error that ``ν`` caused. Every linear step the
filter takes moves it as it moves the state's error: a control period ``ξ ← F·ξ`` (``F`` the Jacobian of eqs
(1)–(2), :class:`~sensor.fusion_model.ProcessModel`); a zero-slip row or the camera's motion, with the gain ``K``
the filter used, ``ξ ← (I − K·H)·ξ``; the reference, which measured ``σ_c·ν`` as part of the increment,
``ξ ← (I − K_c·H_c)·ξ + m·ν`` with ``m = σ_c·K_c·e_y`` (``e_y`` its lateral row). So with ``A`` the step's
``F`` or ``I − K·H`` and ``m`` zero except at a reference, the moments ``Π = E[ξ·ξᵀ]`` and ``c = E[ξ·ν]`` go::

    Π ← A·Π·Aᵀ + A·c·mᵀ + m·cᵀ·Aᵀ + m·mᵀ,    c ← A·c + m        (an update)
    Π ← F·Π·Fᵀ,                              c ← φ·F·c          (a control period of Δt)                  (P2)

(the consider covariance: ``Π`` is what the error's covariance holds beyond the filter's ``P`` when ``ν`` is in the
measurements and not in the model, and ``c`` the cross-covariance of the state with the consider parameter that the
references cited carry through propagation and update). Between two frames nothing injects ``ν``,
so the steps since the anchor compose into one transition ``Φ`` (the products of ``A``), kept per tick, and a frame
applies ``Φ`` and the frame's updates to the moments kept at the anchor.

The committed increments. A commit freezes the increment's part ``δ = ξ_Δ`` (the first three states) into the path
and restarts ``Δ`` at zero, whose error is then exactly zero. The errors of different increments are correlated
(through ``ν`` and the states), so the window keeps, for the increments ahead of the follow point, their joint
``B = E[δ_k·δ_lᵀ]``, their cross-moments with the states ``D_k = E[δ_k·ξᵀ]`` (at the anchor; ``D_k·Φᵀ`` at a
later tick, ``D_k·Aᵀ + E_k·mᵀ`` through an update) and with ``ν``, ``E_k = E[δ_k·ν]`` (``φ·E_k`` in time). A
commit appends ``δ``: ``B`` gains the row ``D_k[:, Δ]`` and the corner ``Π_ΔΔ``, ``D`` the row ``Π_Δ·``, ``E`` the
entry ``c_Δ``; then the ``Δ`` rows and columns of ``Π``, ``c`` and ``D`` are zeroed (the reset).

The term. With eq (4)'s sensitivities ``g_k`` of the increments ahead and ``g_now`` of the current one (the current
``Δ``'s part ``ξ_Δ = Φ_Δ·ξ_anchor``)::

    σ_P² = Σ_k Σ_l g_kᵀ·B_kl·g_l + 2·Σ_k g_kᵀ·(D_k·Φ_Δᵀ)·g_now + g_nowᵀ·(Φ_Δ·Π·Φ_Δᵀ)·g_now               (P3)

(``g_k`` counts the increment the follow point lies in whole or not at all, as eq (4) does), added to eq (5)'s
biases' term (it is the reference's error the states carry into the path; it is not scaled by
``ρ/3``, which measures the camera's motions). It is zero where no reference was taken, and the filter's estimate
and ``P`` are those without it to the bit: only the std reads it. The white part of the reference's error is
already in ``P``; ``σ_c`` is the persisting part on top. docs/field_bias.md §7.15 says how ``u`` and ``τ_c`` were
found.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .fusion_coupling import CouplingMeasurement, coupled_update
from .fusion_noise import PersistingReferenceError
from .fusion_schmidt import schmidt_update

__all__ = ["NoConsider", "PersistingReference", "Transition", "consider_of", "update_gain"]


@dataclass(frozen=True)
class Transition:
    """The linear map of the state's error from the anchor to a tick (``Φ`` of the module notes) and the time since
    the anchor [s]."""

    matrix: np.ndarray
    elapsed: float


def update_gain(p: np.ndarray, h: np.ndarray, r: np.ndarray, nis: float, gate: float) -> np.ndarray:
    """The gain :func:`~sensor.fusion_model.gated_update` used for a measurement it took: ``P·Hᵀ·S⁻¹`` with ``R``
    inflated by ``nis / gate`` where the innovation was beyond the gate."""
    ph = p @ h.T
    s = h @ ph + (r * (nis / gate) if nis > gate else r)
    return np.linalg.solve(s, ph.T).T


def rows_transition(p: np.ndarray, rows: tuple[tuple[np.ndarray, float, float], ...]) -> np.ndarray:
    """``Π (I − k·hᵀ)`` of the sequential scalar updates of :func:`~sensor.fusion_model.apply_rows` from ``p``."""
    a = np.eye(len(p))
    for h, _z, r in rows:
        ph = p @ h
        k = ph / (float(h @ ph) + r)
        a = a - np.outer(k, h @ a)
        p = p - np.outer(k, ph)
    return a


def sensitivities(pose: np.ndarray, starts: np.ndarray, ends: np.ndarray, lfp: float) -> tuple[np.ndarray, ...]:
    """Eq (4)'s ``g`` of the window's increments (zero behind the follow point), flattened (3n), and ``g_now``."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    g = np.zeros((len(starts), 3))
    if len(starts):
        ahead = c * (starts[:, 0] - pose[0]) + s * (starts[:, 1] - pose[1]) > -lfp
        heading = starts[ahead, 2] - pose[2]
        station = c * (ends[ahead, 0] - pose[0]) + s * (ends[ahead, 1] - pose[1])
        g[ahead] = np.column_stack([-np.sin(heading), -np.cos(heading), station + lfp])
    return g.reshape(-1), np.array([s, -c, lfp])


class NoConsider:
    """No persisting error: every hook does nothing and the term is zero (the filter as without it, to the bit)."""

    def reset(self) -> None:
        """Nothing to forget."""

    def advance(self, *_args: object) -> None:
        """No transition kept."""
        return None

    def frame(self, *_args: object) -> None:
        """Nothing to carry."""

    def update(self, *_args: object) -> None:
        """Nothing to carry."""

    def reference(self, *_args: object) -> None:
        """Nothing to carry."""

    def coupled(
        self, x: np.ndarray, p: np.ndarray, coupling: CouplingMeasurement, gate: float, refuse: bool
    ) -> tuple[np.ndarray, np.ndarray, float, bool]:
        """The following unit's measurement taken (:func:`~sensor.fusion_coupling.coupled_update`, the filter's own
        gain) and carried by :meth:`reference`: ``(x, p, nis, used)``."""
        x_new, p_new, nis, used = coupled_update(x, p, coupling, gate, refuse)
        self.reference(p, coupling, nis, gate, used)
        return x_new, p_new, nis, used

    def commit(self, *_args: object) -> None:
        """Nothing to commit."""

    def variance(self, *_args: object) -> float:
        """Zero."""
        return 0.0


class PersistingReference(NoConsider):
    """(P1)–(P3) of the module notes for a filter of ``size`` states.

    Parameters
    ----------
    size
        The filter's number of states (``Δ`` first).
    error
        ``u`` and ``τ_c``.
    """

    def __init__(self, size: int, error: PersistingReferenceError) -> None:
        self.size = size
        self.share = float(error.share)
        self.correlation_time = float(error.correlation_time_s)
        self.gain = bool(getattr(error, "gain", False))
        self.reset()

    def reset(self) -> None:
        """Forget the moments and the window."""
        n = self.size
        self.pi, self.c = np.zeros((n, n)), np.zeros(n)  # Π and c of (P2) at the anchor (or the frame being taken)
        self.b = np.zeros((0, 0))  # B of the window (3m × 3m)
        self.d, self.e = np.zeros((0, 3, n)), np.zeros((0, 3))  # D_k and E_k at the anchor

    def advance(
        self,
        step: tuple[Transition | None, np.ndarray] | None,
        p: np.ndarray,
        rows: tuple[tuple[np.ndarray, float, float], ...],
        dt: float,
    ) -> Transition:
        """``Φ`` at a tick: ``step`` the previous tick's ``Φ`` and the control period's Jacobian ``F`` over ``dt``
        (``None``: the anchor or the first tick, the identity), then the zero-slip ``rows`` taken from the
        covariance ``p`` after the period."""
        if step is None or step[0] is None:
            phi, elapsed = np.eye(self.size), 0.0
        else:
            phi, elapsed = step[1] @ step[0].matrix, step[0].elapsed + dt
        if rows:
            phi = rows_transition(p, rows) @ phi
        return Transition(phi, elapsed)

    def frame(self, transition: Transition | None) -> None:
        """Carry the anchor's moments to the frame's tick (``Φ`` and (P1) over the time since the anchor)."""
        if transition is None:
            return
        a, fade = transition.matrix, math.exp(-transition.elapsed / self.correlation_time)
        self.pi = a @ self.pi @ a.T
        self.c = fade * (a @ self.c)
        self.d = np.einsum("kij,lj->kil", self.d, a)
        self.e = fade * self.e

    def update(self, p: np.ndarray, h: np.ndarray, r: np.ndarray, nis: float, gate: float, used: bool) -> None:
        """A measurement the filter took at the frame with ``(H, R)`` from the covariance ``p`` (none injected)."""
        if used:
            self._apply(np.eye(self.size) - update_gain(p, h, r, nis, gate) @ h, None)

    def reference(
        self,
        p: np.ndarray,
        coupling: CouplingMeasurement,
        nis: float,
        gate: float,
        used: bool,
        gain: np.ndarray | None = None,
    ) -> None:
        """The following unit's measurement ``coupling`` (``H_c = [I₃ 0]``, ``R_c`` taken with ``k_c``) the filter
        took from the covariance ``p``: it injects ``m = σ_c·K_c·e_y`` of (P2). ``gain``: the ``K_c`` it was taken
        with (``None``: the filter's own, recomputed from ``p``)."""
        if not used:
            return
        h = np.hstack([np.eye(3), np.zeros((3, self.size - 3))])
        k = update_gain(p, h, np.asarray(coupling.covariance, dtype=float), nis, gate) if gain is None else gain
        self._apply(np.eye(self.size) - k @ h, self.sigma(coupling) * k[:, 1])

    def sigma(self, coupling: CouplingMeasurement) -> float:
        """``σ_c = u·sqrt(R_c,yy / k_c)`` [m] of the reference ``coupling``."""
        r_yy = float(np.asarray(coupling.covariance, dtype=float)[1, 1])
        return self.share * math.sqrt(max(r_yy / coupling.covariance_scale, 0.0))

    def coupled(
        self, x: np.ndarray, p: np.ndarray, coupling: CouplingMeasurement, gate: float, refuse: bool
    ) -> tuple[np.ndarray, np.ndarray, float, bool]:
        """The following unit's measurement taken and carried by :meth:`reference`: with the Schmidt–Kalman gain of
        :mod:`sensor.fusion_schmidt` where the error's ``gain`` is on, else with the filter's own."""
        if not self.gain:
            return super().coupled(x, p, coupling, gate, refuse)
        moments = (self.pi, self.c)
        x_new, p_new, nis, used, k = schmidt_update(
            x, p, moments, coupling.increment, coupling.covariance, self.sigma(coupling), gate, refuse
        )
        self.reference(p, coupling, nis, gate, used, k)
        return x_new, p_new, nis, used

    def _apply(self, a: np.ndarray, m: np.ndarray | None) -> None:
        """(P2) with ``A`` = ``a`` and the injection ``m`` (``None``: none), no time passing."""
        pi, c = a @ self.pi @ a.T, a @ self.c
        d = np.einsum("kij,lj->kil", self.d, a)
        if m is not None:
            pi = pi + np.outer(c, m) + np.outer(m, c) + np.outer(m, m)
            c = c + m
            d = d + self.e[:, :, None] * m[None, None, :]
        self.pi, self.c, self.d = 0.5 * (pi + pi.T), c, d

    def commit(self, keep: np.ndarray) -> None:
        """Freeze the frame's ``δ = ξ_Δ`` into the window, restart ``Δ`` (the reset) and keep the entries ``keep``
        (the filter's mask over the old increments and the new one, in that order)."""
        m = len(self.d)
        b = np.zeros((3 * m + 3, 3 * m + 3))
        b[: 3 * m, : 3 * m] = self.b
        cross = self.d[:, :, :3].reshape(3 * m, 3)  # E[δ_k·ξ_Δᵀ]
        b[: 3 * m, 3 * m :], b[3 * m :, : 3 * m], b[3 * m :, 3 * m :] = cross, cross.T, self.pi[:3, :3]
        d = np.concatenate([self.d, self.pi[None, :3, :]])
        e = np.concatenate([self.e, self.c[None, :3]])
        self.pi[:3, :], self.pi[:, :3], self.c[:3], d[:, :, :3] = 0.0, 0.0, 0.0, 0.0
        keep = np.asarray(keep, dtype=bool)
        rows = np.repeat(keep, 3)
        self.b, self.d, self.e = b[np.ix_(rows, rows)], d[keep], e[keep]

    def variance(
        self, transition: Transition | None, pose: np.ndarray, starts: np.ndarray, ends: np.ndarray, lfp: float
    ) -> float:
        """``σ_P²`` of (P3) [m²] at the tick ``transition`` leads to, at ``pose`` (the current ``Δ``), with the
        window's start poses and end points (in :meth:`commit`'s order) and the follow point's offset ``lfp``."""
        if transition is None:
            return 0.0
        g, g_now = sensitivities(pose, starts, ends, lfp)
        a = transition.matrix[:3]  # Φ_Δ
        total = float(g @ self.b @ g) if len(g) else 0.0
        if len(self.d):
            cross = np.einsum("kij,lj->kil", self.d, a).reshape(-1, 3)  # D_k·Φ_Δᵀ, stacked
            total += 2.0 * float(g @ cross @ g_now)
        total += float(g_now @ a @ self.pi @ a.T @ g_now)
        return max(total, 0.0)


def consider_of(size: int, error: PersistingReferenceError | None) -> NoConsider:
    """The consider term a filter of ``size`` states keeps for ``error`` (``None``: none)."""
    return NoConsider() if error is None else PersistingReference(size, error)
