"""Loading a scenario: the catalogue or a YAML file, dotted overrides (``--set``), validation."""

from __future__ import annotations

import copy
import itertools
import re
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from vehicle_model.errors import InputError

from ..camera_checks import check_camera
from ..roads.smoothing import checked_road
from ..roads.terrain_files import checked_terrain
from ..yaml_input import RefusedDocument, load_yaml
from .errors import ConfigError, did_you_mean
from .field_errors import dotted_name, format_errors
from .scenario_config import ScenarioConfig
from .vehicle_field import VEHICLE_SUFFIXES, vehicle_data

CATALOGUE_PACKAGE = "scenarios.catalogue"


def validate_config(data: dict[str, Any]) -> ScenarioConfig:
    """Validate a configuration mapping; :class:`ConfigError` lists every bad field.

    A configuration that runs a camera must have one that can work (:func:`scenarios.camera_checks.check_camera`:
    disparity on the road, room for the matches, a lens that does not fold over); otherwise
    :class:`~vehicle_model.errors.InputError` names the field in one line.
    """
    try:
        config = ScenarioConfig.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(format_errors(exc)) from None
    if config.uses_camera:
        check_camera(config.camera, config.vehicle_params())
    return config


def catalogue_names() -> list[str]:
    """Names of the scenarios in the catalogue."""
    files = resources.files(CATALOGUE_PACKAGE).iterdir()
    return sorted(f.name.removesuffix(".yaml") for f in files if f.name.endswith(".yaml"))


def load_scenario_data(name_or_path: str) -> dict[str, Any]:
    """Raw configuration of a catalogue scenario or a YAML file.

    The text is read within the bounds of :func:`scenarios.yaml_input.load_yaml` (UTF-8, size, nesting, aliases).

    Raises
    ------
    ConfigError
        One line naming the scenario or file: unknown, missing, not UTF-8, out of bounds, not valid YAML, empty, or
        not a mapping of fields.
    """
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml"):
        if not path.is_file():
            raise ConfigError(f"scenario file {name_or_path} does not exist")
        source = f"scenario file {name_or_path}"
        try:
            raw = path.read_bytes()
        except OSError as exc:
            raise ConfigError(f"{source} cannot be read: {exc.strerror or exc}") from None
    else:
        entry = resources.files(CATALOGUE_PACKAGE) / f"{name_or_path}.yaml"
        if not entry.is_file():
            near = did_you_mean(name_or_path, catalogue_names())
            choices = near or f"; choose one of {catalogue_names()} or give a YAML file"
            raise ConfigError(f"unknown scenario {name_or_path!r}{choices}")
        source, raw = f"catalogue scenario {name_or_path}", entry.read_bytes()
    try:
        data = load_yaml(raw, source)
    except InputError as exc:
        raise ConfigError(str(exc)) from None
    if data is None:
        raise ConfigError(f"{source} is empty: it must hold a mapping of fields (name, vehicle, path, …)")
    if not isinstance(data, dict):
        raise ConfigError(f"{source} must hold a mapping of fields, not a {type(data).__name__}")
    if path.suffix in (".yaml", ".yml"):
        _files_beside(data, path.parent)
    else:  # a catalogue scenario's road or terrain file ships beside it in the package
        _files_beside(data, Path(str(resources.files(CATALOGUE_PACKAGE))))
    return data


def _files_beside(data: dict[str, Any], folder: Path) -> None:
    """Make a scenario file's relative ``vehicle`` file, ``path.file`` road and ``terrain.file`` grid the ones beside
    it, where they exist there (a scenario, its vehicle and its road kept in one folder run from anywhere); others
    stay as written, relative to the working directory."""

    def beside(value: Any) -> Any:
        if isinstance(value, str) and value and not Path(value).is_absolute() and (folder / value).is_file():
            return str((folder / value).resolve())
        return value

    if isinstance(data.get("vehicle"), str) and data["vehicle"].endswith(VEHICLE_SUFFIXES):
        data["vehicle"] = beside(data["vehicle"])
    for section in ("path", "terrain"):
        if isinstance(data.get(section), dict) and "file" in data[section]:
            data[section]["file"] = beside(data[section]["file"])


_KEY = re.compile(r"^([^.\[\]]+)((?:\[\d+\])*)$")
"""One dotted part of a ``--set`` name: a field, then the indices of its items (``axles[1]``)."""


def _parts(dotted: str) -> list[str | int]:
    """``'vehicle.units[1].steerable'`` → ``['vehicle', 'units', 1, 'steerable']``."""
    parts: list[str | int] = []
    for piece in dotted.split("."):
        match = _KEY.match(piece.strip())
        if match is None:
            raise ConfigError(f"--set {dotted}: {piece!r} is not a field name (field or field[index], e.g. units[1])")
        parts.append(match.group(1))
        parts += [int(i) for i in re.findall(r"\d+", match.group(2))]
    return parts


def set_dotted(data: dict[str, Any], dotted: str, value: Any) -> None:
    """Set ``data['a']['b'] = value`` for ``dotted = 'a.b'`` (``a.b[1].c`` an item of a list), creating levels.

    Raises
    ------
    ConfigError
        An index where there is no list, or beyond its items.
    """
    parts = _parts(dotted)
    node: Any = data
    for i, (key, nxt) in enumerate(itertools.pairwise(parts)):
        here = dotted_name(tuple(parts[: i + 1]))
        if isinstance(key, int):
            if not isinstance(node, list) or not -len(node) <= key < len(node):
                count = f"{parts[i - 1]} has {len(node)}" if isinstance(node, list) else "it is not a list"
                raise ConfigError(f"--set {dotted}: {here}: no item {key}; {count}")
            child = node[key]
        else:
            child = node.get(key) if isinstance(node, dict) else None
        if isinstance(nxt, int) and not isinstance(child, list):
            raise ConfigError(f"--set {dotted}: {here} is not a list of items")
        if not isinstance(nxt, int) and not isinstance(child, dict):
            child = {}
            node[key] = child
        node = child
    last = parts[-1]
    if isinstance(last, int):
        if not -len(node) <= last < len(node):
            here = dotted_name(tuple(parts))
            raise ConfigError(f"--set {dotted}: {here}: no item {last}; {parts[-2]} has {len(node)}")
    node[last] = value


def parse_assignment(text: str) -> tuple[str, Any]:
    """``key.sub=value`` → (``key.sub``, YAML-parsed value)."""
    if "=" not in text:
        raise ConfigError(f"--set {text!r} must look like field.sub=value")
    key, raw = text.split("=", 1)
    try:
        value = load_yaml(raw, f"--set {key.strip()}")
    except RefusedDocument as exc:
        raise ConfigError(str(exc)) from None
    except InputError:
        value = raw  # not YAML: the text itself
    return key.strip(), value


def load_scenario(name_or_path: str, overrides: dict[str, Any] | None = None) -> ScenarioConfig:
    """Load a scenario from the catalogue (or a YAML file), apply dotted overrides, validate it and check its road file.

    A road file is read and checked here (:func:`check_road_file`), with the configuration, so a bad road is refused
    before any command writes anything; :func:`validate_config` alone does not open it (a finished run's
    ``config.yaml`` is read back without its road). Each override's value is copied in, so a later override of a
    field inside it (``camera.calibration`` then ``camera.calibration.mode``) leaves the caller's mapping as it was.
    """
    data = load_scenario_data(name_or_path)
    data.setdefault("name", Path(name_or_path).stem)
    default_vehicle = ScenarioConfig.model_fields["vehicle"].default
    for key, value in (overrides or {}).items():
        if key.startswith(("vehicle.", "vehicle[")):  # a field of the vehicle: its preset or file as a mapping
            data["vehicle"] = vehicle_data(data.get("vehicle", default_vehicle))
        set_dotted(data, key, copy.deepcopy(value))  # a later dotted override must not edit the caller's mapping
    config = validate_config(data)
    check_road_file(config)
    check_terrain_file(config)
    return config


def check_terrain_file(config: ScenarioConfig) -> None:
    """Read and check the height grid a configuration names, if it names one (:mod:`scenarios.roads.terrain_files`).

    Raises
    ------
    scenarios.roads.terrain_files.TerrainFileError
        One line naming the file and the header field, line or row; the grid is read once for the check and the
        run's build (:func:`scenarios.roads.terrain_files.checked_terrain`).
    """
    if config.terrain.file is not None:
        checked_terrain(config.terrain.file)


def check_road_file(config: ScenarioConfig) -> None:
    """Read, smooth and check the road file a configuration names, if it names one (:mod:`scenarios.roads`).

    Raises
    ------
    scenarios.roads.points.RoadFileError
        One line naming the file and the row, field or station; the road is read once for the check and the run's
        build (:func:`scenarios.roads.smoothing.checked_road`).
    """
    spec = config.path
    if spec.file is not None:
        checked_road(spec.file, spec.smoothing, spec.road, spec.lane)
