"""Trailer off-tracking: the kingpin path buffer (de Saxe & Cebon 2018, eqs (3)–(7)) and its geometric ground truth.

All three off-tracking estimates (ground truth, zero-slip, VISO-OT) are this one :class:`OfftrackingBuffer` fed
with kingpin motion increments from different sources. :func:`offtracking_from_path` and
:func:`offtracking_series` compute the same quantity directly from a global kingpin path, without the buffer,
and serve as the reference the buffer is tested against.

Convention (docs/design.md §6, ISO 8855)
----------------------------------------
The trailer frame has its origin at the kingpin, x forward along the trailer centre line, y to the left; yaw
is positive anticlockwise. The follow point sits at ``(−L_fp, 0)``. The **off-tracking** ``e_tr`` is the y
coordinate, in the *current* trailer frame, of the kingpin's *past* path at the station ``x = −L_fp``.
``e_tr > 0`` means the follow point is to the right of the kingpin path; in a steady left turn an unsteered
trailer cuts in and ``e_tr < 0``.

Mapping from the paper's notation (de Saxe & Cebon 2018, §2.2)::

    paper                                   here (ISO 8855)
    y  (longitudinal, forward)         →    x
    x  (lateral)                       →    y
    a + b  (kingpin to follow point)   →    L_fp = follow_point_offset
    eq (6):  y_F ≤ −(a + b)            →    x ≤ −L_fp
    eq (7):  e_tr = x_F interpolated   →    e_tr = y interpolated at x = −L_fp

The paper does not state the handedness of its frame. Read with the camera's (right, forward) axes, its
eqs (1)–(2) suggest its lateral x points to the right (and Δψ positive clockwise); if so its e_tr has the
opposite sign to the one used here. This module follows docs/design.md §6: e_tr is the ISO (left-positive) y.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from .errors import InputError

__all__ = [
    "BUFFER_FILLING",
    "OfftrackingBuffer",
    "OfftrackingEstimate",
    "increments_from_poses",
    "offtracking_from_path",
    "offtracking_series",
]


BUFFER_FILLING = "buffer_filling"
"""Why a buffer gives no estimate yet: less than one trailer length of kingpin path is stored."""


@dataclass(frozen=True, slots=True)
class OfftrackingEstimate:
    """One off-tracking estimate: its value, its standard deviation and, when it has no value, why.

    Every source of the closed loop (the ground truth, the zero-slip estimator, VISO-OT and its fused form)
    gives one of these each control tick; the trailer-steering controller takes one.

    Attributes
    ----------
    value : float
        Off-tracking ``e_tr`` [m] (module docstring for the sign); NaN when there is no estimate.
    std : float
        Its standard deviation [m]; NaN when the source gives none.
    reason : str
        Why there is no value (a short code, e.g. :data:`BUFFER_FILLING`); ``""`` when there is one.
    """

    value: float = math.nan
    std: float = math.nan
    reason: str = ""

    @property
    def available(self) -> bool:
        """Whether there is a (finite) value."""
        return math.isfinite(self.value)

    @classmethod
    def of(cls, value: float | None, std: float = math.nan, reason: str = BUFFER_FILLING) -> OfftrackingEstimate:
        """An estimate from a value that may be ``None`` (no estimate, for ``reason``)."""
        if value is None:
            return cls(math.nan, std, reason or BUFFER_FILLING)
        return cls(float(value), std, "")


def _check_offset(follow_point_offset: float) -> float:
    value = float(follow_point_offset)
    if not (math.isfinite(value) and value > 0.0):
        raise InputError(
            f"follow_point_offset = {follow_point_offset!r} must be a finite distance > 0 m "
            "(kingpin to follow point, measured backwards along the trailer centre line)"
        )
    return value


def _wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped to (−π, π]."""
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


def _interpolate_at_station(
    older: np.ndarray, newer: np.ndarray, c: float | np.ndarray, s: float | np.ndarray, offset: float
) -> float | np.ndarray:
    """y at ``x = −offset`` on segments ``older → newer`` (global offsets from the kingpin, ``(..., 2)``).

    The points are rotated into the trailer frame (heading with cosine ``c``, sine ``s``) and y is
    interpolated linearly: de Saxe & Cebon 2018, eq (7), with the paper's (lateral x, longitudinal y) mapped
    to ISO (y, x).
    """
    x0 = c * older[..., 0] + s * older[..., 1]
    y0 = c * older[..., 1] - s * older[..., 0]
    x1 = c * newer[..., 0] + s * newer[..., 1]
    y1 = c * newer[..., 1] - s * newer[..., 0]
    return y0 + (y1 - y0) * (-offset - x0) / (x1 - x0)


class OfftrackingBuffer:
    """Kingpin path history in the current trailer frame, and the off-tracking read from it.

    Every estimator feeds this buffer with kingpin motion increments (:meth:`push`); :meth:`offtracking`
    interpolates the stored path at the follow-point station (de Saxe & Cebon 2018, eqs (3)–(7)).

    The stored points are kept in the *current* trailer frame: each push applies the rigid transform of the
    increment to all of them at once (vectorised), which is the paper's accumulation of heading changes
    (eq (3)), rotation of the increments into the current frame (eq (4)) and their summation (eq (5)) done
    recursively. Older points than the most recent one behind the follow point are dropped after every push,
    so the buffer holds about one trailer length of path (the paper's buffer length ``k_b``).

    Parameters
    ----------
    follow_point_offset : float
        ``L_fp`` [m] > 0: distance from the kingpin back to the follow point along the trailer centre line
        (the paper's ``a + b``).
    min_spacing : float, optional
        Smallest spacing [m] between stored points, ``0 ≤ min_spacing < L_fp``. While the kingpin has moved
        less than this from the newest stored point (standstill, creeping), no point is added; the increments
        still move the stored points. Also the threshold for detecting reversing.
    max_points : int, optional
        Safety cap on the number of stored points (≥ 2); the oldest are dropped beyond it. If that removes
        the point behind the follow point, :meth:`offtracking` reports no estimate rather than a wrong one.

    Notes
    -----
    *Standstill.* A point is appended when the current kingpin is at least ``min_spacing`` from the newest
    stored point, judged on the accumulated motion, not on a single increment, so slow creeping in
    sub-``min_spacing`` steps still records the path. A pure rotation at standstill rotates the stored path.

    *Reversing.* When the kingpin moves backwards along the trailer axis (an increment with
    ``dx < −min_spacing``, or accumulated creeping that puts the newest stored point more than ``min_spacing``
    ahead of the kingpin), the stored history no longer describes the path ahead of the follow point: the
    buffer is cleared (as by :meth:`reset`) and reports no estimate until one trailer length has again been
    driven forwards.

    *No estimate.* :meth:`offtracking` returns ``None`` until a stored point reaches ``x ≤ −L_fp``, i.e.
    until at least one trailer length has been driven since the last reset.

    *Pruning.* Only one point behind the follow point is kept (eq (6)). If the trailer later yaws relative to
    its path fast enough to swing that point ahead of ``x = −L_fp`` (faster than about ``u/|e_tr|``, which a
    trailer only does at standstill, where it does not yaw), the older points needed are gone and the buffer
    reports no estimate until driving carries the path past the follow point again; it never extrapolates.
    """

    def __init__(self, follow_point_offset: float, min_spacing: float = 1e-3, max_points: int = 100_000) -> None:
        self._offset = _check_offset(follow_point_offset)
        spacing = float(min_spacing)
        if not (math.isfinite(spacing) and 0.0 <= spacing < self._offset):
            raise InputError(
                f"min_spacing = {min_spacing!r} must be finite and in [0, follow_point_offset = {self._offset} m)"
            )
        self._min_spacing = spacing
        if not isinstance(max_points, numbers.Integral) or isinstance(max_points, bool) or max_points < 2:
            raise InputError(f"max_points = {max_points!r} must be an integer ≥ 2")
        self._max_points = int(max_points)
        # Stored points live in self._store[self._start:self._end], oldest first, in the current trailer frame.
        self._store = np.empty((min(1024, 2 * self._max_points + 2), 2))
        self._start = 0
        self._end = 0
        self._distance = 0.0
        self.reset()

    # ------------------------------------------------------------------ properties

    @property
    def follow_point_offset(self) -> float:
        """``L_fp`` [m]."""
        return self._offset

    @property
    def min_spacing(self) -> float:
        """Smallest spacing between stored points [m]."""
        return self._min_spacing

    @property
    def max_points(self) -> int:
        """Cap on the number of stored points."""
        return self._max_points

    @property
    def distance_travelled(self) -> float:
        """Path length [m] of the kingpin since the last reset (sum of the increment lengths)."""
        return self._distance

    @property
    def points(self) -> np.ndarray:
        """Copy of the stored kingpin path ``(N, 2)`` in the current trailer frame [m], oldest first.

        The newest point is the current kingpin ``(0, 0)``, or within ``min_spacing`` of it at standstill.
        """
        return self._store[self._start : self._end].copy()

    def __len__(self) -> int:
        return self._end - self._start

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(follow_point_offset={self._offset}, points={len(self)}, "
            f"distance_travelled={self._distance:.3f})"
        )

    # ------------------------------------------------------------------ updates

    def reset(self) -> None:
        """Forget the history: the buffer holds only the current kingpin and reports no estimate."""
        self._store[0] = 0.0
        self._start = 0
        self._end = 1
        self._distance = 0.0

    def push(self, dx: float, dy: float, dpsi: float) -> None:
        """Add one kingpin motion increment.

        Parameters
        ----------
        dx, dy : float
            Kingpin displacement [m] from the previous sample to now, in the trailer frame *at the previous
            sample* (x forward, y left).
        dpsi : float
            Trailer heading change [rad] over the same interval, positive anticlockwise.

        Raises
        ------
        InputError
            If an increment is not finite.
        """
        dx, dy, dpsi = float(dx), float(dy), float(dpsi)
        if not (math.isfinite(dx) and math.isfinite(dy) and math.isfinite(dpsi)):
            raise InputError(f"kingpin increment (dx={dx}, dy={dy}, dpsi={dpsi}) must be finite")
        if dx < -self._min_spacing:
            self.reset()  # reversing: the history no longer lies ahead of the follow point
            return
        self._distance += math.hypot(dx, dy)

        # Move every stored point into the new frame: translate by −(dx, dy), rotate by −dpsi.
        # de Saxe & Cebon 2018, eqs (3)–(5), applied recursively one frame at a time.
        pts = self._store[self._start : self._end]
        c, s = math.cos(dpsi), math.sin(dpsi)
        x = pts[:, 0] - dx
        y = pts[:, 1] - dy
        pts[:, 0] = c * x + s * y
        pts[:, 1] = c * y - s * x

        newest = pts[-1]
        if newest[0] > self._min_spacing:
            # Crept backwards in sub-min_spacing steps: the newest stored point is now ahead of the kingpin.
            self.reset()
            return
        if newest[0] * newest[0] + newest[1] * newest[1] >= self._min_spacing * self._min_spacing and (
            newest[0] != 0.0 or newest[1] != 0.0
        ):
            self._append_origin()
        self._prune()

    def _append_origin(self) -> None:
        if self._end == self._store.shape[0]:
            n = self._end - self._start
            if 2 * n > self._store.shape[0]:  # more than half full: grow (never beyond 2·max_points + 2)
                grown = np.empty((min(2 * self._store.shape[0], 2 * self._max_points + 2), 2))
                grown[:n] = self._store[self._start : self._end]
                self._store = grown
            else:  # mostly pruned space at the front: move the live points down
                self._store[:n] = self._store[self._start : self._end]
            self._start, self._end = 0, n
        self._store[self._end] = 0.0
        self._end += 1
        if self._end - self._start > self._max_points:
            self._start = self._end - self._max_points

    def _prune(self) -> None:
        # de Saxe & Cebon 2018, eq (6): keep the most recent point with x ≤ −L_fp and everything newer.
        behind = np.flatnonzero(self._store[self._start : self._end, 0] <= -self._offset)
        if behind.size:
            self._start += int(behind[-1])

    # ------------------------------------------------------------------ estimate

    def offtracking(self) -> float | None:
        """Off-tracking ``e_tr`` [m] at the follow point, or ``None`` when there is no estimate.

        Returns
        -------
        float or None
            The y coordinate of the stored kingpin path at ``x = −L_fp`` (positive: follow point to the
            right of the kingpin path), interpolated linearly between the most recent point with
            ``x ≤ −L_fp`` and the next newer one; ``None`` until one trailer length has been driven since
            the last reset, or when the history does not reach back to the follow point.
        """
        if self._end - self._start < 2:
            return None
        older = self._store[self._start]
        newer = self._store[self._start + 1]
        if not (older[0] <= -self._offset < newer[0]):
            return None  # no stored point behind the follow point (too short, or cut by max_points)
        # de Saxe & Cebon 2018, eq (7), with the paper's (lateral x, longitudinal y) mapped to ISO (y, x).
        return float(older[1] + (newer[1] - older[1]) * (-self._offset - older[0]) / (newer[0] - older[0]))


def increments_from_poses(kingpin_xy: np.ndarray, trailer_heading: np.ndarray) -> np.ndarray:
    """Exact kingpin increments between consecutive global trailer poses.

    Parameters
    ----------
    kingpin_xy : ndarray, shape (N, 2)
        Global kingpin positions [m], oldest first.
    trailer_heading : ndarray, shape (N,)
        Global trailer heading ψ2 [rad] at the same samples.

    Returns
    -------
    ndarray, shape (N − 1, 3)
        Rows ``(dx, dy, dpsi)``: ``(dx, dy) = R(−ψ2_prev)·(P5_now − P5_prev)`` in the previous trailer frame,
        ``dpsi = ψ2_now − ψ2_prev`` wrapped to (−π, π]; ready for :meth:`OfftrackingBuffer.push`.
    """
    p = np.asarray(kingpin_xy, dtype=float)
    psi = np.asarray(trailer_heading, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or psi.shape != (p.shape[0],):
        raise InputError(
            f"kingpin_xy must have shape (N, 2) and trailer_heading shape (N,); got {p.shape} and {psi.shape}"
        )
    if not (np.isfinite(p).all() and np.isfinite(psi).all()):
        raise InputError("kingpin_xy and trailer_heading must be finite")
    d = np.diff(p, axis=0)
    c, s = np.cos(psi[:-1]), np.sin(psi[:-1])
    out = np.empty((max(p.shape[0] - 1, 0), 3))
    out[:, 0] = c * d[:, 0] + s * d[:, 1]
    out[:, 1] = c * d[:, 1] - s * d[:, 0]
    out[:, 2] = _wrap_angle(np.diff(psi))
    return out


def offtracking_from_path(
    kingpin_path: np.ndarray,
    kingpin_now: np.ndarray,
    trailer_heading_now: float,
    follow_point_offset: float,
) -> float | None:
    """Geometric off-tracking from a global kingpin path, independent of :class:`OfftrackingBuffer`.

    Parameters
    ----------
    kingpin_path : ndarray, shape (N, 2)
        Global kingpin positions [m], oldest first. It should end at the current kingpin; ``kingpin_now`` is
        not appended.
    kingpin_now : ndarray, shape (2,)
        Current global kingpin position [m] (origin of the current trailer frame).
    trailer_heading_now : float
        Current global trailer heading ψ2 [rad].
    follow_point_offset : float
        ``L_fp`` [m] > 0.

    Returns
    -------
    float or None
        ``e_tr`` [m]: y of the path in the current trailer frame at ``x = −L_fp``, interpolated linearly on
        the most recent segment that crosses that station. ``None`` if the path never reaches back that far,
        or if the most recent crossing is towards the rear (the newest part of the path lies behind the
        follow point, which the kingpin could only have left by reversing).
    """
    offset = _check_offset(follow_point_offset)
    path = np.asarray(kingpin_path, dtype=float)
    origin = np.asarray(kingpin_now, dtype=float)
    psi = float(trailer_heading_now)
    if path.ndim != 2 or path.shape[1] != 2 or origin.shape != (2,):
        raise InputError(f"kingpin_path must have shape (N, 2) and kingpin_now (2,); got {path.shape}, {origin.shape}")
    if not (np.isfinite(path).all() and np.isfinite(origin).all() and math.isfinite(psi)):
        raise InputError("kingpin_path, kingpin_now and trailer_heading_now must be finite")
    if path.shape[0] < 2:
        return None
    c, s = math.cos(psi), math.sin(psi)
    rel = path - origin
    behind = c * rel[:, 0] + s * rel[:, 1] <= -offset  # x ≤ −L_fp in the current trailer frame
    if behind[-1]:
        return None
    crossings = np.flatnonzero(behind[:-1] & ~behind[1:])  # older point behind, newer point ahead
    if crossings.size == 0:
        return None
    i = int(crossings[-1])
    return float(_interpolate_at_station(rel[i], rel[i + 1], c, s, offset))


def offtracking_series(
    kingpin_path: np.ndarray,
    trailer_heading: np.ndarray,
    follow_point_offset: float,
    block: int = 64,
) -> np.ndarray:
    """Geometric off-tracking at every sample of a run (vectorised :func:`offtracking_from_path`).

    Element ``k`` equals ``offtracking_from_path(kingpin_path[:k + 1], kingpin_path[k], trailer_heading[k],
    follow_point_offset)``, with NaN for ``None``.

    Parameters
    ----------
    kingpin_path : ndarray, shape (N, 2)
        Global kingpin positions [m], oldest first.
    trailer_heading : ndarray, shape (N,)
        Global trailer heading ψ2 [rad] at the same samples.
    follow_point_offset : float
        ``L_fp`` [m] > 0.
    block : int, optional
        Number of past samples examined per vectorised pass (a tuning knob, not a limit).

    Returns
    -------
    ndarray, shape (N,)
        ``e_tr`` [m] per sample; NaN where there is no estimate.

    Notes
    -----
    A sample whose arc-length distance to sample ``k`` is below ``L_fp`` lies closer than ``L_fp`` to the
    kingpin, so it cannot satisfy ``x ≤ −L_fp``. The search for each ``k`` therefore starts at the newest
    sample at least ``L_fp`` of path back and walks further back ``block`` samples at a time, for all ``k`` at
    once, until the most recent sample with ``x ≤ −L_fp`` is found or the path runs out.
    """
    offset = _check_offset(follow_point_offset)
    p = np.asarray(kingpin_path, dtype=float)
    psi = np.asarray(trailer_heading, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or psi.shape != (p.shape[0],):
        raise InputError(
            f"kingpin_path must have shape (N, 2) and trailer_heading shape (N,); got {p.shape} and {psi.shape}"
        )
    if not (np.isfinite(p).all() and np.isfinite(psi).all()):
        raise InputError("kingpin_path and trailer_heading must be finite")
    if int(block) < 1:
        raise InputError(f"block = {block!r} must be a positive integer")
    block = int(block)
    n = p.shape[0]
    result = np.full(n, np.nan)
    if n < 2:
        return result
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
    # Newest sample with at least L_fp of path (less a rounding margin) between it and sample k.
    margin = 1e-9 * (offset + arc[-1])
    newest_candidate = np.searchsorted(arc, arc - offset + margin, side="right") - 1
    cos_k, sin_k = np.cos(psi), np.sin(psi)
    steps = np.arange(block)
    chunk = max(1, 2**19 // block)  # bounds the temporaries to a few MB
    for first in range(0, n, chunk):
        pending = np.arange(first, min(first + chunk, n))
        top = newest_candidate[pending]
        keep = top >= 0
        pending, top = pending[keep], top[keep]
        while pending.size:
            idx = top[:, None] - steps[None, :]  # candidate samples, newest first
            rel = p[np.maximum(idx, 0)] - p[pending][:, None, :]
            x = cos_k[pending][:, None] * rel[..., 0] + sin_k[pending][:, None] * rel[..., 1]
            hit = (idx >= 0) & (x <= -offset)
            found = hit.any(axis=1)
            if found.any():
                rows = np.flatnonzero(found)
                k = pending[rows]
                i = idx[rows, np.argmax(hit[rows], axis=1)]
                result[k] = _interpolate_at_station(p[i] - p[k], p[i + 1] - p[k], cos_k[k], sin_k[k], offset)
            keep = ~found & (top - block >= 0)
            pending, top = pending[keep], top[keep] - block
    return result
