"""The lane changes of the heavy-vehicle and passenger-car standards as smooth generated paths.

Both are a lateral offset ``y(x)`` of a straight along +X, built from one transition shape, the *sine-acceleration*
(cycloid) blend from 0 to ``A`` over ``L``::

    y = A·(ξ − sin(2πξ)/(2π)),   y' = (A/L)·(1 − cos 2πξ),   y'' = (2πA/L²)·sin 2πξ,   ξ = x/L

whose lateral acceleration at constant forward speed is one full sine period: the path's curvature
``κ = y''/(1 + y'²)^{3/2}`` is zero at both ends of the transition, so it is continuous along the whole path
(a driver's feed-forward reads no step), and heading and curvature are analytic.

* **Single lane change** (ISO 14791, *Road vehicles — Heavy commercial vehicle combinations and articulated buses —
  Lateral stability test methods*, the path-following single lane change used for rearward amplification and
  high-speed transient off-tracking): one transition. Its defaults, 1.46 m over 61.1 m, are those of a tractor
  driven at 88 km/h through one period of a 0.4 Hz sine of 0.15 g lateral acceleration
  (``A = a·T²/(2π)``, ``L = v·T``) — the figures the test is commonly quoted with; they were **not** checked against
  the standard's own text, which was not available, so they are fields (``path.slc_offset``, ``path.slc_length``).
* **Double lane change** (ISO 3888-1, *Passenger cars — Test track for a severe lane-change manoeuvre — Part 1:
  Double lane-change*; its scope is passenger cars and light commercial vehicles up to 3.5 t): five sections —
  entry lane, lane change, offset lane, return, exit lane — and a lateral offset. The defaults, sections of 15, 30,
  25, 25 and 15 m and an offset of 3.5 m, are the commonly quoted track of the standard's Table 1; they were **not**
  checked against its text either (``path.dlc_sections``, ``path.dlc_offset``). The track's lane widths, which depend
  on the vehicle's width, bound the cones, not the path, and are not modelled: the path is the lanes' centre line.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .paths import SAMPLE_SPACING, ReferencePath

_DENSE = 0.005
"""Step [m] of the grid along x on which the arc length is integrated (trapezoid; error far below 1 µm)."""


def _blend(x: np.ndarray, start: float, length: float, amplitude: float) -> tuple[np.ndarray, ...]:
    """``y, y', y''`` of the sine-acceleration blend from 0 to ``amplitude`` over ``[start, start + length]``."""
    xi = np.clip((x - start) / length, 0.0, 1.0)
    inside = (x > start) & (x < start + length)
    w = 2.0 * math.pi * xi
    y = amplitude * (xi - np.sin(w) / (2.0 * math.pi))
    dy = np.where(inside, amplitude / length * (1.0 - np.cos(w)), 0.0)
    ddy = np.where(inside, 2.0 * math.pi * amplitude / length**2 * np.sin(w), 0.0)
    return y, dy, ddy


def offset_path(
    transitions: Sequence[tuple[float, float, float]], total: float, entry: float, turn_span_x: tuple[float, float]
) -> ReferencePath:
    """A straight along +X from ``(-entry, 0)`` with lateral blends ``(start x, length, change of y)`` added.

    Parameters
    ----------
    transitions
        Each blend's start ``x`` [m] (the manoeuvre starts at ``x = 0``), length [m] and signed change of ``y`` [m].
    total
        Length along x of the manoeuvre and its exit [m] (the path ends at ``x = total``).
    entry
        Approach straight before ``x = 0`` [m].
    turn_span_x
        The manoeuvre's interval of ``x`` [m], turned into the path's ``turn_span`` in arc length.

    Returns
    -------
    ReferencePath
        Sampled about every :data:`~scenarios.setup.paths.SAMPLE_SPACING` of arc length, with analytic heading
        ``atan y'`` and curvature ``y''/(1 + y'²)^{3/2}``.
    """

    def lateral(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        y, dy, ddy = np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)
        for start, length, change in transitions:
            a, b, c = _blend(x, start, length, change)
            y, dy, ddy = y + a, dy + b, ddy + c
        return y, dy, ddy

    dense = np.linspace(-entry, total, max(2, math.ceil((total + entry) / _DENSE) + 1))
    _, dy, _ = lateral(dense)
    speed = np.sqrt(1.0 + dy**2)
    arc = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(dense))])
    n = max(1, math.ceil(arc[-1] / SAMPLE_SPACING))
    s = np.linspace(0.0, arc[-1], n + 1)
    x = np.interp(s, arc, dense)
    y, dy, ddy = lateral(x)
    x[-1] = total  # the last sample exactly at the end
    span = tuple(float(np.interp(v, dense, arc)) for v in turn_span_x)
    return ReferencePath(
        s=s,
        x=x,
        y=y,
        heading=np.arctan(dy),
        curvature=ddy / (1.0 + dy**2) ** 1.5,
        centres=np.zeros((0, 2)),
        turn_span=(span[0], span[1]),
    )


def single_lane_change_path(offset: float, length: float, entry: float, exit_: float, direction: int) -> ReferencePath:
    """ISO 14791's single lane change: ``offset`` [m] sideways over ``length`` [m] (module docstring).

    Parameters
    ----------
    offset, length
        The lateral offset and the length of the transition [m].
    entry, exit_
        Approach and departure straights [m].
    direction
        +1 to the left, −1 to the right.

    Returns
    -------
    ReferencePath
        Starting at ``(-entry, 0)`` heading +X; ``turn_span`` is the transition.
    """
    return offset_path([(0.0, length, direction * offset)], length + exit_, entry, (0.0, length))


def double_lane_change_path(
    offset: float, sections: Sequence[float], entry: float, exit_: float, direction: int
) -> ReferencePath:
    """ISO 3888-1's double lane change: entry lane, change, offset lane, return, exit lane (module docstring).

    Parameters
    ----------
    offset
        Lateral offset of the offset lane's centre line [m].
    sections
        Lengths of the five sections [m]: entry lane, lane change, offset lane, return, exit lane.
    entry, exit_
        Approach straight before the entry lane and departure straight after the exit lane [m].
    direction
        +1: the first change is to the left; −1: to the right.

    Returns
    -------
    ReferencePath
        Starting at ``(-entry, 0)`` heading +X; ``turn_span`` covers the five sections.
    """
    l1, l2, l3, l4, l5 = sections
    k = direction * offset
    transitions = [(l1, l2, k), (l1 + l2 + l3, l4, -k)]
    track = l1 + l2 + l3 + l4 + l5
    return offset_path(transitions, track + exit_, entry, (0.0, track))
