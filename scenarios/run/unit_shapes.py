"""The units of a combination over a run, as the figures draw them: their names, articulation angles from a run's
columns, body outlines over the run, and body and tyre polygons at one pose.

The units are ``tractor`` (the tractor or rigid truck), ``trailer`` (the first towed unit) and ``unit3``, ``unit4``
behind it; a run records the articulation of each towed unit (``gamma``, then ``gamma2``, ``gamma3``:
:mod:`scenarios.loop.further_units`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vehicle_model.geometry import place_points, towed_outlines, tractor_outline, tractor_points, trailer_frames
from vehicle_model.parameters import VehicleParams

from ..setup.build import STEER_TYRE_INSET

__all__ = ["articulation", "pose_polygons", "unit_names", "unit_outlines", "vehicle_polygons"]


def unit_names(params: VehicleParams) -> tuple[str, ...]:
    """The units of a combination as the figures name them: ``tractor``, ``trailer`` (the first towed unit), then
    ``unit3``, ``unit4``."""
    return ("tractor", "trailer", *(f"unit{k}" for k in range(3, params.n_units + 1)))


def articulation(params: VehicleParams, columns: dict[str, np.ndarray]) -> list[np.ndarray]:
    """The articulation angles of every towed unit from a run's columns: ``gamma``, then ``gamma2``, ``gamma3``."""
    return [columns["gamma"], *(columns[f"gamma{k - 1}"] for k in range(3, params.n_units + 1))]


def unit_outlines(params: VehicleParams, columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Every unit's body outline over a run, ``(n, 4, 2)``, by :func:`unit_names`."""
    x, y, psi1 = columns["X"], columns["Y"], columns["psi1"]
    towed = towed_outlines(params, x, y, psi1, articulation(params, columns))
    return dict(zip(unit_names(params), [tractor_outline(params, x, y, psi1), *towed], strict=True))


def vehicle_polygons(
    params: VehicleParams,
    x: float,
    y: float,
    psi1: float,
    gamma: float,
    steer: dict[str, float] | None = None,
    further: list[float] | None = None,
) -> list[tuple[str, np.ndarray]]:
    """Body outlines and tyre footprints of the combination at one pose: ``[(unit, polygon (k, 2)), …]``.

    ``steer`` maps axle names to steer angles [rad] (columns ``steer_<axle>``); unnamed axles are straight.
    ``further`` holds the articulation angles of the units behind the first towed one (``gamma2``, ``gamma3``).
    """
    steer = steer or {}
    frames = trailer_frames(params, x, y, psi1, [gamma, *(further or [])])
    bodies = [("tractor", params.tractor, lambda local: tractor_points(params, x, y, psi1, local))]
    for name, unit, (origin, heading) in zip(unit_names(params)[1:], params.trailers, frames, strict=True):
        bodies.append((name, unit, lambda local, o=origin, h=heading: place_points(o, h, local)))
    out = [(name, place(_body(unit))) for name, unit, place in bodies]
    for name, body, place in bodies:
        for axle in body.axles:
            half_len, half_w = axle.tyre.unloaded_radius, 0.14 * max(axle.n_tyres // 2, 1)
            lateral = 0.5 * body.width - half_w - STEER_TYRE_INSET
            delta = float(steer.get(axle.name, 0.0))
            c, s = np.cos(delta), np.sin(delta)
            shape = np.array([[half_len, half_w], [-half_len, half_w], [-half_len, -half_w], [half_len, -half_w]])
            turned = shape @ np.array([[c, s], [-s, c]])
            for side in (1.0, -1.0):
                out.append((name + " tyre", place(turned + np.array([axle.x, side * lateral]))))
    return out


def _body(unit: Any) -> np.ndarray:
    """A unit's body rectangle in its own stations (front-left, front-right, rear-right, rear-left)."""
    w = 0.5 * unit.width
    return np.array([[unit.front_x, w], [unit.front_x, -w], [unit.rear_x, -w], [unit.rear_x, w]])


def pose_polygons(
    params: VehicleParams, columns: dict[str, np.ndarray], k: int, steer: dict[str, float] | None = None
) -> list[tuple[str, np.ndarray]]:
    """:func:`vehicle_polygons` at sample ``k`` of a run's columns (every unit's articulation from its column)."""
    angles = [float(a[k]) for a in articulation(params, columns)]
    return vehicle_polygons(
        params, columns["X"][k], columns["Y"][k], columns["psi1"][k], angles[0], steer, further=angles[1:]
    )
