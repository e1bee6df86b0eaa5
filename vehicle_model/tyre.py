"""Magic Formula lateral tyre force with friction scaling, combined-slip reduction and relaxation.

All functions are written with casadi operations so the one definition serves the symbolic model;
:func:`lateral_force_function` wraps it for numeric use.

Friction scaling
----------------
The road's μ is the tyre's peak lateral friction coefficient at and below the nominal load. Above
the nominal load the peak falls with Pacejka's load sensitivity ``PDY2/PDY1`` (PAC2002,
docs/vehicle_dynamics.md §3.1). So ``μ_y(Fz) = μ·(1 + (PDY2/PDY1)·max(dfz, 0)) ≤ μ`` and ``|F_y| ≤ μ·F_z``
always holds. The cornering stiffness ``K_y`` does not depend on μ (MF ``λμy`` scaling,
docs/vehicle_dynamics.md §3.2): low friction lowers the peak, not the initial slope.
"""

from __future__ import annotations

import casadi as ca

from .parameters import TyreParams


def peak_friction(tyre: TyreParams, fz: ca.SX, mu: ca.SX) -> ca.SX:
    """Load-dependent peak lateral friction coefficient ``μ_y`` (≤ μ)."""
    dfz = (fz - tyre.fz_nominal) / tyre.fz_nominal  # PAC2002 normalised load change
    return mu * (1.0 + (tyre.pdy2 / tyre.pdy1) * ca.fmax(dfz, 0.0))


def pure_lateral_force(
    tyre: TyreParams, slip: ca.SX, fz: ca.SX, mu: ca.SX, stiffness: float | ca.SX | None = None
) -> ca.SX:
    """Pure-slip lateral force of one tyre [N]; positive for positive slip angle ``slip`` [rad].

    PAC2002 lateral force at zero camber with shifts dropped (docs/vehicle_dynamics.md §3.1)::

        D = μ_y·Fz,  K_y = PKY1·FNOMIN·sin(2·atan(Fz/(PKY2·FNOMIN))),  B = K_y/(C·D)
        E = min(PEY1 + PEY2·dfz, 1),  F_y = D·sin(C·atan(B·α − E·(B·α − atan(B·α))))

    ``stiffness`` overrides ``K_y`` (the vehicle model passes the value at the static load).
    """
    dfz = (fz - tyre.fz_nominal) / tyre.fz_nominal
    c = tyre.pcy1
    d = peak_friction(tyre, fz, mu) * fz
    if stiffness is None:
        stiffness = tyre.pky1 * tyre.fz_nominal * ca.sin(2.0 * ca.atan(fz / (tyre.pky2 * tyre.fz_nominal)))
    b = stiffness / (c * d)
    e = ca.fmin(tyre.pey1 + tyre.pey2 * dfz, 1.0)
    ba = b * slip
    return d * ca.sin(c * ca.atan(ba - e * (ba - ca.atan(ba))))


def combined_slip_factor(fx: ca.SX, fz: ca.SX, mu: ca.SX) -> ca.SX:
    """Friction-ellipse reduction of the lateral force under a longitudinal force ``fx``.

    ``sqrt(1 − (Fx/(μ·Fz))²)``, floored at 0.05 so a tyre at its traction limit keeps a little
    lateral force instead of a singular zero (the drive force is capped below μ·Fz anyway).
    """
    ratio = fx / (mu * fz)
    return ca.sqrt(ca.fmax(1.0 - ratio * ratio, 0.0025))


def relaxation_rate(slip_state: ca.SX, v_long: ca.SX, v_lat: ca.SX, relaxation_length: float) -> ca.SX:
    """Time derivative of the transient slip state (first-order relaxation).

    ``σ·dα'/dt + |V_cx|·α' = −V_cy`` (Pacejka 2012, eq. (7.11)) with ``V_cx, V_cy`` the contact
    point's velocity in wheel axes. In steady state ``α' = −V_cy/|V_cx| = tan α``; the force is
    evaluated at ``atan(α')``. At standstill the tyre behaves as a lateral spring, so the model stays
    well posed at walking pace and when stopped. ``relaxation_length`` is σ [m]
    (:meth:`TyreParams.relaxation_length`).
    """
    return (-v_lat - ca.fabs(v_long) * slip_state) / relaxation_length


def low_speed_damping_time(tyre: TyreParams, speed: ca.SX) -> ca.SX:
    """Carcass-damping time constant, full below ``low_speed_fade`` and zero above twice it."""
    w = ca.fmin(ca.fmax(2.0 - ca.fabs(speed) / tyre.low_speed_fade, 0.0), 1.0)
    return tyre.low_speed_damping_time * w


def lateral_force_function(tyre: TyreParams) -> ca.Function:
    """Numeric ``F_y(slip [rad], Fz [N], μ) → N`` for one tyre (pure slip)."""
    slip, fz, mu = ca.SX.sym("slip"), ca.SX.sym("fz"), ca.SX.sym("mu")
    return ca.Function("tyre_fy", [slip, fz, mu], [pure_lateral_force(tyre, slip, fz, mu)])
