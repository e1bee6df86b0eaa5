"""A run's time series for other tools: CSV or a MATLAB ``.mat`` file, with units (``offtrack export``).

The numbers come from the run directory's ``timeseries.parquet``, their units and descriptions from the Arrow
field metadata the run wrote there (:func:`scenarios.run.results.timeseries_columns`, declared once by the loop's
participants), the run's description from ``config.yaml`` and ``metrics.json``:

* **CSV** (:func:`write_csv`, UTF-8): one header row, each column ``name [unit]`` (bare ``name`` for a column
  written without a unit, e.g. by ``offtrack estimate`` or an older run), then one row per control tick; every
  number in Python's shortest round-trip form (``repr``), so it reads back bit for bit; ``NaN`` where a value is
  missing, ``Inf``/``-Inf``.
* **MATLAB** (:func:`write_mat`, :func:`scipy.io.savemat`, format 5): one column vector per column under a valid
  MATLAB name (:func:`matlab_names`), and the structs ``units`` and ``descriptions`` (a field per variable), the
  cell array ``column_names`` (the original names, in order, beside ``variable_names``) and the struct
  ``metadata`` (scenario, seed, vehicle, …, status, and the whole ``config.yaml`` as text).

:func:`export_target` checks everything a user gives — a run directory with a time series, a known format, an
output that can be written and is not a file already there (unless ``force``) — before anything is read, each
refusal one line (:class:`~vehicle_model.errors.InputError`). The file is written whole (temporary name, then
rename); the temporary a killed export left beside the file is removed by the next export of it
(:func:`remove_stale_temporaries`).
"""

from __future__ import annotations

import contextlib
import csv
import fcntl
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from vehicle_model.errors import InputError

from ..loop.participant import Column
from ..loop.schema import schema_of
from ..run.files import TEMPORARY_SUFFIX, atomic_path
from ..run.results import CONFIG_FILE, RUN_FILES, TIMESERIES_FILE, read_metrics, timeseries_columns
from ..yaml_input import load_yaml

__all__ = [
    "FORMATS",
    "RunTable",
    "csv_header",
    "export_run",
    "export_target",
    "matlab_names",
    "read_run_table",
    "remove_stale_temporaries",
    "write_csv",
    "write_mat",
]

FORMATS: dict[str, str] = {"csv": ".csv", "mat": ".mat"}
"""The formats of ``--to``, with the suffix of the default file name (``RUN_DIR/timeseries.<suffix>``)."""
DEFAULT_STEM = "timeseries"
"""The default file's name without its suffix."""

MATLAB_NAME_LENGTH = 63
"""MATLAB's ``namelengthmax``: the longest variable or struct field name."""
MATLAB_RESERVED = ("units", "descriptions", "column_names", "variable_names", "metadata")
"""The ``.mat`` file's own variables, which no column's variable may take."""
MATLAB_KEYWORDS = frozenset(
    "break case catch classdef continue else elseif end for function global if otherwise parfor persistent return "
    "spmd switch try while".split()
)
"""MATLAB's keywords (``iskeyword``): not valid variable names."""

CONFIG_METADATA = ("name", "seed", "vehicle", "direction", "feedback", "duration_s")
"""Top-level fields of ``config.yaml`` carried into the ``.mat`` file's ``metadata`` (``name`` as ``scenario``)."""
METRICS_METADATA = ("scenario", "status", "message", "rows")
"""Fields of ``metrics.json`` carried into ``metadata`` (for a run without ``config.yaml``: a recorded one)."""


@dataclass
class RunTable:
    """A run's time series with what each column is and what run it came from.

    Attributes
    ----------
    columns : list of Column
        The columns in order, each with its unit and description (``""`` where the file has none) and its role.
    data : dict
        Each column's values by name (float64 arrays of one length).
    metadata : dict
        Scalars describing the run (scenario, seed, …, status) and ``config_yaml``, the text of its configuration.
    """

    columns: list[Column]
    data: dict[str, np.ndarray]
    metadata: dict[str, str | float | int] = field(default_factory=dict)

    @property
    def rows(self) -> int:
        """The number of rows (control ticks)."""
        return len(next(iter(self.data.values()))) if self.data else 0


def export_target(run_dir: Path, to: str, out: Path | None = None, force: bool = False) -> Path:
    """The file an export of ``run_dir`` to ``to`` writes, once every input is known to be usable.

    Parameters
    ----------
    run_dir
        The run directory (it must hold ``timeseries.parquet``).
    to
        The format, a key of :data:`FORMATS`.
    out
        The file to write, or a directory to write ``timeseries.<suffix>`` into; default: into ``run_dir``.
    force
        Replace a file already at the target.

    Returns
    -------
    Path
        The file to write.

    Raises
    ------
    InputError
        One line naming the problem: an unknown format; ``run_dir`` missing or holding no time series; the target
        inside the time series' own directory, a directory, another of the run's own files (``config.yaml``, …),
        a file already there (without ``force``), under a file, or in a directory that cannot be written.
    """
    if to not in FORMATS:
        raise InputError(f"--to {to!r} is not a format offtrack exports; choose one of {', '.join(FORMATS)}")
    run_dir = Path(run_dir)
    if not run_dir.exists():
        raise InputError(f"RUN_DIR {run_dir} does not exist: give the directory of an offtrack run")
    if not run_dir.is_dir():
        raise InputError(f"RUN_DIR {run_dir} is a file, not a run directory: give the directory of an offtrack run")
    series = run_dir / TIMESERIES_FILE
    if not series.exists():
        raise InputError(f"RUN_DIR {run_dir} is not a run directory: it has no {TIMESERIES_FILE}")
    name = DEFAULT_STEM + FORMATS[to]
    target = run_dir / name if out is None else Path(out)
    if target.is_dir() and not target.is_symlink():
        target = target / name
    if series.resolve() in (target.resolve(), *target.resolve().parents):
        raise InputError(f"--out {target} lies inside the run's time series {series}; choose another --out")
    if target.is_dir():
        raise InputError(f"--out {target} is a directory; give a file name or another --out")
    own = RUN_FILES - {DEFAULT_STEM + suffix for suffix in FORMATS.values()}
    if target.name in own and target.parent.resolve() == run_dir.resolve():
        raise InputError(f"--out {target} is one of the run's own files; choose another --out")
    if target.exists() and not force:
        raise InputError(f"--out {target} already exists; pass --force to replace it or choose another --out")
    existing = target.parent
    while not existing.exists() and existing.parent != existing:
        existing = existing.parent
    if not existing.is_dir():
        raise InputError(f"--out {target} lies under {existing}, which is a file, not a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"--out {target} cannot be written: {existing} is not writable")
    return target


def read_run_table(run_dir: Path) -> RunTable:
    """Read a run's time series with its columns' units and descriptions and the run's metadata.

    Parameters
    ----------
    run_dir
        The run directory.

    Returns
    -------
    RunTable
        The columns, their values and the metadata.

    Raises
    ------
    InputError
        The time series cannot be read (no part written yet, a damaged file), or ``config.yaml`` is not a valid
        YAML mapping within the input bounds.
    """
    run_dir = Path(run_dir)
    series = run_dir / TIMESERIES_FILE
    try:
        table = pq.read_table(series)
    except (OSError, pa.ArrowException) as exc:
        raise InputError(f"{series} cannot be read: {exc}") from None
    columns = list(schema_of(timeseries_columns(table.schema)))  # each with its role, an older run's by its name
    data = {c.name: np.array(table.column(c.name).to_numpy(), dtype=float) for c in columns}
    return RunTable(columns, data, _metadata(run_dir))


def _metadata(run_dir: Path) -> dict[str, str | float | int]:
    """The run's scalars from ``config.yaml`` (as written) and ``metrics.json``, and the configuration's text."""
    metadata: dict[str, str | float | int] = {}
    config_path = run_dir / CONFIG_FILE
    if config_path.is_file():
        try:
            raw = config_path.read_bytes()
        except OSError as exc:
            raise InputError(f"{config_path} cannot be read: {exc.strerror or exc}") from None
        config = load_yaml(raw, str(config_path))
        if not isinstance(config, dict):
            raise InputError(f"{config_path} does not hold a configuration")
        for key in CONFIG_METADATA:
            value = config.get(key)
            if key == "vehicle" and isinstance(value, dict):  # a combination held inline: its name
                value = value.get("name")
            if isinstance(value, str | int | float) and not isinstance(value, bool):
                metadata["scenario" if key == "name" else key] = value
        surface = config.get("surface")
        if isinstance(surface, dict):
            for key in ("preset", "mu"):
                if isinstance(surface.get(key), str | int | float):
                    metadata[f"surface_{key}"] = surface[key]
        metadata["config_yaml"] = raw.decode()
    for key, value in (read_metrics(run_dir) or {}).items():
        if key in METRICS_METADATA and isinstance(value, str | int | float) and not isinstance(value, bool):
            metadata.setdefault(key, value)
    return metadata


def csv_header(column: Column) -> str:
    """The CSV header of ``column``: ``name [unit]``, or ``name`` alone when its unit is not known."""
    return f"{column.name} [{column.unit}]" if column.unit else column.name


def _csv_number(value: float) -> str:
    """``repr`` (shortest round trip), ``NaN``, ``Inf`` or ``-Inf``: read back exactly by pandas and MATLAB."""
    if math.isnan(value):
        return "NaN"
    if math.isinf(value):
        return "Inf" if value > 0 else "-Inf"
    return repr(value)


def write_csv(table: RunTable, path: Path) -> None:
    """Write ``table`` as CSV: a header row of :func:`csv_header`, then one row per tick (module docstring).

    Parameters
    ----------
    table
        What to write.
    path
        The file (replaced whole, through a temporary file).
    """
    values = [table.data[c.name].tolist() for c in table.columns]
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)  # held while written: a temporary no one holds is a killed export's
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow([csv_header(c) for c in table.columns])
        writer.writerows([_csv_number(v) for v in row] for row in zip(*values, strict=True))


def matlab_names(names: list[str]) -> dict[str, str]:
    """A valid, distinct MATLAB variable name for each name, by name.

    A valid name starts with a letter, holds only letters, digits and underscores, is at most
    :data:`MATLAB_NAME_LENGTH` characters long and is not a keyword; it is also none of the file's own variables
    (:data:`MATLAB_RESERVED`). A valid name is kept; another has its other characters replaced by ``_``, ``x``
    put before a first character that is not a letter or a name that is taken, and a number appended while it
    clashes.

    Parameters
    ----------
    names
        The column names.

    Returns
    -------
    dict
        The MATLAB name of each column name.
    """
    taken: set[str] = set(MATLAB_RESERVED)
    chosen: dict[str, str] = {}
    for name in names:
        base = re.sub(r"[^A-Za-z0-9_]", "_", name)
        if not re.match(r"[A-Za-z]", base) or base in MATLAB_KEYWORDS or base in MATLAB_RESERVED:
            base = "x" + base
        base = base[:MATLAB_NAME_LENGTH]
        candidate, k = base, 1
        while candidate in taken:
            suffix = f"_{k}"
            candidate, k = base[: MATLAB_NAME_LENGTH - len(suffix)] + suffix, k + 1
        taken.add(candidate)
        chosen[name] = candidate
    return chosen


def write_mat(table: RunTable, path: Path) -> None:
    """Write ``table`` as a MATLAB ``.mat`` file (format 5): a column vector per column, units, metadata.

    Parameters
    ----------
    table
        What to write.
    path
        The file (replaced whole, through a temporary file).
    """
    from scipy.io import savemat

    names = matlab_names([c.name for c in table.columns])
    variables: dict[str, Any] = {names[c.name]: table.data[c.name] for c in table.columns}
    variables["units"] = {names[c.name]: c.unit for c in table.columns}
    variables["descriptions"] = {names[c.name]: c.description for c in table.columns}
    variables["column_names"] = np.array([c.name for c in table.columns], dtype=object)
    variables["variable_names"] = np.array([names[c.name] for c in table.columns], dtype=object)
    variables["metadata"] = dict(table.metadata)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)  # held while written (:func:`remove_stale_temporaries`)
        savemat(fh, variables, oned_as="column", long_field_names=True)


def remove_stale_temporaries(target: Path) -> list[Path]:
    """Remove the temporary files an earlier export of ``target`` left when it was killed; return them.

    An export writes ``.<name>.<random>.tmp`` beside ``target`` (:func:`~scenarios.run.files.atomic_path`) and holds
    an exclusive lock (``flock``) on it while it writes; the kernel drops the lock when its process ends, however it
    ends (SIGKILL included). A temporary of ``target`` whose lock can be taken is no one's: it is removed. One
    still locked belongs to an export under way and is left.
    """
    target = Path(target)
    removed = []
    if not target.parent.is_dir():
        return removed
    for path in target.parent.glob(f".{target.name}.*{TEMPORARY_SUFFIX}"):
        if path.is_symlink() or not path.is_file():
            continue
        try:
            with open(path, "rb") as fh:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
                with contextlib.suppress(FileNotFoundError):
                    path.unlink()
                removed.append(path)
        except (BlockingIOError, FileNotFoundError, PermissionError):
            continue
    return removed


def export_run(run_dir: Path, to: str, out: Path | None = None, force: bool = False) -> Path:
    """Export a run's time series to ``to`` (:data:`FORMATS`): check the inputs, read, write; return the file.

    Parameters
    ----------
    run_dir
        The run directory.
    to
        ``csv`` or ``mat``.
    out
        The file or directory to write to (default: ``run_dir/timeseries.<suffix>``).
    force
        Replace a file already there.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    InputError
        A bad input (:func:`export_target`, :func:`read_run_table`), before anything is written.
    OutputError
        The file could not be written (a full disk): nothing of it is left.
    """
    target = export_target(run_dir, to, out, force)
    table = read_run_table(run_dir)
    remove_stale_temporaries(target)
    (write_csv if to == "csv" else write_mat)(table, target)
    return target
