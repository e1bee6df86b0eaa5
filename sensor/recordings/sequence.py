"""A recorded stereo sequence: its frames' slots before any image is decoded, then the grey pairs in order.

A recording has one :class:`FrameSlot` per frame it says it has (a line of ``times.txt``, a video frame, a left
image message of a bag): its number, its time [s] since the first slot, and, when its images are not there, why
(:data:`MISSING_REASONS`) — a dropped frame is a slot without images, never an assumed rate. The times come from
the recording (:func:`check_times`); intervals much longer than the usual one are reported by :func:`time_gaps`.
:meth:`StereoRecording.pairs` yields every slot with its left and right grey images (``None`` when missing).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass

import cv2
import numpy as np

from vehicle_model.errors import InputError

__all__ = ["GAP_FACTOR", "MISSING_REASONS", "FrameSlot", "StereoRecording", "check_times", "grey", "time_gaps"]

MISSING_REASONS: dict[str, str] = {
    "image_missing": "the recording has no left or no right image for this frame (a dropped frame)",
    "no_right_image": "no right image was taken within the pairing tolerance of the left one",
    "video_ended": "a video ended before the timestamp file",
}
"""Why a frame's images are not there, one sentence each."""

GAP_FACTOR = 1.5
"""An interval longer than this many times the median interval is reported as a gap (frames dropped before)."""


@dataclass(frozen=True)
class FrameSlot:
    """One frame of a recording.

    Attributes
    ----------
    index : int
        Its number in the recording (0 first).
    time : float
        Time since the recording's first frame [s].
    missing : str
        Why its images are not there (a key of :data:`MISSING_REASONS`; "" when they are).
    """

    index: int
    time: float
    missing: str = ""


class StereoRecording(ABC):
    """A recorded stereo sequence (module notes).

    Attributes
    ----------
    source : str
        What it is and where, for messages and the run's record.
    slots : tuple of FrameSlot
        Every frame, in time order.
    size : tuple of int
        ``(width, height)`` of its images [px].
    t0 : float
        The first slot's time on the recording's own clock [s] (``times.txt``'s first line, the first header
        stamp): signals and reference files given with a recording are on that clock.
    """

    source: str
    slots: tuple[FrameSlot, ...]
    size: tuple[int, int]
    t0: float = 0.0

    @abstractmethod
    def pairs(self, start: int = 0) -> Iterator[tuple[FrameSlot, np.ndarray | None, np.ndarray | None]]:
        """The slots from number ``start`` on, each with its left and right grey images (``None`` when missing)."""

    @property
    def times(self) -> np.ndarray:
        """The slots' times [s]."""
        return np.array([s.time for s in self.slots], dtype=float)


def grey(image: np.ndarray) -> np.ndarray:
    """An 8-bit grey image from a grey, BGR or BGRA one (``cv2.cvtColor``); 16-bit images are scaled to 8 bits."""
    if image.dtype == np.uint16:
        image = (image >> 8).astype(np.uint8)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        image = cv2.cvtColor(image, code)
    return np.ascontiguousarray(image, dtype=np.uint8)


def check_times(times: np.ndarray, where: str) -> np.ndarray:
    """The times [s] relative to the first, checked: finite and strictly increasing.

    Raises
    ------
    InputError
        ``where`` named, with the first bad line (1-based) and its value.
    """
    times = np.asarray(times, dtype=float).ravel()
    if times.size == 0:
        raise InputError(f"{where}: no timestamps")
    bad = np.flatnonzero(~np.isfinite(times))
    if bad.size:
        raise InputError(f"{where}: line {bad[0] + 1} is {times[bad[0]]!r}; allowed: finite times in seconds")
    back = np.flatnonzero(np.diff(times) <= 0.0)
    if back.size:
        k = int(back[0]) + 1
        raise InputError(
            f"{where}: line {k + 1} ({times[k]:.9g} s) does not come after line {k} ({times[k - 1]:.9g} s); "
            "allowed: strictly increasing times"
        )
    return times - times[0]


def time_gaps(times: np.ndarray) -> list[tuple[int, float, float]]:
    """``(slot, interval, median interval)`` for every slot whose interval since the one before exceeds
    :data:`GAP_FACTOR` times the median interval [s] (frames were dropped before it)."""
    times = np.asarray(times, dtype=float)
    if times.size < 3:
        return []
    dt = np.diff(times)
    median = float(np.median(dt))
    return [
        (int(k) + 1, float(dt[k]), median) for k in np.flatnonzero(dt > GAP_FACTOR * median) if math.isfinite(median)
    ]
