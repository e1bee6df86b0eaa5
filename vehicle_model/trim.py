"""Steady-state (trim) solver for steady turning and straight running.

In a steady turn every body state is constant: ``u̇ = v̇1 = ṙ1 = ṙ2 = 0``, ``r1 = r2 = r`` and every
transient slip is at rest. Given the speed and either the front steer angle or the kingpin path
curvature, the solver finds ``v1, r, Γ``, the slips, the drive force that holds the speed and
(for a prescribed curvature) the front steer angle. Positions and heading are not part of a trim;
the slope inputs are taken in the frame of a tractor heading along +X (straight crossfall with
``κ = 0``; a slope is not steady in a turn unless it rotates with the vehicle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.optimize import root

from .dynamics import VehicleModel
from .errors import InputError
from .layout import Layout
from .parameters import VehicleParams


@dataclass(frozen=True)
class TrimResult:
    """A steady state.

    Attributes
    ----------
    state : numpy.ndarray
        State vector (position and heading zero).
    inputs : numpy.ndarray
        Input vector.
    layout : Layout
        Names of both vectors.
    """

    state: np.ndarray
    inputs: np.ndarray
    layout: Layout

    def get(self, name: str) -> float:
        """A named state or input."""
        if name in self.layout.states:
            return float(self.state[self.layout.state_index(name)])
        return float(self.inputs[self.layout.input_index(name)])

    @property
    def yaw_rate(self) -> float:
        return self.get("r1")

    def kingpin_velocity(self, params: VehicleParams) -> np.ndarray:
        """Kingpin velocity in tractor axes ``(u, v1 − h1·r)``."""
        return np.array([self.get("u"), self.get("v1") - params.h1 * self.yaw_rate])

    def kingpin_radius(self, params: VehicleParams) -> float:
        """Radius of the kingpin's circle [m] (``inf`` on a straight)."""
        r = self.yaw_rate
        return math.inf if r == 0 else float(np.linalg.norm(self.kingpin_velocity(params)) / abs(r))

    def turn_centre_trailer(self, params: VehicleParams) -> np.ndarray:
        """Instantaneous centre in trailer axes with the origin at the kingpin [m]."""
        g = self.get("gamma")
        vk = self.kingpin_velocity(params)
        # Rotate tractor→trailer axes by R(Γ) (docs/vehicle_dynamics.md §1.1).
        vk2 = np.array([math.cos(g) * vk[0] - math.sin(g) * vk[1], math.sin(g) * vk[0] + math.cos(g) * vk[1]])
        r = self.yaw_rate
        return np.array([-vk2[1] / r, vk2[0] / r])

    def trailer_point_radius(self, params: VehicleParams, station: float) -> float:
        """Radius of the circle traced by the trailer centre-line point at ``station`` (from the kingpin)."""
        c = self.turn_centre_trailer(params)
        return float(math.hypot(station - c[0], c[1]))


def trim(
    params: VehicleParams,
    speed: float,
    *,
    steer: float | None = None,
    kingpin_curvature: float | None = None,
    trailer_steer: dict[str, float] | None = None,
    mu: float | np.ndarray = 0.8,
    slope: tuple[float, float] = (0.0, 0.0),
    model: VehicleModel | None = None,
    tol: float = 1e-10,
) -> TrimResult:
    """Solve for a steady state at forward speed ``speed`` [m/s].

    Parameters
    ----------
    params
        Vehicle.
    speed
        Tractor CG forward speed [m/s].
    steer
        Front (first steerable tractor axle) steer angle [rad]; give this or ``kingpin_curvature``.
    kingpin_curvature
        Signed curvature of the kingpin path [1/m] (positive left); the front steer is solved for.
    trailer_steer
        Fixed steer angles of steerable trailer axles by axle name [rad]; unnamed ones are straight.
    mu
        Friction, one value or one per axle.
    slope
        In-plane gravity direction ``sinθ·(cos ψ_d, sin ψ_d)`` at both bodies, tractor heading +X.
    model
        Prebuilt model of ``params``.
    tol
        Residual tolerance.

    Raises
    ------
    InputError
        Bad arguments, or no steady state found (e.g. beyond the friction limit).
    """
    if (steer is None) == (kingpin_curvature is None):
        raise InputError("give exactly one of steer and kingpin_curvature")
    if kingpin_curvature is not None and kingpin_curvature != 0 and slope != (0.0, 0.0):
        raise InputError("a sloped road is steady only on a straight; use kingpin_curvature = 0 with a slope")
    model = model if model is not None else VehicleModel(params)
    layout = model.layout
    table = params.axle_table
    n_ax = len(layout.axles)
    tractor_steer = [n for n in layout.steerable_axles if table.unit[table.names.index(n)] == 0]
    if not tractor_steer:
        raise InputError("trim needs a steerable tractor axle")
    front = layout.input_index(f"steer_{tractor_steer[0]}")

    u0 = np.zeros(layout.n_inputs)
    u0[layout.mu_slice] = mu
    u0[layout.slope_slice] = np.tile(np.asarray(slope, dtype=float), 2)
    for name, angle in (trailer_steer or {}).items():
        u0[layout.input_index(f"steer_{name}")] = angle
    if steer is not None:
        u0[front] = steer

    # Unknowns z = [v1, r, Γ, F_drive, slips..., (front steer)].
    solve_steer = steer is None
    nz = 4 + n_ax + (1 if solve_steer else 0)
    z = ca.SX.sym("z", nz)
    x = ca.vertcat(0.0, 0.0, 0.0, speed, z[0], z[1], z[2], z[1], z[4 : 4 + n_ax])
    u = ca.SX(u0)
    u[layout.drive_index] = z[3]
    if solve_steer:
        u[front] = z[4 + n_ax]
    xdot = model.rhs_symbolic(x, u)
    residual = [xdot[3], xdot[4], xdot[5], xdot[7], xdot[8:]]
    if solve_steer:
        v_k = ca.sqrt(speed**2 + (z[0] - params.h1 * z[1]) ** 2)
        residual.append(z[1] - kingpin_curvature * v_k)
    res = ca.vertcat(*residual)
    f = ca.Function("trim_res", [z], [res, ca.jacobian(res, z)])

    # Kinematic initial guess (docs/vehicle_dynamics.md §2.3).
    wheelbase = params.tractor_wheelbase()
    if solve_steer:
        r_guess = kingpin_curvature * speed
    else:
        r_guess = speed * math.tan(steer) / wheelbase
    rear_from_cg = -wheelbase - params.tractor.cg_x
    kappa = r_guess / speed if speed != 0 else 0.0
    gamma_guess = math.asin(max(min(params.equivalent_wheelbase() * kappa, 0.95), -0.95))
    z0 = np.zeros(nz)
    z0[0], z0[1], z0[2] = -rear_from_cg * r_guess, r_guess, gamma_guess
    if solve_steer:
        z0[4 + n_ax] = math.atan(wheelbase * kappa)

    sol = root(lambda zz: np.asarray(f(zz)[0]).ravel(), z0, jac=lambda zz: np.asarray(f(zz)[1]), method="hybr", tol=tol)
    resid = np.abs(np.asarray(f(sol.x)[0]).ravel()).max()
    if not sol.success and resid > 1e-6:
        raise InputError(
            f"no steady state found at {speed} m/s (residual {resid:.3g}): the turn may be beyond the friction limit"
        )
    zs = sol.x
    state = np.concatenate([[0.0, 0.0, 0.0, speed, zs[0], zs[1], zs[2], zs[1]], zs[4 : 4 + n_ax]])
    inputs = u0.copy()
    inputs[layout.drive_index] = zs[3]
    if solve_steer:
        inputs[front] = zs[4 + n_ax]
    return TrimResult(state=state, inputs=inputs, layout=layout)
