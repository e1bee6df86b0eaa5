"""The specification of a combination as an assessment opens with it: its units, dimensions, axle groups and their
static loads, and its mass.

Everything is read from the model's :class:`~vehicle_model.parameters.VehicleParams` (what a run drives), so a
preset and a combination file give the same summary: the axle loads are the model's statics
(:attr:`~vehicle_model.parameters.VehicleParams.axle_table`: each towed unit's load solved about its axle group from
the rear forward, the towing unit's between its two load groups, or the loads a file gives). ``offtrack list
--vehicle NAME|FILE`` prints it (:func:`specification_tables`) and ``assessment.md`` opens with it
(:func:`specification_lines`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from rich import box
from rich.table import Table
from rich.text import Text

from vehicle_model.combination import CombinationSpec
from vehicle_model.geometry import towed_outlines, tractor_outline
from vehicle_model.parameters import GRAVITY, VehicleParams
from vehicle_model.presets import catalogue_vehicle

__all__ = [
    "AxleGroupSpec",
    "UnitSpecification",
    "VehicleSpecification",
    "overall_length",
    "specification_lines",
    "specification_tables",
    "unit_kinds",
    "vehicle_specification",
]


def unit_kinds(vehicle: str | CombinationSpec) -> tuple[str, ...] | None:
    """Each unit's kind of a validated ``vehicle`` field (a preset's name or a combination); None for a preset that
    is not a catalogue file."""
    if isinstance(vehicle, CombinationSpec):
        return tuple(u.kind for u in vehicle.units)
    try:
        return tuple(u.kind for u in catalogue_vehicle(vehicle).units)
    except ValueError:
        return None


def overall_length(params: VehicleParams) -> float:
    """Overall length of the combination standing straight [m]: its frontmost to its rearmost point."""
    zero = np.zeros(1)
    corners = [tractor_outline(params, zero, zero, zero)]
    corners += towed_outlines(params, zero, zero, zero, [zero] * (params.n_units - 1))
    x = np.concatenate([c[..., 0].ravel() for c in corners])
    return float(x.max() - x.min())


@dataclass(frozen=True)
class AxleGroupSpec:
    """One axle group of a unit: the axles sharing a load group.

    Attributes
    ----------
    unit
        The unit's label (:attr:`UnitSpecification.label`).
    name
        The load group's name.
    axles
        The axles' names, front to rear.
    stations
        Each axle's station [m] in its unit's stations (the towing unit's from its front axle on the ground, a towed
        unit's from its front coupling, negative behind it).
    tyres
        Tyres on the group.
    steerable, driven
        How many of its axles are steerable, and driven.
    load
        Static vertical load on the group [N].
    """

    unit: str
    name: str
    axles: tuple[str, ...]
    stations: tuple[float, ...]
    tyres: int
    steerable: int
    driven: int
    load: float


@dataclass(frozen=True)
class UnitSpecification:
    """One unit: its label, mass, body and the load its front coupling carries.

    Attributes
    ----------
    label
        ``unit 1`` (the towing unit) … ``unit N``, with the unit's kind where known.
    mass
        [kg].
    length, width
        Body length and width [m].
    coupling_load
        Static vertical load the unit puts on the coupling it hangs on [N]; None for the towing unit.
    """

    label: str
    mass: float
    length: float
    width: float
    coupling_load: float | None


@dataclass(frozen=True)
class VehicleSpecification:
    """A combination's specification (module docstring).

    Attributes
    ----------
    name
        The combination's name.
    overall_length
        Frontmost to rearmost point standing straight [m].
    width
        The widest unit's width [m].
    mass
        Sum of the units' masses [kg].
    units, groups
        The units front to rear and their axle groups.
    """

    name: str
    overall_length: float
    width: float
    mass: float
    units: tuple[UnitSpecification, ...]
    groups: tuple[AxleGroupSpec, ...]

    @property
    def axle_load_sum(self) -> float:
        """Sum of the static axle-group loads [N]: the combination's weight on level ground."""
        return float(sum(g.load for g in self.groups))


def _label(index: int, kinds: tuple[str, ...] | None) -> str:
    kind = kinds[index].replace("_", " ") if kinds is not None and index < len(kinds) else None
    return f"unit {index + 1}" + (f" ({kind})" if kind else "")


def vehicle_specification(params: VehicleParams, kinds: tuple[str, ...] | None = None) -> VehicleSpecification:
    """The specification of ``params``.

    Parameters
    ----------
    params
        The combination the model drives.
    kinds
        Each unit's kind (``tractor``, ``semi_trailer``, …) from the combination file or preset, for the labels.

    Returns
    -------
    VehicleSpecification
    """
    table = params.axle_table
    units = params.units
    loads = np.asarray(table.static_load, dtype=float)
    coupling: list[float | None] = [None] * len(units)
    behind = 0.0  # the coupling load of the unit behind, carried by this one
    for k in range(len(units) - 1, 0, -1):
        on_axles = float(loads[table.unit == k].sum())
        coupling[k] = units[k].mass * GRAVITY + behind - on_axles
        behind = coupling[k]
    unit_specs, groups = [], []
    for k, unit in enumerate(units):
        label = _label(k, kinds)
        unit_specs.append(UnitSpecification(label, unit.mass, unit.length, unit.width, coupling[k]))
        unit_loads = loads[table.unit == k]
        named: dict[str, list[int]] = {}
        for i, axle in enumerate(unit.axles):
            named.setdefault(axle.load_group, []).append(i)
        for group, members in named.items():
            axles = [unit.axles[i] for i in members]
            groups.append(
                AxleGroupSpec(
                    unit=label,
                    name=group,
                    axles=tuple(a.name for a in axles),
                    stations=tuple(float(a.x) for a in axles),
                    tyres=sum(a.n_tyres for a in axles),
                    steerable=sum(a.steerable for a in axles),
                    driven=sum(a.driven for a in axles),
                    load=float(unit_loads[members].sum()),
                )
            )
    return VehicleSpecification(
        name=params.name,
        overall_length=overall_length(params),
        width=max(u.width for u in units),
        mass=float(sum(u.mass for u in units)),
        units=tuple(unit_specs),
        groups=tuple(groups),
    )


def _tonnes(newtons: float) -> str:
    return f"{newtons / GRAVITY / 1000.0:.2f}"


def _stations(stations: tuple[float, ...]) -> str:
    return ", ".join(f"{x:.2f}" for x in stations)


def _group_cells(group: AxleGroupSpec) -> list[str]:
    return [
        group.unit,
        group.name,
        ", ".join(group.axles),
        _stations(group.stations),
        str(group.tyres),
        str(group.steerable),
        str(group.driven),
        _tonnes(group.load),
    ]


GROUP_HEADERS = ("unit", "group", "axles", "stations [m]", "tyres", "steered", "driven", "load [t]")
UNIT_HEADERS = ("unit", "mass [t]", "length [m]", "width [m]", "on coupling [t]")
WRAPPING = ("unit", "axles", "stations [m]")
"""Columns whose cells may wrap in a narrow terminal (numbers and names never do)."""


def _unit_cells(unit: UnitSpecification) -> list[str]:
    coupling = "—" if unit.coupling_load is None else _tonnes(unit.coupling_load)
    return [unit.label, f"{unit.mass / 1000.0:.2f}", f"{unit.length:.2f}", f"{unit.width:.2f}", coupling]


def _summary(spec: VehicleSpecification) -> str:
    return (
        f"{spec.name}: {len(spec.units)} units, overall length {spec.overall_length:.2f} m straight, width "
        f"{spec.width:.2f} m, mass {spec.mass / 1000.0:.2f} t (static axle loads sum to "
        f"{_tonnes(spec.axle_load_sum)} t on level ground)"
    )


STATIONS_NOTE = (
    "Length: the unit's body. On coupling: the static load a towed unit puts on the coupling it hangs on. Stations: "
    "the towing unit's from its front axle, a towed unit's from its front coupling (negative behind it). Loads: the "
    "model's statics on level ground, in tonnes (load / g / 1000)."
)


def specification_lines(spec: VehicleSpecification) -> list[str]:
    """The specification as Markdown lines: a summary line, a table of units and a table of axle groups."""
    lines = [_summary(spec) + ".", ""]
    lines += ["| " + " | ".join(UNIT_HEADERS) + " |", "|---" * len(UNIT_HEADERS) + "|"]
    lines += ["| " + " | ".join(_unit_cells(u)) + " |" for u in spec.units]
    lines += ["", "| " + " | ".join(GROUP_HEADERS) + " |", "|---" * len(GROUP_HEADERS) + "|"]
    lines += ["| " + " | ".join(_group_cells(g)) + " |" for g in spec.groups]
    return [*lines, "", STATIONS_NOTE, ""]


def specification_tables(spec: VehicleSpecification) -> list[Table]:
    """The specification as two rich tables (units, axle groups), the summary the first's title."""

    def table(title: str, headers: tuple[str, ...]) -> Table:
        out = Table(title=title, title_justify="left", box=box.SIMPLE_HEAD, show_edge=False, pad_edge=False)
        for header in headers:
            numeric = header not in ("group", *WRAPPING)
            out.add_column(Text(header), justify="right" if numeric else "left", no_wrap=header not in WRAPPING)
        return out

    units = table(_summary(spec), UNIT_HEADERS)
    for unit in spec.units:
        units.add_row(*(Text(c) for c in _unit_cells(unit)))
    groups = table("Axle groups", GROUP_HEADERS)
    groups.caption = STATIONS_NOTE
    groups.caption_justify = "left"
    for group in spec.groups:
        groups.add_row(*(Text(c) for c in _group_cells(group)))
    return [units, groups]
