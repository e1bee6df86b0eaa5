"""Linear models: Jacobian linearisation of the nonlinear model and the classic 4-state yaw-plane model."""

from __future__ import annotations

from collections.abc import Sequence

import control
import numpy as np

from .dynamics import VehicleModel
from .parameters import GRAVITY, VehicleParams

POSITION_STATES = ("X", "Y", "psi1")


def linearise(
    model: VehicleModel,
    state: np.ndarray,
    inputs: np.ndarray,
    *,
    states: Sequence[str] | None = None,
    input_names: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
) -> control.StateSpace:
    """Linearise ``ẋ = f(x, u)`` at an operating point into a python-control ``StateSpace``.

    Parameters
    ----------
    model
        The vehicle model.
    state, inputs
        Operating point (e.g. from :func:`vehicle_model.trim.trim`).
    states
        States to keep; by default every state except the global position and heading, which do
        not feed back on flat ground.
    input_names
        Inputs to keep; by default the steer inputs and the drive force.
    outputs
        States to output; by default all kept states.

    Returns
    -------
    control.StateSpace
        With named states, inputs and outputs.
    """
    layout = model.layout
    keep = list(states) if states is not None else [s for s in layout.states if s not in POSITION_STATES]
    ins = (
        list(input_names)
        if input_names is not None
        else [f"steer_{n}" for n in layout.steerable_axles] + ["drive_force"]
    )
    outs = list(outputs) if outputs is not None else keep
    ix = [layout.state_index(s) for s in keep]
    iu = [layout.input_index(s) for s in ins]
    a_full = np.asarray(model.jac_x(state, inputs))
    b_full = np.asarray(model.jac_u(state, inputs))
    a = a_full[np.ix_(ix, ix)]
    b = b_full[np.ix_(ix, iu)]
    c = np.zeros((len(outs), len(keep)))
    for row, name in enumerate(outs):
        c[row, keep.index(name)] = 1.0
    d = np.zeros((len(outs), len(ins)))
    return control.ss(a, b, c, d, states=keep, inputs=ins, outputs=outs)


def axle_cornering_stiffness(params: VehicleParams) -> np.ndarray:
    """Linear cornering stiffness of every axle at its static load [N/rad], layout order."""
    return params.axle_cornering_stiffness()


def linear_yaw_plane_model(
    params: VehicleParams, speed: float, cornering_stiffness: np.ndarray | None = None
) -> control.StateSpace:
    """The 4-state linear model of docs/vehicle_dynamics.md §2.1 (constant speed, small Γ, linear tyres).

    States ``[v1, r1, r2, gamma]``; inputs the steer of every steerable axle (layout order) and the
    lateral gravity forces per unit mass ``[g_y1, g_y2]`` (camber, fraction of g).
    ``E·ẋ = A·x + B·u`` with the symmetric mass matrix
    ``E = [[m1+m2, −m2h1, −m2h2], [−m2h1, I1+m2h1², m2h1h2], [−m2h2, m2h1h2, I2+m2h2²]]``.

    Parameters
    ----------
    params
        Vehicle.
    speed
        Constant forward speed [m/s].
    cornering_stiffness
        Per-axle stiffness [N/rad]; defaults to the tyres' at static load.
    """
    t = params.axle_table
    c_ax = axle_cornering_stiffness(params) if cornering_stiffness is None else np.asarray(cornering_stiffness, float)
    m1, m2 = params.tractor.mass, params.trailer.mass
    i1, i2 = params.tractor.yaw_inertia, params.trailer.yaw_inertia
    h1, h2, u = params.h1, params.h2, speed
    e = np.array(
        [
            [m1 + m2, -m2 * h1, -m2 * h2],
            [-m2 * h1, i1 + m2 * h1**2, m2 * h1 * h2],
            [-m2 * h2, m2 * h1 * h2, i2 + m2 * h2**2],
        ]
    )
    tr, tl = t.unit == 0, t.unit == 1
    a1, c1 = t.x_cg[tr], c_ax[tr]
    a2, c2 = t.x_cg[tl], c_ax[tl]
    # Y1 = Σ C1i (δ1i − (v1 + a1i r1)/u); N1 = Σ a1i C1i (…); Y2, N2 with v2 = v1 − h1 r1 − h2 r2 + u Γ.
    # Partial derivatives w.r.t. [v1, r1, r2, Γ]:
    dy1 = np.array([-c1.sum() / u, -(c1 * a1).sum() / u, 0.0, 0.0])
    dn1 = np.array([-(c1 * a1).sum() / u, -(c1 * a1**2).sum() / u, 0.0, 0.0])
    dv2 = np.array([1.0, -h1, -h2, u])  # ∂v2/∂x
    dy2 = -(c2.sum() / u) * dv2 - np.array([0.0, 0.0, (c2 * a2).sum() / u, 0.0])
    dn2 = -((c2 * a2).sum() / u) * dv2 - np.array([0.0, 0.0, (c2 * a2**2).sum() / u, 0.0])
    mu_r1 = np.array([0.0, 1.0, 0.0, 0.0])
    rhs = np.vstack(
        [
            dy1 + dy2 - (m1 + m2) * u * mu_r1,  # Y1 + Y2 − (m1+m2) u r1
            dn1 - h1 * dy2 + m2 * h1 * u * mu_r1,  # N1 − h1 Y2 + m2 h1 u r1
            dn2 - h2 * dy2 + m2 * h2 * u * mu_r1,  # N2 − h2 Y2 + m2 h2 u r1
        ]
    )
    steerable = np.flatnonzero(t.steerable)
    b_steer = np.zeros((3, len(steerable)))
    for col, k in enumerate(steerable):
        ck, ak = c_ax[k], t.x_cg[k]
        if t.unit[k] == 0:
            b_steer[:, col] = [ck, ak * ck, 0.0]
        else:
            b_steer[:, col] = [ck, -h1 * ck, (ak - h2) * ck]
    # Gravity per unit mass: G1 = m1 g g_y1, G2 = m2 g g_y2 enter like Y1 and Y2.
    b_grav = np.array([[m1, m2], [0.0, -h1 * m2], [0.0, -h2 * m2]]) * GRAVITY
    e_inv = np.linalg.inv(e)
    a = np.zeros((4, 4))
    a[:3] = e_inv @ rhs
    a[3] = [0.0, 1.0, -1.0, 0.0]  # Γ̇ = r1 − r2
    b = np.zeros((4, b_steer.shape[1] + 2))
    b[:3] = e_inv @ np.hstack([b_steer, b_grav])
    names_in = [f"steer_{t.names[k]}" for k in steerable] + ["gravity_y_tractor", "gravity_y_trailer"]
    return control.ss(
        a,
        b,
        np.eye(4),
        np.zeros((4, b.shape[1])),
        states=["v1", "r1", "r2", "gamma"],
        inputs=names_in,
        outputs=["v1", "r1", "r2", "gamma"],
    )
