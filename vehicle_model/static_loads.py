"""Static axle loads: solved by statics from the units (:func:`solve_loads`, one load group per towed unit and two
on the tractor when no load is given), and the balance explicit loads must keep: a unit's loads carry its weight and
its coupling loads, and their moments balance theirs."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["LOAD_BALANCE_TOLERANCE", "LOAD_CENTRE_TOLERANCE_M", "check_moments", "check_sum", "solve_loads"]

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


def solve_loads(tractor: Any, trailers: Sequence[Any], gravity: float) -> tuple[list[np.ndarray], list[float]]:
    """Static axle loads per unit (the tractor's, then each towed unit's) and each towed unit's kingpin load [N],
    solved from the rear forward: explicit ``static_load`` s are checked (:func:`check_sum`, :func:`check_moments`),
    otherwise one load group per towed unit and two on the tractor share the weight by statics.

    Parameters
    ----------
    tractor, trailers
        The units' parameters (:class:`vehicle_model.parameters.TractorParams`, ``TrailerParams``).
    gravity
        The acceleration of gravity [m/s²].

    Raises
    ------
    ValueError
        A layout statics cannot solve, or explicit loads out of balance (one line naming the unit).
    """
    trailer_loads: list[np.ndarray] = []
    kingpins: list[float] = []
    behind = 0.0  # the kingpin load of the trailer behind, on this one's fifth wheel
    for i in range(len(trailers) - 1, -1, -1):
        tl = trailers[i]
        field = "trailer" if i == 0 else f"rear_trailers[{i - 1}]"
        weight = tl.mass * gravity + behind
        if all(a.static_load is not None for a in tl.axles):
            loads = np.array([a.static_load for a in tl.axles], dtype=float)
            kingpin = weight - loads.sum()
            if kingpin < 0 or (not tl.front_load and abs(kingpin) > 1e-9 * weight):
                raise ValueError(f"{field}.axles: explicit static loads do not carry the weight on them")
            # Moments about the kingpin (station 0, where the kingpin load acts): Σ F_j·x_j = W·cg + K_behind·x_5w
            fifth = tl.fifth_wheel_x if tl.fifth_wheel_x is not None else 0.0
            check_moments(field, [a.x for a in tl.axles], loads, tl.mass * gravity * tl.cg_x + behind * fifth)
        else:
            groups = _groups(tl.axles)
            if len(groups) != 1:
                raise ValueError(
                    f"{field}.axles: statics need exactly one load group on a towed unit "
                    f"(found {sorted(groups)}); give static_load on every axle of it instead"
                )
            if tl.front_load:
                x_group = float(np.mean([a.x for a in tl.axles]))
                # Moments about the axle-group centre: W·(cg − x_g) + K_behind·(x_5w − x_g) = K·(0 − x_g)
                fifth = tl.fifth_wheel_x if tl.fifth_wheel_x is not None else x_group
                moment = tl.mass * gravity * (tl.cg_x - x_group) + behind * (fifth - x_group)
                if x_group >= 0 or moment <= 0:
                    raise ValueError(f"{field}.cg_x must lie ahead of the axle group for a positive kingpin load")
                kingpin = moment / (0.0 - x_group)
            else:  # a drawbar hinged in pitch: the axles carry everything
                kingpin = 0.0
            loads = np.full(len(tl.axles), (weight - kingpin) / len(tl.axles))
        trailer_loads.insert(0, loads)
        kingpins.insert(0, float(kingpin))
        behind = kingpin
    tr = tractor
    kingpin = kingpins[0]
    if all(a.static_load is not None for a in tr.axles):
        tractor_loads = np.array([a.static_load for a in tr.axles], dtype=float)
        check_sum("tractor", tractor_loads, tr.mass * gravity + kingpin)  # its weight and the kingpin load
        moment = tr.mass * gravity * tr.cg_x + kingpin * tr.fifth_wheel_x
        check_moments("tractor", [a.x for a in tr.axles], tractor_loads, moment)
    else:
        groups = _groups(tr.axles)
        if len(groups) != 2:
            raise ValueError(
                "tractor.axles: statics need exactly two load groups on a tractor "
                f"(found {sorted(groups)}); give static_load on every tractor axle instead"
            )
        (_ga, ia), (_gb, ib) = sorted(groups.items(), key=lambda kv: -np.mean([tr.axles[i].x for i in kv[1]]))
        xa = float(np.mean([tr.axles[i].x for i in ia]))
        xb = float(np.mean([tr.axles[i].x for i in ib]))
        w = tr.mass * gravity
        # Two supports at xa (front group) and xb (rear group): weight at cg_x, kingpin at fifth_wheel_x.
        load_b = (w * (xa - tr.cg_x) + kingpin * (xa - tr.fifth_wheel_x)) / (xa - xb)
        load_a = w + kingpin - load_b
        if load_a <= 0 or load_b <= 0:
            raise ValueError("tractor: CG and fifth wheel give a non-positive axle-group load")
        tractor_loads = np.zeros(len(tr.axles))
        tractor_loads[ia] = load_a / len(ia)
        tractor_loads[ib] = load_b / len(ib)
    return [tractor_loads, *trailer_loads], kingpins


def _groups(axles: Sequence[Any]) -> dict[str, list[int]]:
    groups: dict[str, list[int]] = {}
    for i, a in enumerate(axles):
        groups.setdefault(a.load_group, []).append(i)
    return groups
