"""The fused VISO-OT filter's off-tracking standard deviation: the increments' sensitivities (eq (4)) and the
coherent effects of the biases and of the odometry's error along the optical axis, summed in eq (5).

Off-tracking and its standard deviation. Every tick the off-tracking is read from the buffer moved by the
current ``(Δx, Δy, Δψ)`` (eq (7), :func:`~vehicle_model.offtracking.offtracking_from_path`). Its variance has
five parts. The committed increments newer than the follow-point station, and the current one, each contribute
``gᵀ Q g`` with ``Q`` the increment's covariance and ``g`` the first-order effect of its error on ``e_tr``::

    g = (−sin ψ_s, −cos ψ_s, x_e + L_fp)                                                        (4)

(``ψ_s`` the heading of the increment's start frame and ``x_e`` the station of its end, both in the current
trailer frame: a translation error moves the old path rigidly, a heading error turns it about the increment's
end). The remaining uncertainty of the biases ``(b_g, β_ψ)`` is common to every increment, so it enters coherently,
through ``G``, the change of ``e_tr`` per unit bias summed over the increments (a gyro bias turns each by its
duration and, through (1), moves it by ``L_c`` times that; the odometry's error per metre along (3) by its length).
Both parts follow the camera's evidence: ``ρ``, the mean normalised innovation squared of its recent motions, is 3
when they agree with their covariances (Bar-Shalom, Li & Kirubarajan 2001, ch. 5), so ``ρ/3`` scales them up where
the motions are noisier than their covariances say and down (to a quarter at most) where they are quieter. With
``innovation_ratio_from: lateral`` each motion enters ``ρ`` as three times the NIS of its lateral innovation given
the other two (:func:`lateral_nis`, expectation 1), which the lateral–yaw direction the gyro corrects does not
rule (docs/field_bias.md §7.63). The
coupling ``κ`` of (3) is itself known only to a relative ``u_κ`` (``vo_bias_coupling_uncertainty``: the regression
of the measured errors, docs/field_bias.md), so the translation the filter removes for the estimated ``β_ψ``,
``β_ψ·G_κ`` (``G_κ`` the coupled part of ``G``'s second entry), is uncertain by ``u_κ·β_ψ·G_κ``: a large
estimated odometry error widens the std (while the tyres scrub, by (K7) of :mod:`sensor.fusion_slip` instead).
A camera that looks across its motion (a side camera) has its weakest
direction along its optical axis ``o`` instead: a disparity offset scales its translation along ``o`` by a relative
error, known to ``u_z`` (``vo_axial_scale_uncertainty``, 0 by default), which enters coherently over the path
through ``A_z = Σ (o·Δ_c)·(g_xy·o)`` (``Δ_c`` each increment's camera displacement) and adds ``(u_z·A_z)²`` to
the coupling term; the states ``s_z`` and ``s_f`` of (3') enter the biases' term with ``A_z`` and
``A_f = Σ (t·Δ_c)·|t·Δ_c|·(g_xy·o)`` beside ``G``. The share of the kinematics' disagreement with the camera that the
estimate carries, ``s_k·m_k`` (K2), enters over the path as a slip velocity would, through ``Λ``, the sum of the
increments' lateral sensitivities times their durations (with (K3) the kinematics' error is a state, its
uncertainty is in the increments' own covariance, and this term is zero; with (K4) ``m_k²`` is at least
``(u_p·v_s)²``). What no state explains — the part of
the odometry's error that changes with the scenery faster than ``β_ψ`` follows — is the constant
``offtracking_bias_std`` ``σ_b``::

    σ_e² = (ρ/3)·(Σ gᵀ Q g + f_b²·G·P_b·Gᵀ) + (u_κ·β_ψ·G_κ)² + (u_z·A_z)² + (s_k·m_k·Λ)² + σ_b²     (5)

``f_b`` (``bias_std_scale``, 1 unless set) is a factor on the biases' part: where the biases' remaining uncertainty
as the filter holds it is measured to be wider than the error it leaves in the off-tracking, it narrows that part
alone (docs/field_bias.md §7.19 for a side rig, where the state ``s_f`` makes nearly all of it).

The sums of ``G``, ``A_z`` and ``A_f`` take each increment as the camera's motion corrected by the biases' estimate,
so that a bias error moves it by the camera's whole sensitivity. Where a following unit's camera also measured the
increment (:mod:`sensor.fusion_coupling`, ``H = [I₃ 0]``, its error independent of this unit's biases), the update
left ``I − K_Δ`` of the increment's prior error in it and replaced the rest by the reference's (Gelb 1974, §4.2);
the bias-driven part of the committed increment's error is that share of the camera's, and with
``coupling_bias_share`` the coherent sums take ``g`` through it::

    g' = (I − K_Δ)ᵀ g,    I − K_Δ = P⁺_ΔΔ·(P⁻_ΔΔ)⁻¹                                                          (4')

(``P⁻_ΔΔ``, ``P⁺_ΔΔ`` the increment's covariance before and after the reference's update: ``R_c·S⁻¹`` for an
update taken, the identity for one refused or absent, zero for a reference without error). The independent part
keeps ``g`` and the posterior ``Q``, which holds the reference's share of the error already.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .fusion_noise import FusionNoise

__all__ = [
    "MIN_INNOVATION_RATIO",
    "STD_PARTS",
    "IncrementWindow",
    "PathEffects",
    "axial_effect",
    "bias_effect",
    "lateral_nis",
    "path_effects",
    "reference_share",
    "window_nis",
]

#: The five terms of the off-tracking's variance, eq (5), in its order: the increments' own covariance, the
#: biases' remaining uncertainty, the bias coupling's (with the optical axis's scale), the kinematics' carried
#: disagreement and the constant ``offtracking_bias_std``.
STD_PARTS: tuple[str, ...] = ("increments", "biases", "coupling", "kinematics", "unexplained")

MIN_INNOVATION_RATIO = 0.25
"""Least ``ρ/3`` of eq (5): a run of well-matched motions may shrink the std by half, not to nothing."""


def axial_effect(
    g: np.ndarray, starts: np.ndarray, ends: np.ndarray, turns: np.ndarray, axis: np.ndarray, camera: np.ndarray
) -> tuple[float, float]:
    """``A_z`` of eq (5): the change of ``e_tr`` per relative error ``u_z`` of the odometry's translation along the
    camera's optical axis ``o`` (``axis``), coherent over increments with sensitivities ``g`` (n×3), start poses
    and end points in one frame and turns ``Δψ``: each increment's camera displacement (its kingpin's, plus the
    lever ``(R(Δψ) − I)·p_c`` of the camera at ``p_c`` = ``camera``) has the component ``a = o·Δ_c`` along the
    axis, and the error ``u_z·a·o`` of the increment moves ``e_tr`` by ``g_xy·o`` times that. The second value is
    the same for ``s_f`` of (3'), the square ``(t·Δ_c)·|t·Δ_c|`` of the component across the axis in its place."""
    c, s = np.cos(starts[:, 2]), np.sin(starts[:, 2])
    dx, dy = ends[:, 0] - starts[:, 0], ends[:, 1] - starts[:, 1]
    local = np.column_stack([c * dx + s * dy, -s * dx + c * dy])  # in each increment's start frame
    ct, st = np.cos(turns), np.sin(turns)
    lever = np.column_stack([(ct - 1.0) * camera[0] - st * camera[1], st * camera[0] + (ct - 1.0) * camera[1]])
    moved = local + lever
    along, across = moved @ axis, moved @ np.array([axis[1], -axis[0]])
    across = across * np.abs(across)
    sensitivity = g[:, :2] @ axis
    return float(np.sum(along * sensitivity)), float(np.sum(across * sensitivity))


def bias_effect(
    g: np.ndarray, length: np.ndarray, duration: np.ndarray, slip_point: float, coupling: np.ndarray
) -> np.ndarray:
    """``G`` of eq (5): the change of ``e_tr`` per unit error of ``(b_g, β_ψ)``, coherent over increments with
    sensitivities ``g`` (n×3), lengths [m] and durations [s]: a gyro bias turns and, through eq (1) with
    ``L_c`` = ``slip_point``, moves each increment by its duration; an odometry error per metre along the frame's
    ambiguity ``coupling`` = ``κ·(c_x, c_y)`` by its length. The third entry is the part of the second that the
    coupling carries (the translation along the ambiguity)."""
    gyro = -float(np.sum((g[:, 2] + g[:, 1] * slip_point) * duration))
    c_x, c_y = coupling
    coupled = float(np.sum((g[:, 0] * c_x + g[:, 1] * c_y) * length))
    return np.array([gyro, coupled + float(np.sum(g[:, 2] * length)), coupled])


def reference_share(prior: np.ndarray, posterior: np.ndarray) -> np.ndarray:
    """``I − K_Δ`` of eq (4'): the share of an increment's prior error a measurement of it left in it, from the
    increment's 3×3 covariance before (``prior``) and after (``posterior``) the update (``P⁺·P⁻⁻¹``; the identity
    exactly where the update was refused and left it as it was)."""
    if np.array_equal(prior, posterior):
        return np.eye(3)
    return np.linalg.solve(prior.T, posterior.T).T


def lateral_nis(innovation: np.ndarray, s: np.ndarray) -> float:
    """The normalised innovation squared of the lateral component of a motion's innovation ``ν = (ν_x, ν_y, ν_ψ)``
    given the other two, against its covariance ``S`` (3×3)::

        ν_y|r = ν_y − S_yr·S_rr⁻¹·ν_r,    S_y|r = S_yy − S_yr·S_rr⁻¹·S_ry,    NIS_y|r = ν_y|r² / S_y|r

    (``r`` = ``(x, ψ)``; the conditional mean and variance of a Gaussian, Bar-Shalom, Li & Kirubarajan 2001,
    §3.2.1): a χ²₁ variable, expectation 1, where ``S`` describes the innovation. It does not change with the units
    (or any invertible mix) of the other two components."""
    rest = [0, 2]
    s_rr, s_ry = s[np.ix_(rest, rest)], s[rest, 1]
    weights = np.linalg.solve(s_rr, s_ry)
    residual = float(innovation[1] - weights @ innovation[rest])
    return residual**2 / float(s[1, 1] - s_ry @ weights)


def window_nis(
    noise: FusionNoise, nis: float, innovation: np.ndarray, h: np.ndarray, prior: np.ndarray, r: np.ndarray
) -> float:
    """An accepted motion's entry in the window of ``ρ`` (eq (5)), capped at ``noise.gate``: its 3-D normalised
    innovation squared ``nis``, or with ``noise.innovation_ratio_from`` ``"lateral"`` three times
    :func:`lateral_nis` against ``S = H·P⁻·Hᵀ + R`` (``prior`` = ``P⁻``), so that both have expectation 3
    (``"rear_lateral"`` is one of the two once :meth:`~sensor.fusion_noise.FusionNoise.for_camera` has taken it)."""
    if noise.innovation_ratio_from == "lateral":
        nis = 3.0 * lateral_nis(innovation, h @ prior @ h.T + r)
    return min(nis, noise.gate)


@dataclass(frozen=True)
class IncrementWindow:
    """The committed increments still ahead of the follow point, in the anchor's frame.

    Attributes
    ----------
    starts : numpy.ndarray
        (n, 3) start poses ``(x, y, ψ)``.
    ends : numpy.ndarray
        (n, 2) end points.
    covariances : numpy.ndarray
        (n, 3, 3) each increment's covariance.
    durations : numpy.ndarray
        (n,) each increment's duration [s].
    demands : numpy.ndarray or None
        (n,) the scrub demand ``D`` of (K5) each increment was taken at (``None``: none anywhere).
    shares : numpy.ndarray or None
        (n, 3, 3) ``I − K_Δ`` of eq (4') each increment was left with (``None``: the camera's sensitivity, eq (5)
        as without a reference).
    """

    starts: np.ndarray
    ends: np.ndarray
    covariances: np.ndarray
    durations: np.ndarray
    demands: np.ndarray | None = None
    shares: np.ndarray | None = None


@dataclass(frozen=True)
class PathEffects:
    """The sensitivities of eq (5) over the window and the current increment.

    Attributes
    ----------
    independent : float
        ``Σ gᵀ Q g`` [m²].
    coherent : numpy.ndarray
        ``G``: ∂e_tr/∂(b_g, β_ψ) and the coupled part of the second.
    lever : float
        ``Λ``: ∂e_tr/∂v_s, a slip velocity error held over the window [s].
    axial, cross : float
        ``A_z`` and ``A_f`` (0 when not asked for).
    coupled_demand : float
        ``D̄`` of (K7): the increments' scrub demands weighted by their shares of the coupled part of ``G`` (0 where
        no increment was taken at a demand).
    """

    independent: float
    coherent: np.ndarray
    lever: float
    axial: float
    cross: float
    coupled_demand: float = 0.0


def path_effects(
    pose: np.ndarray,
    current_covariance: np.ndarray,
    elapsed: float,
    window: IncrementWindow,
    follow_point_offset: float,
    slip_point: float,
    coupling: np.ndarray,
    axis: np.ndarray | None,
    camera: np.ndarray,
    demand: float = 0.0,
) -> PathEffects:
    """Eq (4)'s sensitivities summed over the committed increments ahead of the follow point and the current one.

    Parameters
    ----------
    pose
        The current ``(Δx, Δy, Δψ)`` from the anchor.
    current_covariance
        Its 3×3 covariance.
    elapsed
        Time since the anchor [s].
    window
        The committed increments, in the anchor's frame.
    follow_point_offset
        ``L_fp`` [m].
    slip_point
        ``L_c`` of eq (1) [m].
    coupling
        The last frame's ``κ·(c_x, c_y)`` of eq (3).
    axis
        The camera's optical axis in the unit's ground plane (``None``: ``A_z`` and ``A_f`` not needed, zero).
    camera
        The camera's position in the unit's frame [m].
    demand
        The scrub demand of (K5) the current increment is taken at (with the window's ``demands``, ``D̄`` of (K7)).
    """
    d, lfp = pose, follow_point_offset
    c, s = math.cos(d[2]), math.sin(d[2])
    independent = 0.0
    coherent = np.zeros(3)
    lever = axial = cross = 0.0
    scrubbed = weight = 0.0  # Σ D_j·|coupled_j| and Σ |coupled_j| of (K7)
    if len(window.covariances):
        starts, ends = window.starts, window.ends
        ahead = c * (starts[:, 0] - d[0]) + s * (starts[:, 1] - d[1]) > -lfp
        if ahead.any():
            heading = starts[ahead, 2] - d[2]
            station = c * (ends[ahead, 0] - d[0]) + s * (ends[ahead, 1] - d[1])
            g = np.column_stack([-np.sin(heading), -np.cos(heading), station + lfp])
            independent = float(np.einsum("ni,nij,nj->", g, window.covariances[ahead], g))
            length = np.hypot(ends[ahead, 0] - starts[ahead, 0], ends[ahead, 1] - starts[ahead, 1])
            if window.shares is not None:  # (4'): the share of the camera's error the reference left
                g_biases = np.einsum("ni,nij->nj", g, window.shares[ahead])
            else:
                g_biases = g
            coherent = bias_effect(g_biases, length, window.durations[ahead], slip_point, coupling)
            if window.demands is not None:
                coupled = np.abs((g_biases[:, 0] * coupling[0] + g_biases[:, 1] * coupling[1]) * length)
                scrubbed, weight = float(np.dot(window.demands[ahead], coupled)), float(np.sum(coupled))
            lever += float(np.sum(g[:, 1] * window.durations[ahead]))
            if axis is not None:
                turns = np.diff(np.append(starts[:, 2], 0.0))[ahead]  # each increment's Δψ (it ends at the next)
                axial, cross = axial_effect(g_biases, starts[ahead], ends[ahead], turns, axis, camera)
    # ... and the current one, from the anchor (heading −Δψ in the current frame) to the kingpin.
    g_now = np.array([s, -c, lfp])
    independent += float(g_now @ current_covariance @ g_now)
    if axis is not None:
        now_axial, now_cross = axial_effect(
            g_now[None, :], np.zeros((1, 3)), d[None, :2], np.array([d[2]]), axis, camera
        )
        axial, cross = axial + now_axial, cross + now_cross
    now = bias_effect(g_now[None, :], np.array([math.hypot(d[0], d[1])]), np.array([elapsed]), slip_point, coupling)
    coherent += now
    if scrubbed > 0.0 or demand > 0.0:  # (K7): the demand over the path, as the coupled correction is spread on it
        scrubbed, weight = scrubbed + demand * abs(now[2]), weight + abs(now[2])
    coupled_demand = scrubbed / weight if scrubbed > 0.0 and weight > 0.0 else 0.0
    return PathEffects(independent, coherent, lever + g_now[1] * elapsed, axial, cross, coupled_demand)
