"""The points of a road file and the bounds every road is held to before anything is allocated for it.

A road file is read within bounds (:data:`MAX_FILE_BYTES`, :data:`MAX_POINTS`), and its polyline is checked before
the smoothing allocates its dense curve, whose size follows the polyline's length: every point finite, none
repeating the one before, the length within [:data:`MIN_LENGTH`, :data:`MAX_LENGTH`]. Each refusal is one
:class:`RoadFileError` line naming the file and the row, coordinate or point.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vehicle_model.errors import InputError

COLUMNS = ("x", "y", "speed", "crossfall", "mu")
"""The values a road point may have; ``x`` and ``y`` are required."""
SAME_POINT = 1e-6
"""Two consecutive points closer than this [m] are the same point (refused: the direction between them is noise)."""
MIN_LENGTH = 10.0
"""Shortest road [m], along its points: a road shorter than the shortest combination ends the run before its first
trailer is on it, and its smoothed curve is mostly the straight extensions of its ends."""
MAX_LENGTH = 100_000.0
"""Longest road [m], along its points: beyond an hour's drive at a truck's 90 km/h (``duration_s`` holds at most an
hour); the smoothing holds the curve every centimetre, so its memory grows with the length."""
MAX_POINTS = 1_000_000
"""Most points a road file may give: ten a metre over the longest road."""
MAX_FILE_BYTES = 64 * 1024 * 1024
"""Largest road file [bytes]: a CSV of the most points with speed, crossfall and μ fits within it."""
DEGREES = (180.0, 90.0)
"""The largest absolute longitude and latitude [°]: a road under a metre long whose every point lies within them is
named as possibly given in degrees (a road of degrees read as metres is a thousandth of its length or less)."""


class RoadFileError(InputError):
    """A road file that cannot be read or driven; the message is one line naming the file and the place."""


@dataclass(frozen=True)
class RoadPoints:
    """The points of a road file, in driving order, and the optional values given at each.

    Attributes
    ----------
    source : str
        The file, as named in messages.
    xy : numpy.ndarray
        Points ``(N, 2)`` [m].
    speed, crossfall, mu : numpy.ndarray or None
        Target speed [m/s], crossfall [%] (positive falling right) and friction coefficient at each point.
    """

    source: str
    xy: np.ndarray
    speed: np.ndarray | None = None
    crossfall: np.ndarray | None = None
    mu: np.ndarray | None = None


def read_bounded(file: Path, source: str) -> bytes:
    """The bytes of a road file no larger than :data:`MAX_FILE_BYTES`, refused in one line otherwise."""
    try:
        size = file.stat().st_size
        if size > MAX_FILE_BYTES:
            raise RoadFileError(
                f"road file {source} is {size} bytes; a road file holds at most {MAX_FILE_BYTES} ({MAX_POINTS} points)"
            )
        with file.open("rb") as stream:
            data = stream.read(size + 1)  # a read allocates what it asks for: the file's size, not the bound
            if len(data) > size:  # grown since its stat: the rest, within the bound
                data += stream.read(MAX_FILE_BYTES + 1 - len(data))
    except OSError as exc:
        raise RoadFileError(f"road file {source} cannot be read: {exc.strerror or exc}") from None
    if len(data) > MAX_FILE_BYTES:
        raise RoadFileError(f"road file {source} is over {MAX_FILE_BYTES} bytes, the most a road file holds")
    return data


def check_count(source: str, count: int) -> None:
    """Refuse more than :data:`MAX_POINTS` points before they are converted."""
    if count > MAX_POINTS:
        raise RoadFileError(f"road file {source} has more than {MAX_POINTS} points, the most a road has")


def check_values(source: str, column: str, values: np.ndarray, label: Callable[[int], str]) -> None:
    """Refuse values outside what the column can hold (speed > 0, |crossfall| ≤ 10 %, 0 < μ ≤ 1.5)."""
    bounds = {
        "speed": (0.0, 90.0, "a speed in (0, 90] km/h: 90 km/h is a truck's speed limiter"),
        "crossfall": (-10.0, 10.0, "a crossfall in [-10, 10] %: 10 % is beyond any carriageway"),
        "mu": (0.0, 1.5, "a friction coefficient in (0, 1.5]"),
    }
    low, high, what = bounds[column]
    bad = ~((values > low) if column != "crossfall" else (values >= low)) | (values > high)
    if bad.any():
        i = int(np.argmax(bad))
        raise RoadFileError(f"road file {source} {label(i)}: {column} = {values[i]:g} is not {what}")


def check_polyline(source: str, xy: np.ndarray, label: Callable[[int], str]) -> None:
    """Refuse a polyline that cannot be smoothed or driven, before the smoothing allocates for it.

    Raises
    ------
    RoadFileError
        Fewer than two points, a point that is not finite or repeats the one before, a length outside
        [:data:`MIN_LENGTH`, :data:`MAX_LENGTH`] (a road under a metre whose points all lie within ±180, ±90 is named
        as possibly longitude and latitude in degrees).
    """
    if len(xy) < 2:
        raise RoadFileError(f"road file {source} has {len(xy)} point(s); a road needs at least 2")
    finite = np.isfinite(xy).all(axis=1)
    if not finite.all():
        i = int(np.argmin(finite))
        raise RoadFileError(f"road file {source} {label(i)}: ({xy[i, 0]}, {xy[i, 1]}) is not a finite point")
    step = np.hypot(*np.diff(xy, axis=0).T)
    if not np.isfinite(step).all():  # finite points whose differences overflow: beyond any road
        i = int(np.argmin(np.isfinite(step))) + 1
        raise RoadFileError(f"road file {source} {label(i)}: ({xy[i, 0]:g}, {xy[i, 1]:g}) is beyond any road")
    if (step <= SAME_POINT).any():
        i = int(np.argmax(step <= SAME_POINT)) + 1
        raise RoadFileError(
            f"road file {source} {label(i)}: the same point as {label(i - 1)} ({xy[i, 0]:g}, {xy[i, 1]:g}); "
            "remove the repeat"
        )
    along = np.cumsum(step)
    if along[-1] > MAX_LENGTH:
        i = int(np.argmax(along > MAX_LENGTH)) + 1
        raise RoadFileError(
            f"road file {source} {label(i)}: ({xy[i, 0]:g}, {xy[i, 1]:g}) is {along[i - 1]:.6g} m along the road; "
            f"a road is at most {MAX_LENGTH:g} m long (a point far from the others is a typing error)"
        )
    if along[-1] < MIN_LENGTH:
        degrees = along[-1] < 1.0 and bool((np.abs(xy) <= DEGREES).all())
        hint = "; its points look like longitude and latitude in degrees: give projected metres" if degrees else ""
        raise RoadFileError(
            f"road file {source}: the road is {along[-1]:.3g} m long; a road is at least {MIN_LENGTH:g} m long{hint}"
        )


def finite_number(value: object) -> float | None:
    """``value`` as a finite float if it is a JSON number (not a bool) a float can hold, else None."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None
