"""The balance explicit static axle loads must keep: a unit's loads carry its weight and its coupling loads, and
their moments balance theirs (statics, :meth:`vehicle_model.parameters.VehicleParams.axle_table`, solves the loads
when none are given)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["LOAD_BALANCE_TOLERANCE", "LOAD_CENTRE_TOLERANCE_M", "check_moments", "check_sum"]

LOAD_BALANCE_TOLERANCE = 0.01
"""Explicit static axle loads of a tractor may miss its weight plus the kingpin load by this share (a weighbridge's
accuracy); a towed unit's front coupling takes the rest of its weight, so its loads balance the forces exactly."""
LOAD_CENTRE_TOLERANCE_M = 0.10
"""Explicit static axle loads must put their centre (Σ F·x / Σ F) within this distance of the station where the
unit's weight and coupling loads need it: their moments balance (a weighbridge's 1 % on axles metres apart moves
the centre by centimetres)."""


def check_sum(field: str, loads: np.ndarray, carried: float) -> None:
    """Refuse ``loads`` [N] (of ``field``'s axles) that do not sum to ``carried`` [N] within
    :data:`LOAD_BALANCE_TOLERANCE`: one line naming the unit, both sums and the tolerance."""
    if abs(loads.sum() - carried) > LOAD_BALANCE_TOLERANCE * carried:
        raise ValueError(
            f"{field}.axles: explicit static loads sum to {loads.sum() / 1e3:.1f} kN, but the unit's weight and "
            f"coupling loads are {carried / 1e3:.1f} kN (force balance, tolerance {LOAD_BALANCE_TOLERANCE:.0%}); "
            "give loads that carry them, or leave static_load out"
        )


def check_moments(field: str, stations: Sequence[float], loads: np.ndarray, moment: float) -> None:
    """Refuse axle ``loads`` [N] at ``stations`` [m] unless their moment about station 0 equals ``moment`` [N·m] (that
    of the unit's weight and coupling loads; a towed unit's front coupling, at its station 0, has none) within
    :data:`LOAD_CENTRE_TOLERANCE_M` of the loads' centre: one line naming the unit, both stations and the tolerance."""
    total = float(loads.sum())
    centre, needed = float(loads @ np.asarray(stations, dtype=float)) / total, moment / total
    if abs(centre - needed) > LOAD_CENTRE_TOLERANCE_M:
        raise ValueError(
            f"{field}.axles: explicit static loads break the moment balance: their centre lies at station "
            f"{centre:.2f} m, the weight and coupling loads need it at {needed:.2f} m (tolerance "
            f"{LOAD_CENTRE_TOLERANCE_M:.2f} m); give loads whose moments balance, or leave static_load out for "
            "statics to solve them"
        )
