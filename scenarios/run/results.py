"""Run directories: resolved config, a Parquet time series written as the run goes, metrics and plots."""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import yaml

from vehicle_model.errors import InputError

from .files import jsonable, write_atomic

TIMESERIES_FILE = "timeseries.parquet"
METRICS_FILE = "metrics.json"
CONFIG_FILE = "config.yaml"


def new_run_dir(out: Path | None, scenario: str, root: Path = Path("runs"), force: bool = False) -> Path:
    """Create the directory of a run.

    Without ``out`` a fresh ``runs/<scenario>/<timestamp>`` is made. An explicit ``out`` that already
    holds files is refused unless ``force`` (a run never silently overwrites an earlier one).
    """
    if out is None:
        stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        base = root / scenario / stamp
        out, n = base, 1
        while out.exists():
            out = base.with_name(f"{stamp}-{n}")
            n += 1
    elif out.exists() and any(out.iterdir()) and not force:
        raise InputError(f"output directory {out} already holds files; choose another --out or pass --force")
    out.mkdir(parents=True, exist_ok=True)
    return out


def write_config(run_dir: Path, config: Any) -> None:
    """The resolved configuration as YAML."""
    write_atomic(run_dir / CONFIG_FILE, yaml.safe_dump(config.model_dump(mode="json"), sort_keys=False))


def write_metrics(run_dir: Path, metrics: dict[str, Any]) -> None:
    """``metrics.json``, NaN written as null."""
    write_atomic(run_dir / METRICS_FILE, json.dumps(jsonable(metrics), indent=2, allow_nan=False))


class TimeSeriesWriter:
    """Rows of named floats, flushed to Parquet row groups every ``flush_every`` rows.

    The file is valid after every flush, so an interrupted run keeps everything written so far.
    """

    def __init__(self, path: Path, columns: list[str], flush_every: int = 500) -> None:
        self.path = path
        self.columns = list(columns)
        self.flush_every = flush_every
        self._rows: list[list[float]] = []
        self._writer: pq.ParquetWriter | None = None
        self.rows_written = 0

    def append(self, row: dict[str, float]) -> None:
        self._rows.append([float(row.get(c, np.nan)) for c in self.columns])
        if len(self._rows) >= self.flush_every:
            self.flush()

    def flush(self) -> None:
        if not self._rows:
            return
        data = np.array(self._rows, dtype=float)
        table = pa.table({c: data[:, i] for i, c in enumerate(self.columns)}, schema=self._schema())
        if self._writer is None:
            self._writer = pq.ParquetWriter(self.path, self._schema())
        self._writer.write_table(table)
        self.rows_written += len(self._rows)
        self._rows = []

    def close(self) -> None:
        self.flush()
        if self._writer is None:  # no rows at all: still leave a valid, empty file
            self._writer = pq.ParquetWriter(self.path, self._schema())
        self._writer.close()

    def _schema(self) -> pa.Schema:
        return pa.schema([(c, pa.float64()) for c in self.columns])
