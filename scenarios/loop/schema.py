"""Which recorded column is what: a run's columns with their roles, and the selections made from them.

A run's in-memory columns (:meth:`.recording.RowRecorder.arrays`) and a run directory's time series
(:func:`scenarios.run.results.read_timeseries`) are :class:`RecordedColumns`: the values by name and the declared
:class:`~.participant.Column` s (role, vehicle unit, estimator). Metrics, plots and exports find the off-tracking
estimates, their standard deviations and the commands through :func:`estimate_columns`, :func:`std_column` and
:func:`command_columns`, never by taking names apart.

A run written before columns carried roles (its Arrow metadata holds a unit and description, or nothing) is read
through :func:`roles_from_names`, the one place that knows the names' grammar: ``offtracking_<name>`` the estimate
of the first towed unit (unit 2) by estimator ``<name>``, ``offtracking_<name><k>`` that of unit ``k`` where the run
recorded ``offtracking_truth<k>``, ``offtracking_<name>_std`` its standard deviation, ``steer_trailer…`` a steer
command of the first towed unit.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from .participant import Column

__all__ = [
    "FIRST_TOWED_UNIT",
    "RecordedColumns",
    "command_columns",
    "estimate_columns",
    "estimator_names",
    "roles_from_names",
    "schema_of",
    "std_column",
]

FIRST_TOWED_UNIT = 2
"""The vehicle unit of the first towed unit (1 is the tractor or truck)."""


class RecordedColumns(dict[str, np.ndarray]):
    """A run's columns by name, with the declared :class:`~.participant.Column` s they were recorded under.

    Parameters
    ----------
    values
        The columns' values by name, in order.
    schema
        The declared columns (those not among ``values`` are left out of :attr:`schema`).
    """

    def __init__(self, values: Mapping[str, np.ndarray], schema: Iterable[Column]) -> None:
        super().__init__(values)
        self.schema: tuple[Column, ...] = tuple(c for c in schema if c.name in values)


def roles_from_names(columns: Sequence[Column]) -> tuple[Column, ...]:
    """``columns`` with the role, vehicle unit and estimator their names say, where they declare no role.

    The name grammar of runs written before columns carried roles (module notes); a column that declares its role
    is returned as it is.
    """
    truths = (c.name for c in columns if re.fullmatch(r"offtracking_truth[3-9]", c.name))
    further = {name.removeprefix("offtracking_truth") for name in truths}
    out = []
    for column in columns:
        if column.role:
            out.append(column)
            continue
        name = column.name
        role, unit, estimator, physical = "diagnostic", None, None, column.unit
        if name == "time":
            role = "time"
        elif name.startswith("steer_trailer"):
            role, unit, physical = "command", FIRST_TOWED_UNIT, column.unit or "rad"
        elif name == "offtracking_truth":
            role, unit, estimator = "estimate", FIRST_TOWED_UNIT, "truth"
        elif name.startswith("offtracking_truth"):
            suffix = name.removeprefix("offtracking_truth")
            if suffix in further:
                role, unit, estimator = "estimate", int(suffix), "truth"
        elif name.startswith("offtracking_"):
            estimate = name.removeprefix("offtracking_")
            base, digit = estimate[:-1], estimate[-1:]
            if estimate.endswith("_std"):
                role, unit, estimator = "std", FIRST_TOWED_UNIT, estimate.removesuffix("_std")
            elif digit in further and base.isidentifier() and not base[-1:].isdigit():
                role, unit, estimator = "estimate", int(digit), base
            else:
                role, unit, estimator = "estimate", FIRST_TOWED_UNIT, estimate
            if not estimator:
                role, unit, estimator = "diagnostic", None, None
        out.append(dataclasses.replace(column, unit=physical, role=role, vehicle_unit=unit, estimator=estimator))
    return tuple(out)


def schema_of(columns: Mapping[str, np.ndarray] | Sequence[Column]) -> tuple[Column, ...]:
    """The declared columns of a run's columns, in their order, each with its role.

    Parameters
    ----------
    columns
        A run's columns (a :class:`RecordedColumns` carries its declared ones; a plain mapping of names, or a column
        without a role, is read through :func:`roles_from_names`), or the columns themselves.
    """
    if isinstance(columns, Mapping):
        declared = {c.name: c for c in getattr(columns, "schema", ())}
        listed = [declared.get(name, Column(name, "")) for name in columns]
    else:
        listed = list(columns)
    return roles_from_names(listed)


def estimate_columns(columns: Mapping[str, np.ndarray] | Sequence[Column]) -> dict[tuple[str, int], Column]:
    """The off-tracking estimates (the truth's among them) by ``(estimator, vehicle unit)``, in column order."""
    return {
        (str(c.estimator), int(c.vehicle_unit)): c
        for c in schema_of(columns)
        if c.role == "estimate" and c.estimator and c.vehicle_unit is not None
    }


def estimator_names(
    columns: Mapping[str, np.ndarray] | Sequence[Column], vehicle_unit: int = FIRST_TOWED_UNIT
) -> list[str]:
    """The estimators other than the truth that estimate unit ``vehicle_unit``, in column order."""
    return [name for name, unit in estimate_columns(columns) if unit == vehicle_unit and name != "truth"]


def std_column(
    columns: Mapping[str, np.ndarray] | Sequence[Column], estimator: str, vehicle_unit: int = FIRST_TOWED_UNIT
) -> Column | None:
    """The standard deviation of ``estimator``'s estimate of unit ``vehicle_unit`` (``None``: it gives none)."""
    for c in schema_of(columns):
        if c.role == "std" and c.estimator == estimator and c.vehicle_unit == vehicle_unit:
            return c
    return None


def command_columns(
    columns: Mapping[str, np.ndarray] | Sequence[Column], vehicle_unit: int, unit: str | None = None
) -> list[Column]:
    """The commands to unit ``vehicle_unit`` (only those in ``unit``, e.g. ``rad`` for steer angles), in order."""
    return [
        c
        for c in schema_of(columns)
        if c.role == "command" and c.vehicle_unit == vehicle_unit and (unit is None or c.unit == unit)
    ]
