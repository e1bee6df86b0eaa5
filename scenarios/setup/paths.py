"""Reference paths built from straights and arcs, sampled densely with arc length, heading and curvature."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..roads.smoothing import SAMPLE_SPACING


@dataclass(frozen=True)
class Segment:
    """A straight (``curvature == 0``) or a circular arc of signed ``curvature`` [1/m], ``length`` [m] long."""

    length: float
    curvature: float = 0.0


@dataclass(frozen=True)
class ReferencePath:
    """A planar path sampled every :data:`SAMPLE_SPACING` metres.

    Attributes
    ----------
    s, x, y, heading, curvature : numpy.ndarray
        Arc length [m], position [m], tangent heading [rad] (unwrapped) and signed curvature [1/m].
    centres : numpy.ndarray
        Centres of the path's circular parts ``(k, 2)``, used for radial camber and the roundabout test.
    turn_span : tuple of float
        Arc-length interval of the manoeuvre proper (e.g. the 360° circle of the roundabout test).
    """

    s: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    curvature: np.ndarray
    centres: np.ndarray
    turn_span: tuple[float, float]

    @property
    def length(self) -> float:
        return float(self.s[-1])

    @property
    def points(self) -> np.ndarray:
        return np.column_stack([self.x, self.y])

    def at(self, s: float) -> tuple[float, float, float, float]:
        """Position, heading and curvature at arc length ``s`` (clamped to the path)."""
        s = min(max(s, 0.0), self.length)
        return (
            float(np.interp(s, self.s, self.x)),
            float(np.interp(s, self.s, self.y)),
            float(np.interp(s, self.s, self.heading)),
            float(np.interp(s, self.s, self.curvature)),
        )

    def project(self, point: np.ndarray, s_guess: float, window: float = 10.0) -> tuple[float, float]:
        """Arc length of the path point nearest ``point`` near ``s_guess`` and the signed lateral offset (left +).

        Searches ``[s_guess − window/4, s_guess + window]`` so a path that crosses itself (a figure of
        eight, a multi-turn roundabout) is followed in order.
        """
        lo = np.searchsorted(self.s, s_guess - 0.25 * window)
        hi = np.searchsorted(self.s, s_guess + window) + 1
        xs, ys = self.x[lo:hi], self.y[lo:hi]
        d2 = (xs - point[0]) ** 2 + (ys - point[1]) ** 2
        i = int(np.argmin(d2)) + lo
        # Refine on the two segments next to the nearest sample for a continuous arc length.
        best_s, best_off, best_d = float(self.s[i]), 0.0, math.inf
        for a in (i - 1, i):
            if a < 0 or a + 1 >= len(self.s):
                continue
            seg = np.array([self.x[a + 1] - self.x[a], self.y[a + 1] - self.y[a]])
            rel = np.asarray(point, dtype=float) - [self.x[a], self.y[a]]
            t = float(np.clip(rel @ seg / (seg @ seg), 0.0, 1.0))
            d = float(np.hypot(*(rel - t * seg)))
            if d < best_d:
                best_d = d
                best_s = float(self.s[a] + t * (self.s[a + 1] - self.s[a]))
                best_off = float((seg[0] * rel[1] - seg[1] * rel[0]) / math.sqrt(seg @ seg))
        return float(best_s), best_off


def build_path(
    segments: list[Segment],
    start: tuple[float, float, float] = (0.0, 0.0, 0.0),
    centres: list[tuple[float, float]] | None = None,
    turn_span: tuple[float, float] | None = None,
) -> ReferencePath:
    """Chain segments from the pose ``start = (x, y, heading)`` and sample the result."""
    xs, ys, hs, ks = [start[0]], [start[1]], [start[2]], [segments[0].curvature if segments else 0.0]
    x, y, h = start
    for seg in segments:
        if seg.length <= 0:
            raise ValueError(f"path segment length {seg.length} must be positive")
        n = max(1, math.ceil(seg.length / SAMPLE_SPACING))
        ds = seg.length / n
        d = np.arange(1, n + 1) * ds
        if seg.curvature == 0.0:
            px = x + d * math.cos(h)
            py = y + d * math.sin(h)
            ph = np.full(n, h)
        else:
            k = seg.curvature
            ph = h + k * d
            px = x + (np.sin(ph) - math.sin(h)) / k
            py = y - (np.cos(ph) - math.cos(h)) / k
        xs.extend(px)
        ys.extend(py)
        hs.extend(ph)
        ks.extend([seg.curvature] * n)
        x, y, h = float(px[-1]), float(py[-1]), float(ph[-1])
    x_arr, y_arr = np.array(xs), np.array(ys)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x_arr), np.diff(y_arr)))])
    span = turn_span if turn_span is not None else (0.0, float(s[-1]))
    return ReferencePath(
        s=s,
        x=x_arr,
        y=y_arr,
        heading=np.array(hs),
        curvature=np.array(ks),
        centres=np.array(centres if centres else np.zeros((0, 2)), dtype=float).reshape(-1, 2),
        turn_span=span,
    )


def roundabout_path(
    radius: float, turns: float, direction: int, entry: float, exit_: float, settle_turns: float = 0.0
) -> ReferencePath:
    """Entry straight along +X ending at the origin, ``settle_turns + turns`` circles of ``radius``, exit straight.

    ``direction`` is +1 for a left (anticlockwise) and −1 for a right turn. The circle's centre is at
    ``(0, direction·radius)``; ``turn_span`` covers the last ``turns`` circles (the first
    ``settle_turns`` let the combination settle onto the circle before it is assessed).
    """
    k = direction / radius
    settle = 2.0 * math.pi * radius * settle_turns
    arc = 2.0 * math.pi * radius * turns
    segments = [Segment(entry), Segment(settle + arc, k), Segment(exit_)]
    return build_path(
        segments,
        start=(-entry, 0.0, 0.0),
        centres=[(0.0, direction * radius)],
        turn_span=(entry + settle, entry + settle + arc),
    )


def turn_path(radius: float, angle: float, direction: int, entry: float, exit_: float) -> ReferencePath:
    """Entry straight along +X ending at the origin, one arc of ``radius`` through ``angle`` [rad], exit straight.

    ``direction`` is +1 for a left and −1 for a right turn; the arc's centre is at ``(0, direction·radius)`` and
    ``turn_span`` is the arc (the PBS low-speed turn is 90° on the outer steer tyre's radius, docs/pbs.md).
    """
    arc = radius * angle
    segments = [Segment(entry), Segment(arc, direction / radius), Segment(exit_)]
    return build_path(
        [seg for seg in segments if seg.length > 0.0],
        start=(-entry, 0.0, 0.0),
        centres=[(0.0, direction * radius)],
        turn_span=(entry, entry + arc),
    )


def figure_eight_path(radius: float, gap: float, entry: float, exit_: float, direction: int = 1) -> ReferencePath:
    """Entry straight, a full loop one way, a straight of ``gap`` metres, a full loop the other way, exit.

    The loops' centres are ``(0, d·R)`` and ``(gap, −d·R)`` with ``d = direction`` (+1: left loop first).
    """
    k = direction / radius
    loop = 2.0 * math.pi * radius
    segments = [Segment(entry), Segment(loop, k), Segment(gap), Segment(loop, -k), Segment(exit_)]
    return build_path(
        segments,
        start=(-entry, 0.0, 0.0),
        centres=[(0.0, direction * radius), (gap, -direction * radius)],
        turn_span=(entry, entry + 2 * loop + gap),
    )


def straight_path(length: float, entry: float = 0.0) -> ReferencePath:
    """A straight along +X from ``(-entry, 0)``."""
    return build_path([Segment(length + entry)], start=(-entry, 0.0, 0.0), turn_span=(entry, entry + length))
