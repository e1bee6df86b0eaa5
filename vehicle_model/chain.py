"""Yaw-plane equations of motion of a chain of rigid units joined at hinges, for any number of units, in casadi.

A combination is a chain: unit 1 (tractor or rigid truck) pulls unit 2 at a hinge (fifth wheel, drawbar eye), unit
2 pulls unit 3, and so on. Every unit moves in the road plane with three degrees of freedom and every hinge removes
two, so a chain of ``N`` units has ``N + 2`` *generalised speeds*::

    w = [u_1, v_1, r_1, r_2, …, r_N]

(the first unit's CG velocity in its own axes and every unit's yaw rate, ISO 8855: x forward, y left, z up) and
``N − 1`` articulation angles ``Γ_k = ψ_k − ψ_{k+1}``. The hinge between units ``k`` and ``k + 1`` lies ``e_k``
behind unit ``k``'s CG and ``f_{k+1}`` ahead of unit ``k + 1``'s (docs/vehicle_dynamics.md §1.1, where for two units
``e_1 = h1`` and ``f_2 = h2``). Its velocity, found on unit ``k`` and turned into unit ``k + 1``'s axes, gives that
unit's CG velocity::

    (a, b) = (u_k, v_k − e_k·r_k)
    u_{k+1} = a·cos Γ_k − b·sin Γ_k,   v_{k+1} = a·sin Γ_k + b·cos Γ_k − f_{k+1}·r_{k+1}                   (C1)

Every unit's CG velocity is linear in ``w``. Written in the first unit's axes, with ``θ_j = ψ_j − ψ_1`` (``θ_1 =
0``, ``θ_{j+1} = θ_j − Γ_j``) and the unit vectors ``x̂_j = (cos θ_j, sin θ_j)``, ``ŷ_j = (−sin θ_j, cos θ_j)``, each
unit's rotation moves the points behind it sideways::

    V_k = u_1·x̂_1 + v_1·ŷ_1 + Σ_j λ_kj·r_j·ŷ_j                                                          (C2)

with the lever arms ``λ_k1 = −e_1`` and ``λ_kj = −(f_j + e_j)`` for the units ``1 < j < k`` between, ``λ_kk = −f_k``
(0 for ``k = 1``) and ``λ_kj = 0`` for ``j > k``. The hinge forces do no work in any motion the hinges allow, so
Kane's equations (Kane & Levinson 1985, ch. 6; the partial velocities ``∂V_k/∂w`` are the coefficients of (C2))
eliminate them: ``M·ẇ = Q`` with the symmetric positive definite mass matrix (``m_k``, ``I_k`` each unit's mass and
yaw inertia about its CG)::

    M_uu = M_vv = Σ m_k,   M_uv = 0,   M_u,rj = −sin θ_j·Λ_j,   M_v,rj = cos θ_j·Λ_j,   Λ_j = Σ_k m_k·λ_kj
    M_ri,rj = cos(θ_i − θ_j)·Σ_k m_k·λ_ki·λ_kj + δ_ij·I_j                                               (C3)

and, with ``F_k`` the applied force on unit ``k`` at its CG (tyres, gravity along the slope, drag; turned into the
first unit's axes) and ``N_k = F_k − m_k·b_k`` less the velocity-product part of its acceleration::

    b_k = −v_1·r_1·x̂_1 + u_1·r_1·ŷ_1 − Σ_j λ_kj·r_j²·x̂_j
    Q_u = Σ_k N_k·x̂_1,   Q_v = Σ_k N_k·ŷ_1,   Q_rj = τ_j + ŷ_j·Σ_k λ_kj·N_k                              (C4)

(``τ_j`` the applied moment on unit ``j`` about its CG). For two units (C3) is the 4×4 matrix of
docs/vehicle_dynamics.md §1.4 and §2.1. The force that unit ``k`` receives at its front hinge follows from the
rear of the chain forward, in the first unit's axes (``a_k`` the CG acceleration)::

    H_N = m_N·a_N − F_N,   H_k = m_k·a_k − F_k + H_{k+1}                                                 (C5)

and is reported in unit ``k``'s own axes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca

__all__ = ["ChainBody", "ChainMotion", "chain_motion", "chain_velocities"]


@dataclass(frozen=True)
class ChainBody:
    """One unit of the chain, as its equations of motion see it (SI units).

    Attributes
    ----------
    mass : float
        [kg].
    yaw_inertia : float
        About the CG [kg·m²].
    front_hinge : float
        ``f_k``: distance from the CG forward to the hinge with the unit ahead [m] (unused for the first unit).
    rear_hinge : float
        ``e_k``: distance from the CG back to the hinge with the unit behind [m] (unused for the last unit).
    """

    mass: float
    yaw_inertia: float
    front_hinge: float = 0.0
    rear_hinge: float = 0.0


@dataclass(frozen=True)
class ChainMotion:
    """What :func:`chain_motion` derives (casadi expressions).

    Attributes
    ----------
    speed_rates : casadi.SX
        ``ẇ`` solving ``M·ẇ = Q`` of (C3)–(C4), ``N + 2`` entries ``[u̇_1, v̇_1, ṙ_1, …, ṙ_N]``.
    hinge_forces : list of casadi.SX
        ``H_k`` of (C5) for each hinge: the force (x, y) the trailing unit receives at it, in its own axes [N].
    """

    speed_rates: ca.SX
    hinge_forces: list[ca.SX]


def chain_velocities(
    speeds: Sequence[ca.SX], articulation: Sequence[ca.SX], bodies: Sequence[ChainBody]
) -> tuple[list[ca.SX], list[ca.SX]]:
    """CG velocities ``(u_k, v_k)`` of every unit in its own axes, eq (C1).

    Parameters
    ----------
    speeds : sequence of casadi.SX
        ``w = [u_1, v_1, r_1, …, r_N]``.
    articulation : sequence of casadi.SX
        ``Γ_k = ψ_k − ψ_{k+1}``, ``N − 1`` entries [rad].
    bodies : sequence of ChainBody
        The ``N`` units in order.

    Returns
    -------
    u, v : list of casadi.SX
        Forward and lateral CG velocity of each unit [m/s].
    """
    n = len(bodies)
    if n < 1 or len(speeds) != n + 2 or len(articulation) != n - 1:
        raise ValueError(f"a chain of {n} units takes {n + 2} speeds and {n - 1} angles")
    yaw = speeds[2:]
    u, v = [speeds[0]], [speeds[1]]
    for k in range(n - 1):
        a, b = u[k], v[k] - bodies[k].rear_hinge * yaw[k]  # the hinge's velocity on unit k
        c, s = ca.cos(articulation[k]), ca.sin(articulation[k])
        u.append(a * c - b * s)
        v.append(a * s + b * c - bodies[k + 1].front_hinge * yaw[k + 1])
    return u, v


def chain_motion(
    speeds: ca.SX, articulation: ca.SX, bodies: Sequence[ChainBody], applied: Sequence[ca.SX]
) -> ChainMotion:
    """Speed rates and hinge forces of the chain, eqs (C2)–(C5).

    Parameters
    ----------
    speeds : casadi.SX
        ``w``, ``N + 2`` entries.
    articulation : casadi.SX
        ``Γ``, ``N − 1`` entries [rad].
    bodies : sequence of ChainBody
        The ``N`` units in order.
    applied : sequence of casadi.SX
        ``F_k``: per unit the force (x, y) [N] at its CG and the moment about it [N·m], in its own axes, every
        applied load but the hinges'.

    Returns
    -------
    ChainMotion
    """
    n = len(bodies)
    if len(applied) != n or speeds.numel() != n + 2 or articulation.numel() != max(n - 1, 0):
        raise ValueError(f"a chain of {n} units takes {n + 2} speeds, {n - 1} angles and {n} applied loads")
    u1, v1 = speeds[0], speeds[1]
    yaw = [speeds[2 + j] for j in range(n)]
    theta: list[ca.SX | float] = [0.0]
    for k in range(n - 1):
        theta.append(theta[k] - articulation[k])
    cos = [1.0] + [ca.cos(t) for t in theta[1:]]
    sin = [0.0] + [ca.sin(t) for t in theta[1:]]
    lever = [[_lever_arm(bodies, k, j) for j in range(n)] for k in range(n)]  # λ_kj of (C2)
    mass = [b.mass for b in bodies]

    matrix = ca.SX.zeros(n + 2, n + 2)  # (C3)
    matrix[0, 0] = matrix[1, 1] = sum(mass)
    for j in range(n):
        moment = sum(mass[k] * lever[k][j] for k in range(n))
        if moment:
            matrix[0, 2 + j] = matrix[2 + j, 0] = -sin[j] * moment
            matrix[1, 2 + j] = matrix[2 + j, 1] = cos[j] * moment
        for i in range(j + 1):
            product = sum(mass[k] * lever[k][i] * lever[k][j] for k in range(n))
            value = product * (1.0 if i == j else cos[j] if i == 0 else ca.cos(theta[i] - theta[j]))
            matrix[2 + i, 2 + j] = matrix[2 + j, 2 + i] = value + (bodies[j].yaw_inertia if i == j else 0.0)

    net, bias = [], []  # N_k and b_k of (C4), in the first unit's axes
    for k in range(n):
        fx, fy = applied[k][0], applied[k][1]
        bx, by = -v1 * yaw[0], u1 * yaw[0]
        for j in range(k + 1):
            if lever[k][j]:
                bx -= lever[k][j] * yaw[j] ** 2 * cos[j]
                by -= lever[k][j] * yaw[j] ** 2 * sin[j]
        bias.append((bx, by))
        net.append((fx * cos[k] - fy * sin[k] - mass[k] * bx, fx * sin[k] + fy * cos[k] - mass[k] * by))
    force = [sum(x for x, _ in net), sum(y for _, y in net)]
    for j in range(n):
        nx = sum(lever[k][j] * net[k][0] for k in range(n) if lever[k][j])
        ny = sum(lever[k][j] * net[k][1] for k in range(n) if lever[k][j])
        force.append(applied[j][2] - sin[j] * nx + cos[j] * ny)
    rates = ca.solve(matrix, ca.vertcat(*force))

    hinge_forces: list[ca.SX] = []
    behind = (0.0, 0.0)
    for k in range(n - 1, 0, -1):  # (C5), from the rear
        ax, ay = rates[0] + bias[k][0], rates[1] + bias[k][1]
        for j in range(k + 1):
            if lever[k][j]:
                ax -= lever[k][j] * rates[2 + j] * sin[j]
                ay += lever[k][j] * rates[2 + j] * cos[j]
        fx, fy = applied[k][0], applied[k][1]
        hx = mass[k] * ax - (fx * cos[k] - fy * sin[k]) + behind[0]
        hy = mass[k] * ay - (fx * sin[k] + fy * cos[k]) + behind[1]
        behind = (hx, hy)
        hinge_forces.insert(0, ca.vertcat(cos[k] * hx + sin[k] * hy, -sin[k] * hx + cos[k] * hy))  # unit k's axes
    return ChainMotion(speed_rates=rates, hinge_forces=hinge_forces)


def _lever_arm(bodies: Sequence[ChainBody], k: int, j: int) -> float:
    """``λ_kj`` of eq (C2): how far unit ``j``'s rotation moves unit ``k``'s CG sideways, per rad/s [m]."""
    if j > k or k == 0:
        return 0.0
    if j == k:
        return -bodies[k].front_hinge
    if j == 0:
        return -bodies[0].rear_hinge
    return -(bodies[j].front_hinge + bodies[j].rear_hinge)
