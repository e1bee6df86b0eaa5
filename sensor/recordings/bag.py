"""A stereo recording in a ROS 1 or ROS 2 bag: two image topics, read with ``rosbags`` and ``rosbags-image``.

``rosbags.highlevel.AnyReader`` opens a ROS 1 ``.bag`` or a ROS 2 bag folder (SQLite or MCAP) and deserialises the
messages; ``rosbags.image.message_to_cvimage`` turns a ``sensor_msgs/Image`` or ``CompressedImage`` into an OpenCV
image. A frame's time is its left message's header stamp; each left image is paired with the right image whose
stamp is nearest, within a tolerance (default a quarter of the median left interval): a left image without one is a
slot without images (``no_right_image``), a right image without a left one is not a frame. Before any work the bag
is opened, both topics must exist and carry images, the stamps must be distinct, and the first left image is decoded
for the frame size.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from vehicle_model.errors import InputError

from .sequence import FrameSlot, StereoRecording, check_times, grey

__all__ = ["IMAGE_TYPES", "BagPair", "is_bag"]

IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
"""Message types read as images (rosbags names ROS 1 types the same way)."""


def is_bag(path: Path) -> bool:
    """Whether ``path`` looks like a bag: a ``.bag`` file (ROS 1), or a folder with a ``metadata.yaml`` (ROS 2), or
    a ``.db3``/``.mcap`` file."""
    path = Path(path)
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix.lower() in (".bag", ".db3", ".mcap")


def _stamp_ns(message: Any) -> int:
    stamp = message.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


class BagPair(StereoRecording):
    """Two image topics of a bag (module notes), checked when made.

    Parameters
    ----------
    path : Path
        A ROS 1 ``.bag`` file or a ROS 2 bag folder.
    left_topic, right_topic : str
        The left and right cameras' image topics.
    tolerance : float, optional
        Largest stamp difference of a left and a right image of one frame [s] (default: a quarter of the median
        left interval).
    """

    def __init__(self, path: Path, left_topic: str, right_topic: str, tolerance: float | None = None) -> None:
        self.path = Path(path)
        self.topics = (left_topic, right_topic)
        if not self.path.exists():
            raise InputError(f"{self.path}: not found; allowed: a ROS 1 .bag file or a ROS 2 bag folder")
        stamps: dict[str, list[int]] = {left_topic: [], right_topic: []}
        first: np.ndarray | None = None
        with self._reader() as reader:
            connections = self._connections(reader)
            for connection, _, raw in reader.messages(connections=connections):
                message = reader.deserialize(raw, connection.msgtype)
                stamps[connection.topic].append(_stamp_ns(message))
                if first is None and connection.topic == left_topic:
                    first = self._image(message)
        left, right = (np.array(sorted(stamps[t]), dtype=np.int64) for t in self.topics)
        for topic, values in ((left_topic, left), (right_topic, right)):
            if values.size == 0:
                raise InputError(f"{self.path}: topic {topic} has no message")
            if np.any(np.diff(values) == 0):
                raise InputError(f"{self.path}: topic {topic} has two images with one header stamp")
        times = check_times((left - left[0]) * 1e-9, f"{self.path} {left_topic} header stamps")
        self.t0 = float(left[0]) * 1e-9
        interval = float(np.median(np.diff(times))) if times.size > 1 else 0.0
        limit = tolerance if tolerance is not None else 0.25 * interval
        if not (limit >= 0.0):
            raise InputError(f"--pair-tolerance {tolerance!r}: allowed: a time ≥ 0 s")
        nearest = np.clip(np.searchsorted(right, left), 1, max(right.size - 1, 1))
        candidates = np.stack([right[nearest - 1], right[np.minimum(nearest, right.size - 1)]])
        best = candidates[np.argmin(np.abs(candidates - left), axis=0), np.arange(left.size)]
        paired = np.abs(best - left) <= round(limit * 1e9)
        self._left_slot = {int(s): k for k, s in enumerate(left)}
        self._right_slot = {int(best[k]): k for k in np.flatnonzero(paired)}
        assert first is not None
        self.size = (int(first.shape[1]), int(first.shape[0]))
        self.source = f"bag {self.path} ({left_topic}, {right_topic})"
        self.slots = tuple(
            FrameSlot(k, float(t), "" if ok else "no_right_image")
            for k, (t, ok) in enumerate(zip(times, paired, strict=True))
        )

    @contextlib.contextmanager
    def _reader(self) -> Iterator[Any]:
        """The bag opened with ``rosbags.highlevel.AnyReader`` (closed after the block)."""
        from rosbags.highlevel import AnyReader

        try:
            reader = AnyReader([self.path])
            reader.open()
        except Exception as exc:  # rosbags raises its own errors for a file that is not a bag
            raise InputError(
                f"{self.path}: cannot be read as a ROS 1 or ROS 2 bag ({type(exc).__name__}: {exc})"
            ) from None
        try:
            yield reader
        finally:
            reader.close()

    def _connections(self, reader: Any) -> list[Any]:
        found = [c for c in reader.connections if c.topic in self.topics]
        for topic in self.topics:
            mine = [c for c in found if c.topic == topic]
            if not mine:
                images = sorted({c.topic for c in reader.connections if c.msgtype in IMAGE_TYPES})
                raise InputError(f"{self.path}: has no topic {topic}; its image topics: {', '.join(images) or 'none'}")
            if any(c.msgtype not in IMAGE_TYPES for c in mine):
                raise InputError(
                    f"{self.path}: topic {topic} carries {mine[0].msgtype}; allowed: {', '.join(IMAGE_TYPES)}"
                )
        return found

    def _image(self, message: Any) -> np.ndarray:
        from rosbags.image import message_to_cvimage

        try:
            return grey(np.asarray(message_to_cvimage(message)))
        except Exception as exc:  # rosbags-image raises its own errors for an encoding it cannot convert
            raise InputError(f"{self.path}: an image cannot be converted ({type(exc).__name__}: {exc})") from None

    def pairs(self, start: int = 0) -> Iterator[tuple[FrameSlot, np.ndarray | None, np.ndarray | None]]:
        """The slots from ``start`` on with their grey images, in stamp order (the bag is read once, in its order)."""
        left_images: dict[int, np.ndarray] = {}
        right_images: dict[int, np.ndarray] = {}
        wanted = {slot.index for slot in self.slots[start:] if not slot.missing}
        upcoming = list(self.slots[start:])

        def ready() -> Iterator[tuple[FrameSlot, np.ndarray | None, np.ndarray | None]]:
            while upcoming:
                slot = upcoming[0]
                if slot.missing:
                    yield upcoming.pop(0), None, None
                elif slot.index in left_images and slot.index in right_images:
                    yield upcoming.pop(0), left_images.pop(slot.index), right_images.pop(slot.index)
                else:
                    return

        with self._reader() as reader:
            for connection, _, raw in reader.messages(connections=self._connections(reader)):
                message = reader.deserialize(raw, connection.msgtype)
                stamp = _stamp_ns(message)
                table, store = (
                    (self._left_slot, left_images)
                    if connection.topic == self.topics[0]
                    else (self._right_slot, right_images)
                )
                slot = table.get(stamp)
                if slot is not None and slot in wanted:
                    store[slot] = self._image(message)
                yield from ready()
        yield from ready()
        for slot in upcoming:  # stamps paired when read but whose images never came (cannot happen in one bag)
            yield FrameSlot(slot.index, slot.time, "image_missing"), None, None
