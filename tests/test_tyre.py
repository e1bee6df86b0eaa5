"""Magic Formula tyre: reference values, friction scaling, bounds."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from vehicle_model.parameters import TyreParams
from vehicle_model.tyre import combined_slip_factor, lateral_force_function

TYRE = TyreParams()
FY = lateral_force_function(TYRE)


def fy(slip, fz, mu):
    return float(FY(slip, fz, mu))


@pytest.mark.parametrize(("fz_kn", "ky_kn"), [(20, 119.9), (30, 173.7), (35, 198.2), (40, 220.9)])
def test_cornering_stiffness_matches_reference_table(fz_kn, ky_kn):
    # docs/vehicle_dynamics.md §3.1 table: K_y of the PAC2002 315/80 R22.5 tyre.
    assert TYRE.cornering_stiffness(fz_kn * 1e3) / 1e3 == pytest.approx(ky_kn, abs=0.1)


@pytest.mark.parametrize("mu", [0.1, 0.25, 0.5, 0.8, 1.0])
def test_friction_scaling_keeps_the_initial_slope(mu):
    fz = 30e3
    slope = fy(1e-5, fz, mu) / 1e-5
    assert slope == pytest.approx(TYRE.cornering_stiffness(fz), rel=1e-3)


@pytest.mark.parametrize(
    ("scale", "expected"), [(1.0, [0.10, 0.20, 0.37, 0.59, 0.73]), (0.5, [0.10, 0.18, 0.30, 0.37, 0.37])]
)
def test_force_curve_matches_reference_at_30kN(scale, expected):
    # docs/vehicle_dynamics.md §3.2: F_y/F_z at 1, 2, 4, 8, 15 deg for λμ = 1 and 0.5 at 30 kN. At this load the
    # PAC2002 peak coefficient is PDY1 + PDY2·dfz, which is the μ that reproduces λμ = 1.
    fz = 30e3
    dfz = (fz - TYRE.fz_nominal) / TYRE.fz_nominal
    mu = scale * (TYRE.pdy1 + TYRE.pdy2 * dfz)
    ratios = [fy(math.radians(a), fz, mu) / fz for a in (1, 2, 4, 8, 15)]
    assert ratios == pytest.approx(expected, abs=0.006)


@pytest.mark.parametrize("fz", [10e3, 20e3, 35e3, 50e3])
@pytest.mark.parametrize("mu", [0.1, 0.5, 0.8])
def test_force_never_exceeds_mu_fz_and_is_odd(fz, mu):
    slips = np.linspace(-math.pi / 2, math.pi / 2, 2001)
    f = np.array(FY(slips.reshape(1, -1), fz, mu)).ravel()
    assert np.abs(f).max() <= mu * fz * (1 + 1e-12)
    assert np.abs(f).max() >= 0.9 * mu * fz * (
        1 + min(0.0, TYRE.pdy2 / TYRE.pdy1 * (fz - TYRE.fz_nominal) / TYRE.fz_nominal)
    )
    assert f == pytest.approx(-f[::-1], abs=1e-9)


def test_friction_ellipse():
    fz, mu = 30e3, 0.5
    assert float(combined_slip_factor(0.0, fz, mu)) == 1.0
    assert float(combined_slip_factor(0.6 * mu * fz, fz, mu)) == pytest.approx(0.8)
    assert float(combined_slip_factor(mu * fz, fz, mu)) == pytest.approx(0.05)
    assert isinstance(combined_slip_factor(ca.SX.sym("f"), fz, mu), ca.SX)


def test_relaxation_length_matches_reference():
    # PTY1/PTY2 give σ ≈ 0.4 m at 30 kN (docs/vehicle_dynamics.md §3.3).
    assert TYRE.relaxation_length(30e3) == pytest.approx(0.40, abs=0.01)
