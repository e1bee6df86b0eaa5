"""A stereo recording as two video files and a timestamp file (one time per frame [s]).

Frame ``k`` is the ``k``-th frame of each video and line ``k + 1`` of the timestamp file; the videos are decoded
by OpenCV (``cv2.VideoCapture``, its bundled FFmpeg) and turned grey. Before any work each video is opened and its
first frame decoded, the two must have one frame size, and their frame counts (as the container states them) must
not fall short of the timestamp file by more than a frame; a video that ends early leaves its last slots without
images (``video_ended``). A lossless codec (FFV1, PNG) keeps the images the camera took; a lossy one (H.264) adds
its own artefacts to the odometry's matching.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from vehicle_model.errors import InputError

from .kitti import read_times
from .sequence import FrameSlot, StereoRecording, grey

__all__ = ["VideoPair"]


def _open(path: Path) -> tuple[int, tuple[int, int]]:
    """Frame count (as the container says) and size of a video, checked by decoding its first frame."""
    if not path.is_file():
        raise InputError(f"{path}: not found; allowed: a video file OpenCV can read (mp4, mkv, avi, …)")
    capture = cv2.VideoCapture(str(path))
    try:
        ok, frame = capture.read() if capture.isOpened() else (False, None)
        if not ok or frame is None:
            raise InputError(f"{path}: OpenCV cannot decode a frame of it; allowed: a video file (mp4, mkv, avi, …)")
        count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
        return count, (int(frame.shape[1]), int(frame.shape[0]))
    finally:
        capture.release()


class VideoPair(StereoRecording):
    """Two videos and their timestamps (module notes), checked when made.

    Parameters
    ----------
    left, right : Path
        The left and right camera's videos.
    times : Path
        One time per frame [s].
    """

    def __init__(self, left: Path, right: Path, times: Path) -> None:
        self.left, self.right = Path(left), Path(right)
        t, self.t0 = read_times(Path(times))
        (n_left, size_left), (n_right, size_right) = _open(self.left), _open(self.right)
        if size_left != size_right:
            raise InputError(
                f"{self.right}: frames are {size_right[0]}×{size_right[1]} px, {self.left}'s "
                f"{size_left[0]}×{size_left[1]} px; allowed: one size for both cameras"
            )
        for path, n in ((self.left, n_left), (self.right, n_right)):
            if 0 < n < len(t) - 1:
                raise InputError(
                    f"{path}: {n} frames for {len(t)} timestamps in {times}; allowed: one timestamp per frame"
                )
        self.size = size_left
        self.source = f"videos {self.left} and {self.right}"
        self.slots = tuple(FrameSlot(k, float(v)) for k, v in enumerate(t))

    def pairs(self, start: int = 0) -> Iterator[tuple[FrameSlot, np.ndarray | None, np.ndarray | None]]:
        """The slots from ``start`` on with their grey frames (decoded in order; ``video_ended`` past the end)."""
        captures = [cv2.VideoCapture(str(p)) for p in (self.left, self.right)]
        try:
            for capture in captures:
                if start:
                    capture.set(cv2.CAP_PROP_POS_FRAMES, start)
            ended = False
            for slot in self.slots[start:]:
                frames = [] if ended else [c.read() for c in captures]
                if ended or not all(ok for ok, _ in frames):
                    ended = True
                    yield FrameSlot(slot.index, slot.time, "video_ended"), None, None
                    continue
                yield slot, grey(frames[0][1]), grey(frames[1][1])
        finally:
            for capture in captures:
                capture.release()
