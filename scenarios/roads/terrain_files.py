"""Height grids from files: the ESRI ASCII grid (``.asc``) and a CSV grid (``.csv``), read within bounds.

Both give a :class:`vehicle_model.terrain.GridTerrain` (bilinear between the nodes). Every refusal is one
:class:`TerrainFileError` line naming the file and the header field, line or row, and what it accepts; the sizes a
file claims are checked before anything is allocated for them (a header claiming 10⁹ cells is refused before the
values are read).

ESRI ASCII grid: a header of ``ncols``, ``nrows``, ``xllcorner`` or ``xllcenter``, ``yllcorner`` or ``yllcenter``,
``cellsize`` and optionally ``NODATA_value`` (one ``key value`` a line, keys in any case), then ``nrows`` rows of
``ncols`` heights, the first row the northernmost. A ``*corner`` is the outer corner of the south-west cell, so its
node (the cell's centre) lies half a cell inside; a ``*center`` is that node.

CSV grid: a header row ``x,y,z`` (in any order; other columns are refused), then one row a node in metres. The nodes
must form a complete regular lattice — every combination of the distinct ``x`` and the distinct ``y`` exactly once,
each evenly spaced — in any row order.

A grid may hold no NODATA cell and no non-finite height: a gap in the ground under a vehicle has no answer.
"""

from __future__ import annotations

import csv
import io
import math
from functools import lru_cache
from pathlib import Path

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.terrain import GridTerrain

TERRAIN_SUFFIXES = (".asc", ".csv")
"""The file types a height grid is read from."""
MAX_FILE_BYTES = 256 * 1024 * 1024
"""Largest terrain file [bytes]: the largest grid at about 25 characters a height."""
MAX_CELLS = 10_000_000
"""Most nodes a grid may have: a 10 km × 10 km area at about 3 m, 80 MB of heights."""
MAX_COORDINATE = 1e8
"""Largest |coordinate| of a grid's corner [m]: beyond any projected system's eastings and northings."""
MAX_CELLSIZE = 1000.0
"""Largest node spacing [m]: a coarser grid says nothing about the ground under an axle."""
MAX_HEIGHT = 10_000.0
"""Largest |height| [m]: above any ground on Earth."""
SPACING_TOLERANCE = 1e-6
"""Relative tolerance on a CSV grid's even spacing."""
HEADER_KEYS = ("ncols", "nrows", "xllcorner", "xllcenter", "yllcorner", "yllcenter", "cellsize", "nodata_value")
"""The keys an ESRI ASCII grid's header may hold."""


class TerrainFileError(InputError):
    """A terrain file that cannot be read; the message is one line naming the file and the place."""


def _number(source: str, where: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise TerrainFileError(f"terrain file {source} {where}: {text!r:.40} is not a number") from None
    if not math.isfinite(value):
        raise TerrainFileError(f"terrain file {source} {where}: {text!r:.40} is not a finite number")
    return value


def _read_header(source: str, stream: io.TextIOBase) -> tuple[dict[str, float], str]:
    """The ESRI header's fields and the first line of data (the line after the header)."""
    header: dict[str, float] = {}
    line_number = 0
    while True:
        line = stream.readline()
        line_number += 1
        if not line:
            raise TerrainFileError(f"terrain file {source}: ends in its header (line {line_number}); give the values")
        parts = line.split()
        if not parts:
            continue
        key = parts[0].lower()
        if key[0].isdigit() or key[0] in "+-.":
            return header, line
        if key not in HEADER_KEYS or len(parts) != 2:
            raise TerrainFileError(
                f"terrain file {source} line {line_number}: {line.strip()!r:.60} is not a header field "
                f"'key value' with key one of {HEADER_KEYS}"
            )
        if key in header:
            raise TerrainFileError(f"terrain file {source} line {line_number}: {parts[0]} is given twice")
        header[key] = _number(source, f"header {parts[0]}", parts[1])


def _check_header(source: str, header: dict[str, float]) -> tuple[int, int, float, float, float, float | None]:
    """``(ncols, nrows, x0, y0, cellsize, nodata)`` of a header, every field within its bounds."""
    for key in ("ncols", "nrows", "cellsize"):
        if key not in header:
            raise TerrainFileError(f"terrain file {source}: the header has no {key}")
    sizes = []
    for key in ("ncols", "nrows"):
        value = header[key]
        if value != int(value) or not 2 <= value <= MAX_CELLS // 2:
            raise TerrainFileError(
                f"terrain file {source} header {key} = {value:g}: must be a whole number in [2, {MAX_CELLS // 2}]"
            )
        sizes.append(int(value))
    ncols, nrows = sizes
    if ncols * nrows > MAX_CELLS:
        raise TerrainFileError(
            f"terrain file {source} header: ncols × nrows = {ncols * nrows} cells is beyond {MAX_CELLS}"
        )
    cellsize = header["cellsize"]
    if not 0.0 < cellsize <= MAX_CELLSIZE:
        raise TerrainFileError(
            f"terrain file {source} header cellsize = {cellsize:g}: must be in (0, {MAX_CELLSIZE:g}] m"
        )
    origin = []
    for axis in ("x", "y"):
        corner, centre = header.get(f"{axis}llcorner"), header.get(f"{axis}llcenter")
        if (corner is None) == (centre is None):
            raise TerrainFileError(
                f"terrain file {source} header: give exactly one of {axis}llcorner and {axis}llcenter"
            )
        value = corner if corner is not None else centre
        assert value is not None
        if abs(value) > MAX_COORDINATE:
            raise TerrainFileError(f"terrain file {source} header {axis}ll: {value:g} is outside ±{MAX_COORDINATE:g} m")
        origin.append(value + 0.5 * cellsize if corner is not None else value)
    return ncols, nrows, origin[0], origin[1], cellsize, header.get("nodata_value")


def read_esri_ascii(file: str | Path) -> GridTerrain:
    """The grid of an ESRI ASCII grid file (the module's docstring says the format).

    Raises
    ------
    TerrainFileError
        One line naming the file and the header field, line or value.
    """
    source = str(file)
    with open(file, encoding="ascii", errors="strict", newline="") as stream:
        try:
            header, first = _read_header(source, stream)  # type: ignore[arg-type]
            ncols, nrows, x0, y0, cellsize, nodata = _check_header(source, header)
            heights = np.empty((nrows, ncols))  # bounded by MAX_CELLS above
            row, line = 0, first
            line_number = len(header) + 1
            while line:
                parts = line.split()
                if parts:
                    if row >= nrows:
                        raise TerrainFileError(
                            f"terrain file {source} line {line_number}: more than nrows = {nrows} rows"
                        )
                    if len(parts) != ncols:
                        raise TerrainFileError(
                            f"terrain file {source} line {line_number}: {len(parts)} values; ncols = {ncols}"
                        )
                    try:
                        heights[row] = np.array(parts, dtype=float)
                    except ValueError:
                        raise TerrainFileError(
                            f"terrain file {source} line {line_number}: a value is not a number"
                        ) from None
                    row += 1
                line = stream.readline()
                line_number += 1
        except UnicodeDecodeError:
            raise TerrainFileError(f"terrain file {source}: is not a text file of ASCII numbers") from None
    if row != nrows:
        raise TerrainFileError(f"terrain file {source}: {row} rows of values; nrows = {nrows}")
    if nodata is not None and np.any(heights == nodata):
        r, c = np.argwhere(heights == nodata)[0]
        raise TerrainFileError(
            f"terrain file {source} row {r + 1} column {c + 1}: NODATA_value {nodata:g}; a grid under the path "
            "must have every height (fill its gaps)"
        )
    _check_heights(source, heights, lambda r, c: f"row {r + 1} column {c + 1}")
    return GridTerrain(x0, y0, cellsize, cellsize, heights[::-1].copy())  # rows from the south


def _check_heights(source: str, heights: np.ndarray, where) -> None:  # type: ignore[no-untyped-def]
    bad = ~np.isfinite(heights) | (np.abs(heights) > MAX_HEIGHT)
    if np.any(bad):
        index = tuple(np.argwhere(bad)[0])
        raise TerrainFileError(
            f"terrain file {source} {where(*index)}: height {heights[index]:g} is not in [-{MAX_HEIGHT:g}, "
            f"{MAX_HEIGHT:g}] m"
        )


def _axis(source: str, name: str, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct, evenly spaced values of one coordinate and each row's index among them."""
    distinct, index = np.unique(values, return_inverse=True)
    if len(distinct) < 2:
        raise TerrainFileError(f"terrain file {source} column {name}: needs at least 2 distinct values")
    step = np.diff(distinct)
    if np.ptp(step) > SPACING_TOLERANCE * step.mean():
        raise TerrainFileError(
            f"terrain file {source} column {name}: the nodes are not evenly spaced (steps {step.min():g} to "
            f"{step.max():g} m); give a regular grid"
        )
    return distinct, index


def read_csv_grid(file: str | Path) -> GridTerrain:
    """The grid of a CSV grid file (the module's docstring says the format).

    Raises
    ------
    TerrainFileError
        One line naming the file and the row or column.
    """
    source = str(file)
    rows: list[tuple[float, float, float]] = []
    with open(file, encoding="utf-8", errors="strict", newline="") as stream:
        try:
            reader = csv.reader(stream)
            header = [h.strip().lower() for h in next(reader, [])]
            if sorted(header) != ["x", "y", "z"]:
                raise TerrainFileError(
                    f"terrain file {source} row 1: the header must be x,y,z (any order), not {header!r:.60}"
                )
            order = [header.index(c) for c in ("x", "y", "z")]
            for i, record in enumerate(reader):
                if not record or all(not cell.strip() for cell in record):
                    continue
                if len(rows) >= MAX_CELLS:
                    raise TerrainFileError(f"terrain file {source} row {i + 2}: more than {MAX_CELLS} nodes")
                if len(record) != 3:
                    raise TerrainFileError(f"terrain file {source} row {i + 2}: {len(record)} values; give x,y,z")
                x, y, z = (_number(source, f"row {i + 2} {c}", record[k]) for c, k in zip("xyz", order, strict=True))
                rows.append((x, y, z))
        except UnicodeDecodeError:
            raise TerrainFileError(f"terrain file {source}: is not UTF-8 text") from None
    if len(rows) < 4:
        raise TerrainFileError(f"terrain file {source}: {len(rows)} nodes; a grid needs at least 2 × 2")
    data = np.array(rows)
    for k, name in ((0, "x"), (1, "y")):
        if np.any(np.abs(data[:, k]) > MAX_COORDINATE):
            raise TerrainFileError(f"terrain file {source} column {name}: a value is outside ±{MAX_COORDINATE:g} m")
    xs, col = _axis(source, "x", data[:, 0])
    ys, row = _axis(source, "y", data[:, 1])
    if len(xs) * len(ys) != len(data) or len(np.unique(row * len(xs) + col)) != len(data):
        raise TerrainFileError(
            f"terrain file {source}: {len(data)} nodes for {len(xs)} x × {len(ys)} y; give every (x, y) node exactly "
            "once"
        )
    heights = np.empty((len(ys), len(xs)))
    heights[row, col] = data[:, 2]
    _check_heights(source, heights, lambda r, c: f"node x = {xs[c]:g}, y = {ys[r]:g}")
    dx = float((xs[-1] - xs[0]) / (len(xs) - 1))
    dy = float((ys[-1] - ys[0]) / (len(ys) - 1))
    return GridTerrain(float(xs[0]), float(ys[0]), dx, dy, heights)


def read_terrain_file(file: str | Path) -> GridTerrain:
    """A height grid from an ``.asc`` or ``.csv`` file, its size checked before it is read.

    Raises
    ------
    TerrainFileError
        One line naming the file: missing, unknown extension, over :data:`MAX_FILE_BYTES`, or what the format's
        reader refuses.
    """
    path = Path(file)
    source = str(file)
    suffix = path.suffix.lower()
    if suffix not in TERRAIN_SUFFIXES:
        raise TerrainFileError(
            f"terrain file {source}: unknown extension {path.suffix!r}; give one of {TERRAIN_SUFFIXES}"
        )
    if not path.is_file():
        raise TerrainFileError(f"terrain file {source} does not exist")
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise TerrainFileError(f"terrain file {source}: {size} bytes is over {MAX_FILE_BYTES} (256 MiB)")
    return read_esri_ascii(path) if suffix == ".asc" else read_csv_grid(path)


@lru_cache(maxsize=4)
def _remembered(file: str, stamp: tuple[int, int, int]) -> GridTerrain:
    del stamp  # part of the key only: a file changed on disk is read again
    return read_terrain_file(file)


def checked_terrain(file: str | Path) -> GridTerrain:
    """:func:`read_terrain_file`, remembered for the file as it is on disk (inode, size, modification time), so the
    check with the configuration and the run's build share one reading."""
    try:
        stat = Path(file).stat()
    except OSError:
        return read_terrain_file(file)
    return _remembered(str(file), (stat.st_ino, stat.st_size, stat.st_mtime_ns))
