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

so every unit's velocity ``V_k = (u_k, v_k, r_k) = J_k(Γ)·w`` is linear in ``w`` with a Jacobian that depends on the
articulation angles only. The hinge forces do no work in any motion the hinges allow, so Kane's equations
(Kane & Levinson 1985, ch. 6; the partial velocities are the rows of ``J_k``) eliminate them::

    Σ_k J_kᵀ·(F_k − D_k·A_k) = 0,   D_k = diag(m_k, m_k, I_k)                                              (C2)

with ``F_k`` the applied force and moment on unit ``k`` at its CG in its axes (tyres, gravity along the slope,
drag) and ``A_k`` the CG acceleration and yaw acceleration in the unit's own (rotating) axes::

    A_k = J_k·ẇ + (∂V_k/∂Γ)·Γ̇ + (−v_k·r_k, u_k·r_k, 0),   Γ̇_k = r_k − r_{k+1}                              (C3)

(C2) is linear in ``ẇ`` with the symmetric positive definite mass matrix ``M = Σ J_kᵀ D_k J_k``; for two units it is
the 4×4 matrix of docs/vehicle_dynamics.md §1.4 and §2.1. The force that unit ``k + 1`` receives at its front hinge,
in its axes, follows from the rear of the chain forward::

    H_N = m_N·a_N − F_N,   H_k = m_k·a_k − F_k + R(Γ_k)·H_{k+1}                                            (C4)

(``a_k`` the translational part of ``A_k``; ``R(Γ_k)`` turns unit ``k + 1``'s axes into unit ``k``'s; the force a unit
receives from the unit behind is ``−R·H``.)
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
        ``ẇ`` of (C2), ``N + 2`` entries ``[u̇_1, v̇_1, ṙ_1, …, ṙ_N]``.
    hinge_forces : list of casadi.SX
        ``H_{k+1}`` of (C4) for each hinge: the force (x, y) the trailing unit receives at it, in its axes [N].
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
    """Speed rates and hinge forces of the chain, eqs (C2)–(C4).

    Parameters
    ----------
    speeds : casadi.SX
        ``w``, a column of ``N + 2`` symbols (or entries of one state vector).
    articulation : casadi.SX
        ``Γ``, a column of ``N − 1`` symbols.
    bodies : sequence of ChainBody
        The ``N`` units in order.
    applied : sequence of casadi.SX
        ``F_k``: per unit the force (x, y) [N] at its CG and the moment about it [N·m], in its axes, every applied
        load but the hinges'.

    Returns
    -------
    ChainMotion
    """
    n = len(bodies)
    if len(applied) != n:
        raise ValueError(f"a chain of {n} units takes {n} applied loads, got {len(applied)}")
    w = [speeds[i] for i in range(n + 2)]
    gamma = [articulation[i] for i in range(n - 1)]
    u, v = chain_velocities(w, gamma, bodies)
    yaw = w[2:]
    gamma_rate = ca.vertcat(*[yaw[k] - yaw[k + 1] for k in range(n - 1)]) if n > 1 else ca.SX(0, 1)
    mass_matrix = ca.SX.zeros(n + 2, n + 2)
    force = ca.SX.zeros(n + 2, 1)
    bias_accelerations = []
    for k, body in enumerate(bodies):
        velocity = ca.vertcat(u[k], v[k], yaw[k])
        jac = ca.jacobian(velocity, speeds)
        # (C3): the rate of V_k through the articulation, and the rotating axes' terms
        through_angles = ca.jtimes(velocity, articulation, gamma_rate) if n > 1 else ca.SX.zeros(3, 1)
        bias = through_angles + ca.vertcat(-v[k] * yaw[k], u[k] * yaw[k], 0.0)
        inertia = ca.diag(ca.vertcat(body.mass, body.mass, body.yaw_inertia))
        mass_matrix += jac.T @ inertia @ jac
        force += jac.T @ (applied[k] - inertia @ bias)  # (C2)
        bias_accelerations.append((jac, bias))
    rates = ca.solve(mass_matrix, force)
    hinge_forces: list[ca.SX] = []
    behind = None
    for k in range(n - 1, 0, -1):  # (C4), from the rear
        jac, bias = bias_accelerations[k]
        accel = (jac @ rates + bias)[:2]
        h = bodies[k].mass * accel - applied[k][:2]
        if behind is not None:
            c, s = ca.cos(gamma[k]), ca.sin(gamma[k])
            h = h + ca.vertcat(c * behind[0] + s * behind[1], -s * behind[0] + c * behind[1])
        hinge_forces.insert(0, h)
        behind = h
    return ChainMotion(speed_rates=rates, hinge_forces=hinge_forces)
