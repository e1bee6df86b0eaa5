"""The odometry's axial states' effect on the off-tracking through the fused filter's own posterior.

Eq (5) of :mod:`sensor.fusion_std` carries the remaining uncertainty of the states ``s_z`` and ``s_f`` of (3')
(:mod:`sensor.fusion_model`) into the off-tracking's std at the camera's own sensitivity: ``A_z`` and ``A_f``, the
change of ``e_tr`` per unit of each if every increment of the path were the camera's motion corrected by the states'
current estimate. The increments are not the camera's alone. Each is the filter's posterior, the camera's motion
fused with the trailer's signals and the zero-slip kinematics; where those carry the lateral motion (a dry road,
the kinematics trusted) an error of ``s_z`` or ``s_f`` hardly moves the increment, and where the camera carries it
(slip seen, the kinematics de-weighted) it moves it by the camera's whole sensitivity. How much is in the filter's
covariance at the frame: the regression of the increment's error on the state's error (Gelb 1974, §4.2: the
linear minimum-variance estimate of one error given another is ``P_xy·P_yy⁻¹`` times it)::

    c_k = P_k[Δ, s] / P_k[s, s]      (3 × 1 per state s ∈ {s_z, s_f}, at the frame that commits increment k)    (A1)

and the off-tracking's change per unit error of the state is ``−Σ_k g_k·c_k`` over the increments ahead of the
follow point (``g_k`` of eq (4)) and the current one; the sign makes it the same quantity as ``A_z`` (an error of
the state, not of its estimate)::

    A'_s = −(Σ_k g_k·c_k + g_now·P_now[Δ, s] / P_now[s, s])                                               (A2)

For an increment the camera alone measures, ``c_k`` is the camera's sensitivity itself and ``A'_s`` = ``A_s``.
With ``vo_axial_effect: posterior`` eq (5)'s biases' term takes ``A'_z``, ``A'_f`` in place of ``A_z``, ``A_f``;
the coupling term's ``(u_z·A_z)²``, which is no state, keeps the camera's. The commit drops the cross-covariance of
the committed increment with the states (:mod:`sensor.fusion`, module notes), so ``c_k`` is taken just before it.
docs/field_bias.md §7.11 says what it changes for a side rig.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["AxialRegression"]


class AxialRegression:
    """(A1) of every committed increment still in the off-tracking's window, and (A2) over them.

    Parameters
    ----------
    states
        Indices of the axial states in the filter's state (``s_z`` and/or ``s_f``, in that order).
    """

    def __init__(self, states: list[int]) -> None:
        self.states = list(states)
        self.reset()

    def reset(self) -> None:
        """Forget the committed increments."""
        self.regressions = np.zeros((0, 3, len(self.states)))

    def regression(self, p: np.ndarray) -> np.ndarray:
        """(A1) of the increment ``Δ`` (the first three states) with the covariance ``p``: 3 × (number of states)."""
        return np.stack([p[:3, i] / max(float(p[i, i]), 1e-30) for i in self.states], axis=1)

    def commit(self, p: np.ndarray, keep: np.ndarray) -> None:
        """Append the regression of the increment committed with covariance ``p`` and keep the entries ``keep``
        (the window's own mask over its old entries and the new one, in that order)."""
        appended = np.concatenate([self.regressions, self.regression(p)[None]])
        self.regressions = appended[np.asarray(keep, dtype=bool)]

    def effect(
        self, pose: np.ndarray, current_covariance: np.ndarray, starts: np.ndarray, ends: np.ndarray, lfp: float
    ) -> np.ndarray:
        """(A2) for each state [m per unit of the state].

        Parameters
        ----------
        pose
            The current ``(Δx, Δy, Δψ)`` from the anchor.
        current_covariance
            The filter's whole covariance now (its cross-covariance of ``Δ`` with the states is the current
            increment's (A1)).
        starts, ends
            The window's start poses (n, 3) and end points (n, 2) in the anchor's frame, in the order of
            :attr:`regressions`.
        lfp
            The follow point's offset ``L_fp`` [m].
        """
        c, s = math.cos(pose[2]), math.sin(pose[2])
        g_now = np.array([s, -c, lfp])  # eq (4) of the current increment, as in sensor.fusion_std.path_effects
        total = g_now @ self.regression(current_covariance)
        if len(self.regressions):
            ahead = c * (starts[:, 0] - pose[0]) + s * (starts[:, 1] - pose[1]) > -lfp
            if ahead.any():
                heading = starts[ahead, 2] - pose[2]
                station = c * (ends[ahead, 0] - pose[0]) + s * (ends[ahead, 1] - pose[1])
                g = np.column_stack([-np.sin(heading), -np.cos(heading), station + lfp])
                total = total + np.einsum("ni,nik->k", g, self.regressions[ahead])
        return -total
