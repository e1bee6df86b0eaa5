"""Side-by-side stereo videos (left | right, H.264 through imageio-ffmpeg) of rendered camera frames."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from vehicle_model.errors import InputError


class StereoVideoWriter:
    """Streams stereo pairs side by side (left | right, 4 px black gap) into an H.264 mp4.

    Parameters
    ----------
    path : str or Path
        Output file.
    fps : float
        Frame rate (the camera rate).
    quality : float
        imageio-ffmpeg quality, 0–10 (10 best).
    """

    GAP = 4

    def __init__(self, path: str | Path, fps: float, quality: float = 7.0) -> None:
        self.path = Path(path)
        self.fps = float(fps)
        self.quality = quality
        self.frames = 0
        self._gen = None
        self._size: tuple[int, int] | None = None

    def append(self, left: np.ndarray, right: np.ndarray) -> None:
        """Add one pair of equally sized grey (or RGB) images."""
        left, right = np.asarray(left), np.asarray(right)
        if left.shape != right.shape:
            raise InputError(f"stereo frames differ in shape: {left.shape} vs {right.shape}")
        if left.ndim == 3:
            import cv2

            left, right = cv2.cvtColor(left, cv2.COLOR_RGB2GRAY), cv2.cvtColor(right, cv2.COLOR_RGB2GRAY)
        h, _w = left.shape
        gap = np.zeros((h, self.GAP), np.uint8)
        frame = np.hstack([left, gap, right])
        # yuv420p needs even sides: pad with black.
        ph, pw = frame.shape[0] % 2, frame.shape[1] % 2
        if ph or pw:
            frame = np.pad(frame, ((0, ph), (0, pw)))
        size = (frame.shape[1], frame.shape[0])
        if self._gen is None:
            import imageio_ffmpeg

            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._gen = imageio_ffmpeg.write_frames(
                str(self.path),
                size,
                fps=self.fps,
                codec="libx264",
                pix_fmt_in="gray",
                pix_fmt_out="yuv420p",
                quality=self.quality,
                macro_block_size=1,
                ffmpeg_log_level="error",
            )
            self._gen.send(None)
            self._size = size
        elif size != self._size:
            raise InputError(f"video frames must keep one size: {size} vs {self._size}")
        self._gen.send(np.ascontiguousarray(frame, dtype=np.uint8))
        self.frames += 1

    def close(self) -> None:
        """Finish the file."""
        if self._gen is not None:
            self._gen.close()
            self._gen = None


def write_video(
    path: str | Path, frames_left: Iterable[np.ndarray], frames_right: Iterable[np.ndarray], fps: float
) -> int:
    """Write a side-by-side stereo video (mp4, H.264).

    Parameters
    ----------
    path : str or Path
        Output file (``.mp4``).
    frames_left, frames_right : iterable of numpy.ndarray
        Equally many grey uint8 images of one size (iterables are consumed lazily).
    fps : float
        Frame rate [1/s].

    Returns
    -------
    int
        Frames written.
    """
    writer = StereoVideoWriter(path, fps)
    try:
        for left, right in zip(frames_left, frames_right, strict=True):
            writer.append(left, right)
    finally:
        writer.close()
    return writer.frames
