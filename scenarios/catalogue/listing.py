"""What ``offtrack list`` shows: the catalogue's scenarios, the vehicle presets and the surface presets as tables.

Each table fits the console's width: names and numbers are never cut; a description is one line, cut with an
ellipsis where the terminal ends (the whole text is in the scenario's YAML file, ``scenarios/catalogue/NAME.yaml``,
or the vehicle's, ``vehicle_model/catalogue/NAME.yaml``).
"""

from __future__ import annotations

from rich import box
from rich.table import Table
from rich.text import Text

from vehicle_model.combination import combination_summary
from vehicle_model.presets import VEHICLE_PRESETS, catalogue_vehicle
from vehicle_model.surface import FRICTION_PRESETS

from ..config import ScenarioConfig, catalogue_names, load_scenario

__all__ = ["preset_tables", "scenario_row", "scenario_table", "surface_table", "vehicle_table"]

NOT_SET = "–"
"""A cell with no value (a straight path has no radius)."""
UNRADIUSED = ("straight", "file", "single_lane_change", "double_lane_change")
"""Path kinds that do not use ``path.radius``."""


def _table(title: str, columns: list[tuple[str, str]]) -> Table:
    """An empty table in the listing's compact style (no outer edge, two spaces between columns).

    ``columns`` are ``(header, justify)`` pairs.

    Headers are plain text (``[m]`` is a unit, not markup); names and numbers never wrap; a ``description``
    column gives way first when the terminal is narrow, each of its cells keeping to one line (:func:`_one_line`).
    """
    table = Table(
        title=title,
        title_justify="left",
        caption_justify="left",
        box=box.SIMPLE_HEAD,
        show_edge=False,
        pad_edge=False,
        collapse_padding=True,
        min_width=len(title),
    )
    for header, justify in columns:
        if header == "description":
            table.add_column(Text(header), min_width=12)  # wraps in the width sums; its cells keep to one line
        elif justify == "right":  # a number: never cut (a name or a list gives way first)
            table.add_column(Text(header), justify=justify, no_wrap=True, min_width=6)  # type: ignore[arg-type]
        else:
            table.add_column(Text(header), justify=justify, no_wrap=True)  # type: ignore[arg-type]
    return table


def _one_line(text: str) -> Text:
    """``text`` with its white space folded, as a cell that keeps to one line (an ellipsis where it is cut)."""
    return Text(" ".join(text.split()), no_wrap=True, overflow="ellipsis")


def scenario_row(config: ScenarioConfig) -> tuple[str, str, str, str, str, str]:
    """The cells of a scenario: name, radius [m], cornering speed [km/h], duration, surface, description.

    Parameters
    ----------
    config
        The resolved scenario.

    Returns
    -------
    tuple of str
        The radius is the control point's path radius (:data:`NOT_SET` for a path without one,
        :data:`UNRADIUSED`); the duration ``full path`` when the run lasts until the driver reaches the path's end;
        the surface a preset name, or ``μ`` and its value, with its low-friction patches counted.
    """
    radius = f"{config.path.radius:g}" if config.path.kind not in UNRADIUSED else NOT_SET
    duration = "full path" if config.duration_s is None else f"{config.duration_s:g} s"
    surface = config.surface.preset if config.surface.mu is None else f"μ {config.surface.mu:g}"
    if config.surface.patches:
        surface += f" +{len(config.surface.patches)} patches"
    description = str(getattr(config, "description", "") or "")
    return config.name, radius, f"{config.speed.cornering_kmh:g}", duration, surface, description


def scenario_table(names: list[str] | None = None) -> Table:
    """The scenarios of the catalogue (or ``names``): a row each (:func:`scenario_row`).

    Parameters
    ----------
    names
        Catalogue names or YAML files (default: the whole catalogue).

    Returns
    -------
    rich.table.Table
        Columns name, R [m], km/h, duration, surface, description.
    """
    columns = [("name", "left"), ("R [m]", "right"), ("km/h", "right"), ("duration", "left"), ("surface", "left")]
    table = _table("Scenarios (offtrack run NAME)", [*columns, ("description", "left")])
    table.caption = "R: the control point's path radius; km/h: the cornering speed"
    for name in catalogue_names() if names is None else names:
        *cells, description = scenario_row(load_scenario(name))
        table.add_row(*(Text(c) for c in cells), _one_line(description))
    return table


def vehicle_table() -> Table:
    """The vehicle presets (``--vehicle NAME``): name, overall length, units, steerable axles and description.

    Returns
    -------
    rich.table.Table
        A row a combination of the catalogue (:func:`vehicle_model.combination.combination_summary`).
    """
    columns = [("name", "left"), ("L [m]", "right"), ("units", "left"), ("steerable axles", "left")]
    table = _table("Vehicle presets (--vehicle NAME or --vehicle FILE.yaml)", [*columns, ("description", "left")])
    table.caption = "L: overall length, straight; semi: semi-trailer; files: vehicle_model/catalogue/NAME.yaml"
    table.columns[0].min_width = max(map(len, VEHICLE_PRESETS))  # a name is what one types: never cut
    for name in VEHICLE_PRESETS:
        spec = catalogue_vehicle(name)
        length, units, steerable = combination_summary(spec)
        table.add_row(Text(name), f"{length:.2f}", Text(units), Text(steerable), _one_line(spec.description))
    return table


def surface_table() -> Table:
    """The surface presets (``--surface NAME``): name and friction coefficient μ."""
    table = _table("Surface presets (--surface NAME)", [("name", "left"), ("μ", "right")])
    for name, mu in FRICTION_PRESETS.items():
        table.add_row(Text(name), f"{mu:.2f}")
    return table


def preset_tables() -> list[Table]:
    """The three tables of ``offtrack list``: scenarios, vehicle presets, surface presets."""
    return [scenario_table(), vehicle_table(), surface_table()]
