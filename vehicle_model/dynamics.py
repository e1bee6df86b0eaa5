"""The nonlinear yaw-plane tractor–semi-trailer model, defined once in casadi.

Two rigid bodies, tractor (unit 1) and semi-trailer (unit 2), joined at the kingpin; any number of
axles per unit, lumped on the centre line; any axle may be steered. The tyre forces follow from each unit's
velocity; the equations of motion are those of a chain of units (:mod:`vehicle_model.chain`: Kane's equations with
the hinge forces eliminated, here for two units: a symmetric 4×4 mass matrix in ``[u̇, v̇1, ṙ1, ṙ2]``,
docs/vehicle_dynamics.md §1.1 and §1.4, extended with the tractor longitudinal equation so that the forward speed
follows from the drive force instead of being prescribed); the hitch force is recovered after.

From this one definition :class:`VehicleModel` derives the right-hand side, a fixed-step RK4
step, the multi-step integrator, the outputs and the Jacobians.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np

from . import tyre as tyre_model
from .chain import ChainBody, chain_motion, chain_velocities
from .codegen import compile_library, load_functions
from .layout import Layout
from .parameters import GRAVITY, VehicleParams
from .period import period_source

AIR_DENSITY = 1.2
"""Air density for aerodynamic drag [kg/m³]."""

TRACTION_MARGIN = 0.95
"""Drive and brake force per axle are capped at this fraction of μ·Fz (no wheel spin or lock is modelled)."""

ROLLING_SPEED = 0.1
"""Contact-point speed [m/s] over which rolling resistance and brake force change sign (``tanh(v/ROLLING_SPEED)``):
both oppose the wheel's travel and vanish at standstill instead of pushing the vehicle backwards."""


def axle_force_demand(
    force: ca.SX, static_load: float, driven: bool, driven_load: float, total_load: float, v_long: ca.SX
) -> ca.SX:
    """The longitudinal force asked of one axle [N] by the signed demand ``force`` (before its friction cap).

    A positive demand drives: it is shared among the driven axles in proportion to their static load
    (``force·F_z0/ΣF_z0,driven``; none on the others). A negative demand is the service brake of every axle of every
    unit: shared among all axles in proportion to their static load (``force·F_z0/ΣF_z0``, docs/vehicle_dynamics.md
    §1.6), against the contact point's forward speed ``v_long`` (``tanh(v_long/ROLLING_SPEED)``).
    """
    brake = force * static_load / total_load * ca.tanh(v_long / ROLLING_SPEED)
    drive = force * static_load / driven_load if driven else ca.SX(0.0)
    return ca.if_else(force >= 0.0, drive, brake)


def in_plane_gravity(sx: Any, sy: Any, cos_psi: Any, sin_psi: Any) -> tuple[Any, Any]:
    """Gravity's in-plane part per unit mass ``(g_x, g_y)`` [m/s²] in the axes of a body heading ``ψ``, from the
    road's global slope vector ``(s_x, s_y)`` (docs/vehicle_dynamics.md §1.3); numbers or casadi symbols."""
    return (
        GRAVITY * (sx * cos_psi + sy * sin_psi),
        GRAVITY * (-sx * sin_psi + sy * cos_psi),
    )


@dataclass(frozen=True)
class SymbolicModel:
    """Symbols and expressions of the model."""

    x: ca.SX
    u: ca.SX
    xdot: ca.SX
    outputs: dict[str, ca.SX]


def define_model(params: VehicleParams) -> SymbolicModel:
    """Build the symbolic right-hand side ``ẋ = f(x, u)`` and the named outputs."""
    layout = Layout.for_vehicle(params)
    table = params.axle_table
    x = ca.SX.sym("x", layout.n_states)
    u_in = ca.SX.sym("u", layout.n_inputs)

    _, _, psi1, u, v1, r1, gamma, r2 = (x[i] for i in range(8))
    slip_state = x[layout.slip_slice]
    trailing = x[layout.trailing_slice]  # (Γ_k, r_{k+1}) of further semi-trailers
    n_units = params.n_units
    steer_in = u_in[layout.steer_slice]
    drive_force = u_in[layout.drive_index]
    mu = u_in[layout.mu_slice]
    slope = u_in[layout.slope_slice]

    # The units as a chain (vehicle_model/chain.py): each fifth wheel e_k behind its unit's CG, each kingpin f_k
    # ahead of its trailer's; eq (C1) gives every trailer's CG velocity (docs/vehicle_dynamics.md §1.1).
    bodies = tuple(
        ChainBody(unit.mass, unit.yaw_inertia, front_hinge=front, rear_hinge=rear)
        for unit, (front, rear) in zip(params.units, params.hinge_distances(), strict=True)
    )
    angles = [gamma] + [trailing[2 * i] for i in range(n_units - 2)]
    yaw = [r1, r2] + [trailing[2 * i + 1] for i in range(n_units - 2)]
    speeds = ca.vertcat(u, v1, *yaw)
    articulation = ca.vertcat(*angles)
    unit_u, unit_v = chain_velocities([u, v1, *yaw], angles, bodies)
    u2, v2 = unit_u[1], unit_v[1]
    headings = [psi1]
    for angle in angles:
        headings.append(headings[-1] - angle)
    gamma_dot = r1 - r2

    # In-plane gravity per body (docs/vehicle_dynamics.md §1.3), from the global slope vector.
    def body_gravity(sx: ca.SX, sy: ca.SX, psi: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        gx, gy = in_plane_gravity(sx, sy, ca.cos(psi), ca.sin(psi))
        cos_theta = ca.sqrt(ca.fmax(1.0 - sx * sx - sy * sy, 0.0))
        return gx, gy, cos_theta

    gravity = [body_gravity(slope[2 * k], slope[2 * k + 1], headings[k]) for k in range(n_units)]

    # Drive force shared among the driven axles, brake force among all axles, in proportion to their static load.
    driven_load = float(np.sum(table.static_load[table.driven]))
    total_load = float(np.sum(table.static_load))

    steer_iter = iter(range(len(layout.steerable_axles)))
    fx_body = [ca.SX(0.0) for _ in range(n_units)]
    fy_body = [ca.SX(0.0) for _ in range(n_units)]
    mz_body = [ca.SX(0.0) for _ in range(n_units)]
    slip_dot, out_fy, out_fx, out_fz, out_slip = [], [], [], [], []
    for k, _name in enumerate(table.names):
        unit = int(table.unit[k])
        tyre = table.tyres[k]
        n = float(table.n_tyres[k])
        a = float(table.x_cg[k])
        delta = steer_in[next(steer_iter)] if table.steerable[k] else ca.SX(0.0)
        ub, vb, rb = unit_u[unit], unit_v[unit], yaw[unit]
        fz_static = float(table.static_load[k]) / n
        fz = table.static_load[k] * gravity[unit][2]
        fz_tyre = fz / n
        # Cornering stiffness and relaxation length at the static load: on a slope θ the load falls by
        # cos θ ≥ 0.995 (θ ≤ 10 %), which moves them by < 0.5 %; the peak force uses the actual load.
        stiffness = float(tyre.cornering_stiffness(fz_static))
        sigma = float(tyre.relaxation_length(fz_static))
        # Contact-point velocity in wheel axes (docs/vehicle_dynamics.md §1.2).
        vy_body = vb + a * rb
        cd, sd = ca.cos(delta), ca.sin(delta)
        v_cx = cd * ub + sd * vy_body
        v_cy = -sd * ub + cd * vy_body
        # Longitudinal wheel force: rolling resistance and the drive or brake share, capped by the axle's friction.
        fx_w = -tyre.rolling_resistance * fz * ca.tanh(v_cx / ROLLING_SPEED)
        limit = TRACTION_MARGIN * mu[k] * fz
        demand = axle_force_demand(
            drive_force, table.static_load[k], bool(table.driven[k]), driven_load, total_load, v_cx
        )
        fx_w = fx_w + ca.fmin(ca.fmax(demand, -limit), limit)
        # Transient slip with low-speed carcass damping (see tyre.relaxation_rate).
        alpha_dot = tyre_model.relaxation_rate(slip_state[k], v_cx, v_cy, sigma)
        alpha_eff = ca.atan(slip_state[k] + tyre_model.low_speed_damping_time(tyre, v_cx) * alpha_dot)
        fy_w = (
            n
            * tyre_model.pure_lateral_force(tyre, alpha_eff, fz_tyre, mu[k], stiffness)
            * tyre_model.combined_slip_factor(fx_w, fz, mu[k])
        )
        fx_b = fx_w * cd - fy_w * sd
        fy_b = fx_w * sd + fy_w * cd
        fx_body[unit] += fx_b
        fy_body[unit] += fy_b
        mz_body[unit] += a * fy_b
        slip_dot.append(alpha_dot)
        out_fy.append(fy_w)
        out_fx.append(fx_w)
        out_fz.append(fz)
        out_slip.append(ca.atan(slip_state[k]))

    f_aero = -0.5 * AIR_DENSITY * params.tractor.drag_area * u * ca.fabs(u)

    # Newton–Euler with the hinge forces eliminated (vehicle_model/chain.py, eqs (C2)–(C4); the tractor's
    # longitudinal equation included, so the forward speed follows from the drive force).
    applied = [
        ca.vertcat(fx_body[k] + unit.mass * gravity[k][0], fy_body[k] + unit.mass * gravity[k][1], mz_body[k])
        for k, unit in enumerate(params.units)
    ]
    applied[0][0] += f_aero
    motion = chain_motion(speeds, articulation, bodies, applied)
    u_dot, v1_dot, r1_dot, r2_dot = (motion.speed_rates[i] for i in range(4))
    trailing_dot = []
    for k in range(2, n_units):  # (Γ̇_k, ṙ_{k+1}) of the further trailers
        trailing_dot += [yaw[k - 1] - yaw[k], motion.speed_rates[2 + k]]
    hitch_x, hitch_y = motion.hinge_forces[0][0], motion.hinge_forces[0][1]

    xdot = ca.vertcat(
        u * ca.cos(psi1) - v1 * ca.sin(psi1),
        u * ca.sin(psi1) + v1 * ca.cos(psi1),
        r1,
        u_dot,
        v1_dot,
        r1_dot,
        gamma_dot,
        r2_dot,
        ca.vertcat(*slip_dot),
        *trailing_dot,
    )
    outputs = {
        "fy": ca.vertcat(*out_fy),
        "fx": ca.vertcat(*out_fx),
        "fz": ca.vertcat(*out_fz),
        "slip": ca.vertcat(*out_slip),
        "mu_used": mu,
        "hitch_force": ca.vertcat(hitch_x, hitch_y),
        "trailer_velocity": ca.vertcat(u2, v2),
    }
    return SymbolicModel(x=x, u=u_in, xdot=xdot, outputs=outputs)


def rk4_step_expr(f: ca.Function, x: ca.SX, u: ca.SX, h: ca.SX) -> ca.SX:
    """One classical Runge–Kutta 4 step of ``ẋ = f(x, u)`` with inputs held."""
    k1 = f(x, u)
    k2 = f(x + 0.5 * h * k1, u)
    k3 = f(x + 0.5 * h * k2, u)
    k4 = f(x + h * k3, u)
    return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


class VehicleModel:
    """Numeric functions of one vehicle, all generated from :func:`define_model`.

    Parameters
    ----------
    params
        The vehicle.
    compile
        Generate C code and compile it with the system C compiler (cached on disk) for speed;
        falls back to casadi's virtual machine when no compiler is found.

    Attributes
    ----------
    rhs : casadi.Function
        ``(x, u) → ẋ``.
    rhs_symbolic : casadi.Function
        The same, uncompiled, for use inside other symbolic expressions.
    rk4_step : casadi.Function
        ``(x, u, h) → x⁺``, one RK4 step of length ``h``.
    outputs : casadi.Function
        ``(x, u) → (fy, fx, fz, slip, mu_used, hitch_force, trailer_velocity)``.
    jac_x, jac_u : casadi.Function
        ``(x, u) → ∂ẋ/∂x``, ``∂ẋ/∂u``.
    library : pathlib.Path or None
        The compiled shared library (with the control-period function of :mod:`.period`); ``None``
        when the functions run in casadi's virtual machine.
    """

    def __init__(self, params: VehicleParams, compile: bool = True) -> None:
        self.params = params
        self.layout = Layout.for_vehicle(params)
        sym = define_model(params)
        self.symbolic = sym
        rhs = ca.Function("rhs", [sym.x, sym.u], [sym.xdot], ["x", "u"], ["xdot"])
        h = ca.SX.sym("h")
        step = ca.Function(
            "rk4_step", [sym.x, sym.u, h], [rk4_step_expr(rhs, sym.x, sym.u, h)], ["x", "u", "h"], ["x_next"]
        )
        out_names = list(sym.outputs)
        outputs = ca.Function("outputs", [sym.x, sym.u], list(sym.outputs.values()), ["x", "u"], out_names)
        jac_x = ca.Function("jac_x", [sym.x, sym.u], [ca.jacobian(sym.xdot, sym.x)], ["x", "u"], ["A"])
        jac_u = ca.Function("jac_u", [sym.x, sym.u], [ca.jacobian(sym.xdot, sym.u)], ["x", "u"], ["B"])
        self.rhs_symbolic = rhs  # callable on casadi symbols (a compiled library is not)
        funcs = [rhs, step, outputs, jac_x, jac_u]
        # the control-period function (vehicle_model/period.py) is compiled into the same library
        extra = period_source(step, self.layout.n_states, self.layout.n_inputs)
        self.library = compile_library(funcs, f"vehicle_{params.name}", extra) if compile else None
        compiled = load_functions(funcs, self.library) if self.library is not None else None
        self.compiled = compiled is not None
        self.rhs, self.rk4_step, self.outputs, self.jac_x, self.jac_u = compiled if compiled is not None else funcs
        self.output_names = tuple(out_names)

    @cached_property
    def _integrators(self) -> dict[int, ca.Function]:
        return {}

    def integrator(self, substeps: int) -> ca.Function:
        """``(x, u, h) → x`` after ``substeps`` RK4 steps of length ``h`` with inputs held.

        Also returns every intermediate state as a second output ``(n_states, substeps)``.
        """
        if substeps < 1:
            raise ValueError(f"substeps = {substeps} must be at least 1")
        cache = self._integrators
        if substeps not in cache:
            x = ca.MX.sym("x", self.layout.n_states)
            u = ca.MX.sym("u", self.layout.n_inputs)
            h = ca.MX.sym("h")
            acc = self.rk4_step.mapaccum("rk4_acc", substeps, [0], [0])
            traj = acc(x, ca.repmat(u, 1, substeps), ca.repmat(h, 1, substeps))
            cache[substeps] = ca.Function(
                f"advance_{substeps}", [x, u, h], [traj[:, -1], traj], ["x", "u", "h"], ["x_end", "trajectory"]
            )
        return cache[substeps]
