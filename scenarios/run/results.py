"""Run directories: where they go, what ``--force`` clears, the config, the metrics and a crash-safe time series.

Output directories
------------------
:func:`check_output_dir` refuses, with one line naming the option, an output path that is a file, lies
under a file or cannot be written, before anything is simulated. :func:`new_run_dir` creates a run
directory; an explicit one that already holds files is refused unless ``force``, which means "this
directory is mine": :func:`clear_run_dir` first removes everything an earlier offtrack run, study,
comparison or KITTI export wrote there (:data:`RUN_FILES`, ``*.png``, ``timeseries.parquet``,
``cases/``, ``image_0/``, ``image_1/``, the run directories of a study's cases, temporary files of
atomic writes). If the directory also holds anything offtrack does not write, nothing is removed and
the run is refused with a message naming it: a user's files are never deleted.

The time series
---------------
``timeseries.parquet`` is a Parquet *dataset directory* of part files ``part-000000.parquet``,
``part-000001.parquet``, … (:class:`TimeSeriesWriter`). A single Parquet file has its footer written only
when it is closed, so a run killed by SIGKILL (the out-of-memory killer, a walltime's second signal, a
node failure) would leave an unreadable file; whole part files, each written under a hidden temporary
name and renamed when complete, leave everything up to the last flush readable at any moment, and
``pandas.read_parquet(run_dir / "timeseries.parquet")`` reads the parts in name order (the zero-padded
numbers keep that the row order) and skips the hidden temporary files.

Each column is float64 and, when the writer is given the columns the loop's participants declare
(:class:`~scenarios.loop.participant.Column`), carries that column's unit, description and role — with the vehicle
unit and the estimator it belongs to, where it has them — as Arrow field metadata (:data:`UNIT_KEY`,
:data:`DESCRIPTION_KEY`, :data:`ROLE_KEY`, :data:`VEHICLE_UNIT_KEY`, :data:`ESTIMATOR_KEY`, UTF-8), so the file
says what its numbers are wherever it goes; :func:`timeseries_columns` reads them back and :func:`read_timeseries`
gives the values with them (:class:`scenarios.loop.schema.RecordedColumns`). The writer refuses a row with a key
it was not given as a column, and :attr:`TimeSeriesWriter.unwritten` names the columns no row has written.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import re
import shutil
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import yaml

from vehicle_model.errors import InputError, OutputError

from ..config import ScenarioConfig, validate_config
from ..loop.participant import Column, SchemaError
from ..loop.schema import RecordedColumns
from ..yaml_input import load_yaml
from .claim import LOCK_FILE, claim_directory
from .files import TEMPORARY_SUFFIX, atomic_path, cannot_write, write_atomic
from .json_output import write_json

TIMESERIES_FILE = "timeseries.parquet"
METRICS_FILE = "metrics.json"
CONFIG_FILE = "config.yaml"
PLOT_FILES = ("plan_view.png", "offtracking.png")
"""The plots of a run (:mod:`scenarios.run.report`), in the default format."""
PLOT_FORMATS = ("png", "svg", "pdf")
"""The image formats a command writes its plots in (``--format``); the first is the default."""

FLUSH_ROWS = 500
"""A :class:`TimeSeriesWriter` writes a part file at least every this many rows …"""
FLUSH_INTERVAL_S = 2.0
"""… and as soon as its oldest unwritten row is this many wall-clock seconds old (rendered runs are slow).

Both are read when a writer is made, so a test (or a user who wants finer crash granularity) can set them
on this module before a run starts."""

UNIT_KEY = b"unit"
"""Arrow field metadata key of a time-series column's unit (SI; ``-`` for a count, flag or code)."""
DESCRIPTION_KEY = b"description"
"""Arrow field metadata key of a time-series column's one-line description."""
ROLE_KEY = b"role"
"""Arrow field metadata key of a time-series column's role (:data:`scenarios.loop.participant.ROLES`)."""
VEHICLE_UNIT_KEY = b"vehicle_unit"
"""Arrow field metadata key of the vehicle unit a time-series column belongs to (decimal; absent: none)."""
ESTIMATOR_KEY = b"estimator"
"""Arrow field metadata key of the estimator a time-series column comes from (absent: none)."""

PART_NAME = "part-{:06d}.parquet"
"""Name of the ``k``-th part file of the time series (six digits: names sort in row order)."""

RUN_FILES = frozenset(
    {
        CONFIG_FILE,
        METRICS_FILE,
        TIMESERIES_FILE,  # a single file, as written before the dataset directory
        "table.parquet",
        "table.csv",
        "table.md",
        "comparison.csv",
        "comparison.md",
        "calib.txt",
        "poses.txt",
        "times.txt",
        "offtrack.json",
        "stereo.mp4",
        "animation.mp4",
        "animation.gif",
        "calibration.yaml",
        "residuals.json",
        "recording.yaml",
        "vo_eval.json",
        "timeseries.csv",
        "timeseries.mat",
    }
)
"""Files offtrack writes into an output directory (besides its plots, ``*.png``/``.svg``/``.pdf``, and the
directories below)."""

_PART = re.compile(r"part-\d+\.parquet")
_CASE_FILE = re.compile(r"[^/]+\.json|\..+\.running")
_FRAME = re.compile(r"\d{6}\.png")
_OWNED_DIRS: dict[str, re.Pattern[str]] = {
    TIMESERIES_FILE: _PART,
    "cases": _CASE_FILE,
    "image_0": _FRAME,
    "image_1": _FRAME,
}
"""Directories offtrack writes, with the names of the files it puts in them."""
_RUN_MARKERS = (CONFIG_FILE, METRICS_FILE, TIMESERIES_FILE)
"""A subdirectory holding one of these is the run directory of a study's case or of a compared feedback."""


def check_plot_format(plot_format: str, option: str = "--format") -> str:
    """The plot format ``plot_format`` (one of :data:`PLOT_FORMATS`, any case), checked before any work.

    Raises
    ------
    InputError
        One line naming ``option`` and the allowed values.
    """
    fmt = str(plot_format).strip().lower().lstrip(".")
    if fmt not in PLOT_FORMATS:
        raise InputError(f"{option} {plot_format!r}: choose {', '.join(PLOT_FORMATS[:-1])} or {PLOT_FORMATS[-1]}")
    return fmt


def plot_files(plot_format: str = PLOT_FORMATS[0]) -> tuple[str, ...]:
    """The names of a run's plots (:data:`PLOT_FILES`) in ``plot_format`` (``png``, ``svg`` or ``pdf``)."""
    fmt = check_plot_format(plot_format)
    return tuple(str(Path(name).with_suffix(f".{fmt}")) for name in PLOT_FILES)


def plot_file(name: str, plot_format: str = PLOT_FORMATS[0]) -> str:
    """``name`` (e.g. ``comparison.png``) with the suffix of ``plot_format``."""
    return str(Path(name).with_suffix(f".{check_plot_format(plot_format)}"))


# --------------------------------------------------------------------------------- output directories


def check_output_dir(path: Path, option: str = "--out") -> None:
    """Refuse an output directory that cannot be one, before any work is done.

    Parameters
    ----------
    path
        The directory (it may not exist yet).
    option
        The command-line option that named it, for the message.

    Raises
    ------
    InputError
        One line naming ``option``: ``path`` is a file, lies under a file, or its nearest existing
        directory is not writable.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"{option} {path} is a file, not a directory")
    existing = path
    while not existing.exists() and existing.parent != existing:
        existing = existing.parent
    if existing.exists() and not existing.is_dir():
        raise InputError(f"{option} {path} lies under {existing}, which is a file, not a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"{option} {path} cannot be written: {existing} is not writable")


def new_run_dir(out: Path | None, scenario: str, root: Path = Path("runs"), force: bool = False) -> Path:
    """Create the directory of a run.

    Without ``out`` a fresh ``runs/<scenario>/<timestamp>`` is made. The directory is claimed for this process
    first (:func:`scenarios.run.claim.claim_directory`): another process writing there is refused. An explicit
    ``out`` that already holds files is refused unless ``force`` (a run never silently overwrites an earlier one); with
    ``force`` the earlier run's files are removed first (:func:`clear_run_dir`).

    Raises
    ------
    InputError
        ``out`` cannot be a directory (:func:`check_output_dir`), another process holds it, it holds files and
        not ``force``, or it holds files offtrack did not write.
    """
    if out is None:
        stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        base = root / scenario / stamp
        out, n = base, 1
        while out.exists() or not _made(out):  # made here, so two runs started in one second get two directories
            out = base.with_name(f"{stamp}-{n}")
            n += 1
    check_output_dir(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {out} cannot be created: {exc.strerror}") from None
    claim_directory(out)  # before anything is read or cleared: a second process into it is refused here
    if any(entry.name != LOCK_FILE for entry in out.iterdir()):
        if not force:
            raise InputError(f"output directory {out} already holds files; choose another --out or pass --force")
        clear_run_dir(out)
    return out


def _made(directory: Path) -> bool:
    """Make ``directory`` (and its parents); False if it exists already. A path that cannot be made is left to
    :func:`check_output_dir` to refuse."""
    try:
        directory.parent.mkdir(parents=True, exist_ok=True)
        directory.mkdir()
    except FileExistsError:
        return False
    except OSError:
        return True
    return True


def _owned(entry: Path, top: bool) -> bool:
    """Whether offtrack writes ``entry`` (a file or directory in an output directory, ``top`` level or a case's)."""
    name = entry.name
    if name.startswith(".") and name.endswith(TEMPORARY_SUFFIX):  # left by an interrupted atomic write
        return not entry.is_symlink() and entry.is_file()
    if entry.is_symlink():
        return False
    if entry.is_file():
        return name in RUN_FILES or name.endswith(tuple(f".{fmt}" for fmt in PLOT_FORMATS))
    if not entry.is_dir():
        return False
    children = list(entry.iterdir())
    if name in _OWNED_DIRS:
        pattern = _OWNED_DIRS[name]
        return all(
            not c.is_symlink() and c.is_file() and (pattern.fullmatch(c.name) or c.name.endswith(TEMPORARY_SUFFIX))
            for c in children
        )
    if not top:
        return False
    # A study case's (or a compared feedback's) run directory; an empty one (a case killed at once) holds nothing.
    names = {c.name for c in children}
    return (not children or any(m in names for m in _RUN_MARKERS)) and all(_owned(c, top=False) for c in children)


def clear_run_dir(directory: Path, option: str = "--out") -> list[Path]:
    """Remove what an earlier offtrack run left in ``directory`` (``--force``); return what was removed.

    Every entry is checked before anything is removed: if one was not written by offtrack (a file of another
    name, a directory of other files, a symbolic link), nothing is removed.

    Raises
    ------
    InputError
        ``directory`` holds something offtrack did not write, or something it cannot remove (a file made immutable,
        a directory not writable): one line naming it. What was removed before it stays removed.
    """
    directory = Path(directory)
    entries = sorted(e for e in directory.iterdir() if e.name != LOCK_FILE)  # the claim stays (scenarios.run.claim)
    foreign = [e for e in entries if not _owned(e, top=True)]
    if foreign:
        more = f" (and {len(foreign) - 1} more)" if len(foreign) > 1 else ""
        raise InputError(
            f"{option} {directory} holds {foreign[0].name}{more}, which offtrack did not write; --force only "
            "replaces an earlier offtrack run: move it away or choose another " + option
        )
    for entry in entries:
        try:
            _remove(entry)
        except OSError as exc:
            raise InputError(
                f"{option} {directory}: --force cannot remove {exc.filename or entry} ({exc.strerror or exc}); "
                f"remove it yourself or choose another {option}"
            ) from None
    return entries


def _remove(entry: Path) -> None:
    """Remove a file, or a directory with everything in it; an :class:`OSError` names the whole path that failed."""
    if not entry.is_dir() or entry.is_symlink():
        entry.unlink()
        return

    def failed(function: Any, path: str, info: Any) -> None:  # rmtree's own error names only the base name
        exc = info[1] if isinstance(info, tuple) else info
        raise OSError(getattr(exc, "errno", None), getattr(exc, "strerror", None) or str(exc), path) from exc

    shutil.rmtree(entry, **({"onexc": failed} if sys.version_info >= (3, 12) else {"onerror": failed}))


# ------------------------------------------------------------------------------------- config, metrics


def config_yaml(config: Any, road_columns: dict[str, tuple[float, float]] | None = None) -> str:
    """The resolved configuration as the YAML a run writes (every field, in the schema's order).

    Parameters
    ----------
    config : ScenarioConfig
        The validated configuration.
    road_columns
        The road file's columns that ran instead of the scenario's speed and surface
        (:attr:`scenarios.setup.build.ScenarioSetup.road_columns`): a comment above the fields says so.

    Returns
    -------
    str
        The YAML text; :func:`scenarios.config.validate_config` of its loaded form gives ``config`` back.
    """
    text = yaml.safe_dump(config.model_dump(mode="json"), sort_keys=False, allow_unicode=True)
    return road_note(road_columns) + text


def road_note(road_columns: dict[str, tuple[float, float]] | None) -> str:
    """YAML comment lines saying which of the scenario's fields a road file's columns replaced, and with what."""
    spans = {"speed_kmh": ("speed", "km/h", "speed"), "mu": ("mu", "", "surface")}
    lines = [
        f"# the road file's {column} column ran ({low:.3g}–{high:.3g}{' ' + unit if unit else ''}), "
        f"not the {section} below: a road file's columns win\n"
        for name, (column, unit, section) in spans.items()
        if name in (road_columns or {})
        for low, high in [road_columns[name]]  # type: ignore[index]
    ]
    return "".join(lines)


def write_config(run_dir: Path, config: Any, road_columns: dict[str, tuple[float, float]] | None = None) -> None:
    """The resolved configuration as YAML (:func:`config_yaml`)."""
    write_atomic(run_dir / CONFIG_FILE, config_yaml(config, road_columns))


def read_config(run_dir: Path) -> ScenarioConfig:
    """The resolved configuration a run wrote (validated again).

    Raises
    ------
    InputError
        ``run_dir`` has no ``config.yaml`` (it is not a run directory), or it is not a valid configuration (nor
        UTF-8 YAML within :mod:`scenarios.yaml_input`'s bounds).
    """
    path = Path(run_dir) / CONFIG_FILE
    if not path.is_file():
        raise InputError(f"{run_dir} is not a run directory: it has no {CONFIG_FILE}")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path} cannot be read: {exc.strerror or exc}") from None
    data = load_yaml(raw, str(path))  # within bounds, like any configuration a user gives
    if not isinstance(data, dict):
        raise InputError(f"{path} does not hold a configuration")
    return validate_config(data)


def write_metrics(run_dir: Path, metrics: dict[str, Any]) -> None:
    """``metrics.json``, strict JSON: NaN written as null, with its reason (:mod:`.json_output`)."""
    write_json(run_dir / METRICS_FILE, metrics)


def read_metrics(run_dir: Path) -> dict[str, Any] | None:
    """The ``metrics.json`` of a run, or None if it has none (or an unreadable one)."""
    try:
        data = json.loads((Path(run_dir) / METRICS_FILE).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


# ----------------------------------------------------------------------------------------- time series


class TimeSeriesWriter:
    """Rows of named floats, written as whole Parquet part files into the dataset directory ``path``.

    Why part files (module docstring): a Parquet file is readable only once its footer is written at
    close, so a run killed with SIGKILL would lose its whole series. Each flush here writes one complete
    part file under a hidden temporary name, syncs it and renames it to ``part-NNNNNN.parquet``; a reader
    (``pandas.read_parquet(path)``) sees only whole parts, in row order, at any moment. A flush happens
    every ``flush_every`` rows, and at the first row that arrives ``flush_interval_s`` seconds of wall time
    or more after the oldest unflushed one (a rendered run makes a few rows a second), so a killed run
    loses at most about that much of its work.
    :meth:`close` writes an empty part with the columns if no row was written, so an empty run still
    leaves a readable, empty series with its columns. A row with a key that is not a column is refused
    (:class:`~scenarios.loop.participant.SchemaError`); :attr:`unwritten` names the columns no row has held.

    Parameters
    ----------
    path
        The dataset directory (an earlier series there, file or directory, is replaced).
    columns
        The columns (every one float64): declared ones (:class:`~scenarios.loop.participant.Column`), whose
        unit and description go into the file as field metadata, or bare names; may be set later through
        :attr:`columns`, before the first row.
    flush_every
        Rows per part (default :data:`FLUSH_ROWS`).
    flush_interval_s
        Longest wall time between flushes while rows arrive [s] (default :data:`FLUSH_INTERVAL_S`).
    """

    def __init__(
        self,
        path: Path,
        columns: Sequence[str | Column],
        flush_every: int | None = None,
        flush_interval_s: float | None = None,
    ) -> None:
        self.path = Path(path)
        self.columns = columns  # names, or declared columns with their units
        self.flush_every = FLUSH_ROWS if flush_every is None else int(flush_every)
        self.flush_interval_s = FLUSH_INTERVAL_S if flush_interval_s is None else float(flush_interval_s)
        self._rows: list[list[float]] = []
        self.rows_written = 0
        self.parts = 0
        self._oldest = 0.0  # wall time at which the oldest buffered row arrived
        self.failure: str | None = None  # why writing the series failed (a full disk, …)
        try:
            if self.path.is_symlink() or self.path.is_file():
                self.path.unlink()
            elif self.path.is_dir():
                shutil.rmtree(self.path)
            self.path.mkdir(parents=True)
        except OSError as exc:
            raise cannot_write(self.path, exc) from exc

    @property
    def columns(self) -> list[str]:
        """The column names, in order; set it to names or to declared columns (with their units)."""
        return self._names

    @columns.setter
    def columns(self, columns: Sequence[str | Column]) -> None:
        self._fields = [_field(c) for c in columns]
        self._names = [f.name for f in self._fields]
        self._known = frozenset(self._names)
        self._unwritten = set(self._names)

    @property
    def unwritten(self) -> list[str]:
        """The columns no row appended so far has held, in order."""
        return [c for c in self._names if c in self._unwritten]

    def append(self, row: dict[str, float]) -> None:
        """Add one row (missing columns are NaN); flush if enough rows or time have gone by since the oldest.

        Raises
        ------
        SchemaError
            The row has a key that is not one of :attr:`columns`.
        """
        if not self._known.issuperset(row):
            key = next(k for k in row if k not in self._known)
            raise SchemaError(f"the time series {self.path} has no column {key!r}: a row holds only its columns")
        if self._unwritten:
            self._unwritten.difference_update(row)
        if self.failure is not None:
            return  # the series ends where the first write failed
        now = time.monotonic()
        if not self._rows:
            self._oldest = now
        self._rows.append([float(row.get(c, np.nan)) for c in self.columns])
        if len(self._rows) >= self.flush_every or now - self._oldest >= self.flush_interval_s:
            self.flush()

    def flush(self) -> None:
        """Write the buffered rows as the next part file (nothing if there are none).

        Raises
        ------
        OutputError
            The part could not be written (:attr:`failure` says why). The series keeps the parts written
            before; every later row is dropped and every later flush and :meth:`close` does nothing.
        """
        if self._rows and self.failure is None:
            data = np.array(self._rows, dtype=float).reshape(len(self._rows), len(self.columns))
            self._write_part({c: data[:, i] for i, c in enumerate(self.columns)})
            self.rows_written += len(self._rows)
            self._rows = []

    def close(self) -> None:
        """Flush the last rows; leave an empty part with the columns if there were no rows at all."""
        self.flush()
        if self.parts == 0 and self.failure is None:
            self._write_part({c: np.zeros(0) for c in self.columns})

    def _write_part(self, data: dict[str, np.ndarray]) -> None:
        table = pa.table(data, schema=pa.schema(self._fields))
        try:
            with atomic_path(self.path / PART_NAME.format(self.parts)) as tmp, open(tmp, "wb") as fh:
                pq.write_table(table, fh)
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:
            self._rows = []
            self.failure = f"{exc}; the series holds the first {self.rows_written} rows"
            raise OutputError(f"the time series could not be written: {self.failure}") from exc
        self.parts += 1


def _field(column: str | Column) -> pa.Field:
    """The float64 Arrow field of a column: a declared one with its unit, description and role as metadata."""
    if isinstance(column, str):
        return pa.field(column, pa.float64())
    metadata = {UNIT_KEY: column.unit.encode(), DESCRIPTION_KEY: column.description.encode()}
    if column.role:
        metadata[ROLE_KEY] = column.role.encode()
    if column.vehicle_unit is not None:
        metadata[VEHICLE_UNIT_KEY] = str(column.vehicle_unit).encode()
    if column.estimator:
        metadata[ESTIMATOR_KEY] = column.estimator.encode()
    return pa.field(column.name, pa.float64(), metadata=metadata)


def timeseries_columns(schema: pa.Schema) -> list[Column]:
    """The columns of a time series' schema with the unit, description and role it carries (``""`` where it has
    none).

    Parameters
    ----------
    schema
        The schema of ``timeseries.parquet`` (``pyarrow.parquet.read_table(path).schema``).

    Returns
    -------
    list of Column
        One per field, in order; a series written without declared columns (bare names) gives empty units, one
        written before columns had roles empty roles (:func:`scenarios.loop.schema.roles_from_names` reads those).
    """
    columns = []
    for field in schema:
        metadata = field.metadata or {}

        def text(key: bytes, metadata: dict[bytes, bytes] = metadata) -> str:
            return metadata.get(key, b"").decode(errors="replace")

        role, unit, estimator = text(ROLE_KEY), text(VEHICLE_UNIT_KEY), text(ESTIMATOR_KEY)
        try:
            column = Column(
                field.name,
                text(UNIT_KEY),
                text(DESCRIPTION_KEY),
                role=role,
                vehicle_unit=int(unit) if unit else None,
                estimator=estimator or None,
            )
        except ValueError:  # metadata this version does not know: the column as named
            column = Column(field.name, text(UNIT_KEY), text(DESCRIPTION_KEY))
        columns.append(column)
    return columns


def read_timeseries(run_dir: Path) -> RecordedColumns:
    """The time series a run wrote, as float64 columns with their declarations (empty if it has none or no row
    yet)."""
    path = Path(run_dir) / TIMESERIES_FILE
    if not path.exists():
        return RecordedColumns({}, ())
    table = pq.read_table(path)
    values = {name: np.array(table.column(name).to_numpy(), dtype=float) for name in table.column_names}
    return RecordedColumns(values, timeseries_columns(table.schema))
