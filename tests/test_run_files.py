"""Files that are never half-written (atomic writes through a temporary file and a rename), JSON-native values."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from scenarios.run.files import atomic_path, jsonable, write_atomic


def test_a_write_replaces_the_file_whole_and_leaves_no_temporary_file(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "metrics.json"
    write_atomic(path, "old")
    write_atomic(path, "new")
    assert path.read_text() == "new"
    assert sorted(p.name for p in path.parent.iterdir()) == ["metrics.json"]


def test_a_failed_write_keeps_the_old_file_and_removes_the_temporary_one(tmp_path: Path) -> None:
    path = tmp_path / "table.parquet"
    path.write_text("old")
    with pytest.raises(RuntimeError, match="disk full"), atomic_path(path) as tmp:
        tmp.write_text("half")
        raise RuntimeError("disk full")  # the fault: the writer fails midway
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.parquet"]


def test_json_native_values_with_non_finite_numbers_as_null() -> None:
    value = {"a": np.float64(1.5), "b": np.arange(3), 4: [math.nan, np.inf, True, None], "p": Path("x/y")}
    text = json.dumps(jsonable(value), allow_nan=False)  # strict JSON: would raise on a NaN left in
    assert json.loads(text) == {"a": 1.5, "b": [0, 1, 2], "4": [None, None, True, None], "p": "x/y"}
