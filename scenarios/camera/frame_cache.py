"""A directory of developed stereo frames: a camera's :class:`~sensor.stereo_camera.FrameStore` on disk.

A camera built with a frame cache (:func:`.build.stereo_camera`, ``frame_cache=``) keeps each frame it develops
(:meth:`sensor.stereo_camera.StereoCamera.pair`) in ``DIRECTORY/TAG/NNNNNN.npz`` and, when a later run takes the same
frame at the same pose and mount flex, reads it back instead of rendering it. ``TAG`` names the camera (its
configuration, rig, world and vehicle, :func:`.build.camera_tag`), so one directory serves several scenarios; a stored
frame of another pose or flex is rendered again and replaced. ``OFFTRACK_FRAME_CACHE`` sets the directory of every
camera run that is not given one (:func:`frame_cache_from_env`). The key holds the camera and its settings and
:data:`FRAME_REVISION`, not the renderer's code itself: a change to what a camera sees under the same settings raises
the revision, so that no cache serves frames the current code would not render.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from sensor.camera import Misalignment
from sensor.stereo_camera import CachedPair
from vehicle_model.geometry import ChainPose, CombinationPose, chain_pose

__all__ = ["FRAME_CACHE_ENV", "FRAME_REVISION", "FrameCache", "frame_cache_from_env"]

FRAME_CACHE_ENV = "OFFTRACK_FRAME_CACHE"
"""Environment variable naming the frame cache directory of camera runs (unset or empty: none)."""

FRAME_REVISION = 2
"""The revision of what the world, its lighting and the renderer draw for a given camera description, part of every
frame's key (:func:`.build.camera_tag`): raised with any change to the rendered images of an unchanged configuration."""


def frame_cache_from_env() -> Path | None:
    """The directory ``OFFTRACK_FRAME_CACHE`` names, or ``None`` when it is unset or empty."""
    value = os.environ.get(FRAME_CACHE_ENV, "").strip()
    return Path(value) if value else None


def _key(pose: CombinationPose | ChainPose, right_rotation: Misalignment | None) -> np.ndarray:
    """The pose (every unit's: the other units are drawn) and the flex of a frame as one float64 vector (the flex NaN
    when there is none); the rig is in the cache's tag."""
    flex = (np.nan,) * 3 if right_rotation is None else (right_rotation.roll, right_rotation.pitch, right_rotation.yaw)
    full = chain_pose(pose)
    values = (full.x, full.y, full.psi1, *full.angles, *flex)
    return np.array([float(v) for v in values], dtype=np.float64)


class FrameCache:
    """Developed frames of one camera in ``directory / tag``, one ``.npz`` per frame number.

    Parameters
    ----------
    directory : Path
        The cache's root (created on the first frame saved).
    tag : str
        Names the camera (:func:`.build.camera_tag`): frames of other cameras are never taken for its own.
    """

    def __init__(self, directory: Path, tag: str) -> None:
        self.directory = Path(directory) / tag
        self.loaded = 0
        self.saved = 0

    def _file(self, frame: int) -> Path:
        return self.directory / f"{int(frame):06d}.npz"

    def load(
        self, frame: int, pose: CombinationPose | ChainPose, right_rotation: Misalignment | None
    ) -> CachedPair | None:
        """The stored frame ``frame`` if it was taken at exactly this pose and flex, else ``None``."""
        path = self._file(frame)
        if not path.is_file():
            return None
        with np.load(path) as data:
            if not np.array_equal(data["key"], _key(pose, right_rotation), equal_nan=True):
                return None
            pair = CachedPair(data["left"], data["right"], float(data["metered"]))
        self.loaded += 1
        return pair

    def save(
        self, frame: int, pose: CombinationPose | ChainPose, right_rotation: Misalignment | None, pair: CachedPair
    ) -> None:
        """Keep frame ``frame`` (written whole to a temporary file first, so a reader never sees half a frame)."""
        self.directory.mkdir(parents=True, exist_ok=True)
        path = self._file(frame)
        tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npz")
        np.savez(tmp, key=_key(pose, right_rotation), left=pair.left, right=pair.right, metered=pair.metered)
        tmp.replace(path)
        self.saved += 1

    def __len__(self) -> int:
        """Frames stored."""
        return len(list(self.directory.glob("[0-9]" * 6 + ".npz"))) if self.directory.is_dir() else 0
