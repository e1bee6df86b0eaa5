"""The chain form of the equations of motion (vehicle_model/chain.py).

* For two units it is the tractor–semi-trailer model as it was hand-derived (tests/data/two_unit_model, written
  before the change): ``ẋ`` and the hitch force at the driving ones of 40 points per preset (the braking ones
  predate the service brake on every axle) within 1e-9 relative, a 6 s open-loop run within 1e-9 relative of its
  span.
* For three and four units, without applied loads: the kinetic energy and the linear momentum are conserved (the
  hinges do no work and exert no net force), which a wrong mass matrix or a missing velocity term breaks.
* For a B-double at walking pace in a steady turn, with linear tyres: each unit's turning radius at its hinge follows
  the kinematic chain ``R_{k+1}² = R_k² + c_k² − L_k²`` within 1 %.
"""

from __future__ import annotations

import math
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from vehicle_model.chain import ChainBody, chain_motion, chain_velocities
from vehicle_model.dynamics import VehicleModel
from vehicle_model.presets import VEHICLE_PRESETS

REFERENCE = Path(__file__).parent / "data" / "two_unit_model" / "reference.npz"


@pytest.fixture(scope="module")
def reference() -> dict[str, np.ndarray]:
    with np.load(REFERENCE) as data:
        return {k: data[k] for k in data.files}


TWO_UNIT_PRESETS = ["field", "lst", "lst-unladen", "reference", "reference-unladen"]
"""The presets the reference file pins (the tractor–semi-trailers of the catalogue when it was written)."""


@pytest.mark.parametrize("name", TWO_UNIT_PRESETS)
def test_two_units_are_the_hand_derived_model(name: str, reference: dict[str, np.ndarray]) -> None:
    from tests.data.two_unit_model.make_reference import open_loop_run

    model = VehicleModel(VEHICLE_PRESETS[name](), compile=False)
    # The reference's braking points (a negative force demand) had the brake on the driven axles alone; the model
    # now brakes every axle (tests/test_braking.py), so only the driving points pin the equations of motion.
    driving = reference[f"{name}/u"][:, model.layout.drive_index] >= 0.0
    assert driving.sum() >= 10
    x, u = reference[f"{name}/x"][driving], reference[f"{name}/u"][driving]
    xdot_ref = reference[f"{name}/xdot"][driving]
    xdot = np.array([np.asarray(model.rhs(a, b)).ravel() for a, b in zip(x, u, strict=True)])
    scale = np.maximum(np.abs(xdot_ref), 1e-6 * np.abs(xdot_ref).max(axis=0))
    assert np.max(np.abs(xdot - xdot_ref) / scale) < 1e-9
    hitch = model.output_names.index("hitch_force")
    forces = np.array([np.asarray(model.outputs(a, b)[hitch]).ravel() for a, b in zip(x, u, strict=True)])
    np.testing.assert_allclose(forces, reference[f"{name}/hitch_force"][driving], rtol=1e-9, atol=1e-9 * 1e5)
    run = open_loop_run(model)[::5]
    span = np.ptp(reference[f"{name}/run"], axis=0) + 1e-12
    assert np.max(np.abs(run - reference[f"{name}/run"]) / span) < 1e-9


def _free_chain(bodies: list[ChainBody]) -> ca.Function:
    """``(ψ_1, Γ, w) → (ψ̇_1, Γ̇, ẇ)`` of a chain with no applied load."""
    n = len(bodies)
    psi = ca.SX.sym("psi")
    gamma = ca.SX.sym("gamma", n - 1)
    w = ca.SX.sym("w", n + 2)
    motion = chain_motion(w, gamma, bodies, [ca.SX.zeros(3, 1)] * n)
    rates = ca.vertcat(w[2], *[w[2 + k] - w[3 + k] for k in range(n - 1)], motion.speed_rates)
    return ca.Function("free", [ca.vertcat(psi, gamma, w)], [rates])


def _energy_and_momentum(state: np.ndarray, bodies: list[ChainBody]) -> tuple[float, np.ndarray]:
    n = len(bodies)
    psi1, gamma, w = state[0], state[1:n], state[n:]
    u, v = chain_velocities(list(w), list(gamma), bodies)
    energy, momentum, heading = 0.0, np.zeros(2), psi1
    for k, body in enumerate(bodies):
        if k:
            heading -= gamma[k - 1]
        uk, vk = float(u[k]), float(v[k])
        energy += 0.5 * (body.mass * (uk**2 + vk**2) + body.yaw_inertia * w[2 + k] ** 2)
        c, s = math.cos(heading), math.sin(heading)
        momentum += body.mass * np.array([c * uk - s * vk, s * uk + c * vk])
    return energy, momentum


B_DOUBLE_LIKE = [
    ChainBody(9000.0, 3.0e4, rear_hinge=1.5),
    ChainBody(20000.0, 2.0e5, front_hinge=4.0, rear_hinge=3.5),
    ChainBody(15000.0, 1.5e5, front_hinge=5.0, rear_hinge=4.0),
    ChainBody(3000.0, 4.0e3, front_hinge=2.0),
]


@pytest.mark.parametrize("n_units", [3, 4])
def test_a_free_chain_keeps_its_energy_and_momentum(n_units: int) -> None:
    bodies = B_DOUBLE_LIKE[:n_units]
    f = _free_chain(bodies)
    rng = np.random.default_rng(7)
    state = np.concatenate([[0.3], rng.uniform(-0.6, 0.6, n_units - 1), [8.0, 0.5], rng.uniform(-0.4, 0.4, n_units)])
    e0, p0 = _energy_and_momentum(state, bodies)
    h = 1e-3
    for _ in range(2000):  # 2 s of RK4
        k1 = np.asarray(f(state)).ravel()
        k2 = np.asarray(f(state + 0.5 * h * k1)).ravel()
        k3 = np.asarray(f(state + 0.5 * h * k2)).ravel()
        k4 = np.asarray(f(state + h * k3)).ravel()
        state = state + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    e1, p1 = _energy_and_momentum(state, bodies)
    assert abs(e1 - e0) / e0 < 1e-8
    assert np.linalg.norm(p1 - p0) / np.linalg.norm(p0) < 1e-8
    assert np.ptp([state[1:n_units]]) > 0.0  # the chain did articulate


def test_hinge_forces_balance_the_first_unit_of_a_free_chain() -> None:
    # No applied load: the first unit is accelerated by its rear hinge alone, m_1·a_1 = −R(Γ_1)·H_2 (eq (C4) run
    # from the rear of a four-unit chain forward).
    bodies = B_DOUBLE_LIKE
    gamma = ca.SX.sym("gamma", 3)
    w = ca.SX.sym("w", 6)
    motion = chain_motion(w, gamma, bodies, [ca.SX.zeros(3, 1)] * 4)
    a1 = ca.vertcat(motion.speed_rates[0] - w[1] * w[2], motion.speed_rates[1] + w[0] * w[2])
    h2 = motion.hinge_forces[0]
    c, s = ca.cos(gamma[0]), ca.sin(gamma[0])
    residual = ca.Function(
        "r", [gamma, w], [bodies[0].mass * a1 + ca.vertcat(c * h2[0] + s * h2[1], -s * h2[0] + c * h2[1])]
    )
    rng = np.random.default_rng(3)
    for _ in range(5):
        g, v = rng.uniform(-0.7, 0.7, 3), np.concatenate([[6.0, 0.4], rng.uniform(-0.5, 0.5, 4)])
        assert np.max(np.abs(np.asarray(residual(g, v)))) < 1e-6 * bodies[0].mass  # [N] against forces of 1e3–1e4 N
        assert np.max(np.abs(np.asarray(ca.Function("h", [gamma, w], [h2])(g, v)))) > 100.0  # the hinge does work


def _linear_tyre(c_alpha: float, x: float, delta: float | ca.SX, u: ca.SX, v: ca.SX, r: ca.SX) -> ca.SX:
    """Force (x, y) and moment on a unit from one axle of cornering stiffness ``c_alpha`` at station ``x``."""
    vy = v + x * r
    cd, sd = ca.cos(delta), ca.sin(delta)
    alpha = ca.atan((-sd * u + cd * vy) / (cd * u + sd * vy))
    fy_wheel = -c_alpha * alpha
    fx, fy = -sd * fy_wheel, cd * fy_wheel
    return ca.vertcat(fx, fy, x * fy)


def test_a_b_double_at_walking_pace_follows_the_kinematic_chain() -> None:
    # Tractor (steer 2.0 m ahead of the CG, drive axle 1.8 m behind, fifth wheel 1.5 m behind), lead semi-trailer
    # (kingpin 4.0 m ahead of its CG, axle 3.0 m behind, its fifth wheel 3.5 m behind: 0.5 m behind the axle), rear
    # semi-trailer (kingpin 5.0 m ahead, axle 3.0 m behind); one axle each, so no scrub and, at 1 m/s, no slip.
    bodies = B_DOUBLE_LIKE[:3]
    stations = [(2.0, -1.8), (-3.0,), (-3.0,)]
    c_alpha, speed, steer = 3.0e5, 1.0, 0.15
    w = ca.SX.sym("w", 5)
    gamma = ca.SX.sym("gamma", 2)
    drive = ca.SX.sym("drive")
    u, v = chain_velocities([w[i] for i in range(5)], [gamma[0], gamma[1]], bodies)
    applied = []
    for k, axles in enumerate(stations):
        load = ca.SX.zeros(3, 1)
        for j, x in enumerate(axles):
            load += _linear_tyre(c_alpha, x, steer if (k, j) == (0, 0) else 0.0, u[k], v[k], w[2 + k])
        applied.append(load + (ca.vertcat(drive, 0.0, 0.0) if k == 0 else 0.0))
    f = ca.Function("f", [w, gamma, drive], [chain_motion(w, gamma, bodies, applied).speed_rates])
    z = ca.SX.sym("z", 5)  # v_1, r (every unit's, a steady turn), Γ_1, Γ_2, drive force
    speeds = ca.vertcat(speed, z[0], z[1], z[1], z[1])
    rates = f(speeds, z[2:4], z[4])
    solve = ca.rootfinder("steady", "newton", ca.Function("g", [z], [rates]))
    wheelbase = 3.8
    turn = wheelbase / math.tan(steer)
    sol = np.asarray(solve([0.0, speed / turn, 0.3, 0.3, 0.0])).ravel()
    _, r, g1, g2, _ = sol
    velocities = ca.Function("uv", [w, gamma], [ca.vertcat(*u), ca.vertcat(*v)])
    us, vs = (np.asarray(a).ravel() for a in velocities([speed, sol[0], r, r, r], [g1, g2]))

    def radius(k: int, x: float) -> float:  # the point at station x of unit k turns at radius |V|/|r|
        return math.hypot(us[k], vs[k] + x * r) / abs(r)

    r1 = radius(0, 2.0)  # the steer axle
    lengths = [2.0 + 1.8, 4.0 + 3.0]  # L_k: front reference to the (one) axle
    offsets = [1.5 - 1.8, 3.5 - 3.0]  # c_k: axle to the rear hinge
    r2 = math.sqrt(r1**2 + offsets[0] ** 2 - lengths[0] ** 2)
    r3 = math.sqrt(r2**2 + offsets[1] ** 2 - lengths[1] ** 2)
    assert radius(1, 4.0) == pytest.approx(r2, rel=0.01)
    assert radius(2, 5.0) == pytest.approx(r3, rel=0.01)
    assert radius(2, -3.0) == pytest.approx(math.sqrt(r3**2 - 8.0**2), rel=0.01)
    assert g1 > 0.05 and g2 > 0.05  # a real turn, articulated
