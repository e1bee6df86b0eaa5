"""A KITTI-odometry folder (Geiger, Lenz & Urtasun 2012): ``image_0/``, ``image_1/``, ``calib.txt``, ``times.txt``.

The layout ``offtrack render`` writes (:mod:`scenarios.export.kitti`) and the KITTI odometry benchmark's:

    image_0/000000.png …   left camera, grey
    image_1/000000.png …   right camera
    calib.txt              P0, P1 (3×4, row-major) of the rectified pair (optional with a calibration file)
    times.txt              one time per frame [s]
    poses.txt              optional: the left camera's pose per frame in the first one's frame (3×4)

Frame ``k`` is line ``k + 1`` of ``times.txt`` and the images numbered ``k``; a frame whose image is absent in
either folder is a dropped frame (:data:`~sensor.recordings.sequence.MISSING_REASONS`). Before any work the folder
is checked: the folders and ``times.txt`` exist, the times increase, no image lies beyond ``times.txt``, every image
is readable and all have one size, and ``calib.txt`` describes a rectified pair (:func:`read_kitti_calib`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from vehicle_model.errors import InputError

from .sequence import FrameSlot, StereoRecording, check_times, grey

__all__ = ["KittiFolder", "RectifiedCamera", "check_image_files", "read_kitti_calib", "read_times"]

_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm")


@dataclass(frozen=True)
class RectifiedCamera:
    """The camera model of a rectified pair: focal length and principal point [px], baseline [m].

    From KITTI's ``P0 = K·[I | 0]`` and ``P1 = K·[I | −b·e_x]``: ``f = P0[0, 0]``, ``(cu, cv) = (P0[0, 2], P0[1, 2])``,
    ``b = −P1[0, 3] / P1[0, 0]`` (Geiger, Lenz & Urtasun 2012, the devkit's calibration).
    """

    f: float
    cu: float
    cv: float
    baseline: float

    def vo_config(self, **overrides: Any) -> Any:
        """A :class:`sensor.vo.VOConfig` of this camera (other fields from ``overrides``)."""
        from sensor.vo import VOConfig

        return VOConfig(f=self.f, cu=self.cu, cv=self.cv, baseline=self.baseline, **overrides)


def read_kitti_calib(path: Path) -> RectifiedCamera:
    """The rectified camera of a KITTI ``calib.txt`` (P0 and P1 needed; P2, P3, Tr ignored).

    Raises
    ------
    InputError
        The file is missing or unreadable, P0 or P1 is missing or not 12 numbers, or they are not a rectified pair
        (the same K, the right camera on the +x axis): one line naming the file and the key.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: not found; allowed: a KITTI calib.txt with P0 and P1, or --calibration FILE.yaml")
    rows: dict[str, np.ndarray] = {}
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot be read ({exc})") from None
    for number, line in enumerate(text.splitlines(), 1):
        if ":" not in line:
            continue
        key, values = line.split(":", 1)
        try:
            numbers = np.array([float(v) for v in values.split()])
        except ValueError:
            raise InputError(f"{path}: line {number} ({key.strip()}) holds something other than numbers") from None
        rows[key.strip()] = numbers
    for key in ("P0", "P1"):
        if key not in rows:
            raise InputError(f"{path}: has no {key}; allowed: KITTI's P0 and P1 of a rectified pair (12 numbers each)")
        if rows[key].size != 12 or not np.all(np.isfinite(rows[key])):
            raise InputError(f"{path}: {key} has {rows[key].size} numbers; allowed: 12 finite numbers (3×4, row-major)")
    p0, p1 = rows["P0"].reshape(3, 4), rows["P1"].reshape(3, 4)
    same_k = np.allclose(p0[:, :3], p1[:, :3], rtol=1e-9, atol=1e-9)
    if not same_k or np.any(np.abs(p0[:, 3]) > 1e-9) or abs(p1[1, 3]) > 1e-9 or abs(p1[2, 3]) > 1e-9:
        raise InputError(
            f"{path}: P0 and P1 are not a rectified pair; allowed: P0 = K·[I | 0] and P1 = K·[I | −b·e_x] with one K"
        )
    f = float(p0[0, 0])
    baseline = float(-p1[0, 3] / p1[0, 0]) if p1[0, 0] else math.nan
    if not (f > 0 and p0[1, 1] > 0 and baseline > 0 and p0[0, 2] > 0 and p0[1, 2] > 0):
        raise InputError(
            f"{path}: focal length {f:g} px, principal point ({p0[0, 2]:g}, {p0[1, 2]:g}) px, baseline "
            f"{baseline:g} m; allowed: all positive (P1[0, 3] = −f·b < 0)"
        )
    return RectifiedCamera(f, float(p0[0, 2]), float(p0[1, 2]), baseline)


def read_times(path: Path) -> tuple[np.ndarray, float]:
    """A ``times.txt`` (one time per line [s]) relative to its first line, checked (:func:`check_times`), and the
    first line's time."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: not found; allowed: a file with one time per frame [s]")
    try:
        lines = [line.split()[0] for line in path.read_text().splitlines() if line.strip()]
        times = np.array([float(v) for v in lines], dtype=float)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: cannot be read as one time per line ({exc})") from None
    return check_times(times, str(path)), float(times[0])


def _numbered(folder: Path) -> dict[int, Path]:
    out: dict[int, Path] = {}
    for path in folder.iterdir():
        if path.is_file() and path.suffix.lower() in _SUFFIXES and path.stem.isdigit():
            out[int(path.stem)] = path
    return out


def check_image_files(paths: list[Path]) -> tuple[int, int] | None:
    """Every file is a readable image and all have one size; the size ``(width, height)`` (None: no files).

    Pillow reads each header and verifies the file's structure without decoding its pixels.

    Raises
    ------
    InputError
        One line naming the first unreadable file, or the sizes found and an odd file.
    """
    from PIL import Image

    sizes: dict[tuple[int, int], Path] = {}
    for path in paths:
        try:
            with Image.open(path) as im:
                size = (int(im.size[0]), int(im.size[1]))
                im.verify()
        except Exception as exc:  # Pillow raises many kinds for a file that is not an image
            raise InputError(f"{path}: unreadable image ({type(exc).__name__}: {exc})") from None
        sizes.setdefault(size, path)
    if len(sizes) > 1:
        (a, pa), (b, pb) = list(sizes.items())[:2]
        raise InputError(
            f"mixed image sizes: {pa} is {a[0]}×{a[1]} px, {pb} is {b[0]}×{b[1]} px; allowed: one size for every image"
        )
    return next(iter(sizes)) if sizes else None


class KittiFolder(StereoRecording):
    """A KITTI-odometry folder (module notes), checked when made.

    Parameters
    ----------
    folder : Path
        The sequence's folder.

    Attributes
    ----------
    camera : RectifiedCamera or None
        From ``calib.txt`` (None when the folder has none).
    poses_file : Path or None
        ``poses.txt`` when the folder has one.
    """

    def __init__(self, folder: Path) -> None:
        folder = Path(folder)
        if not folder.is_dir():
            raise InputError(f"{folder}: not found; allowed: a KITTI-odometry folder (image_0/, image_1/, times.txt)")
        for sub in ("image_0", "image_1"):
            if not (folder / sub).is_dir():
                raise InputError(
                    f"{folder}: has no {sub}/ folder; allowed: a KITTI-odometry folder (image_0/, image_1/)"
                )
        times, self.t0 = read_times(folder / "times.txt")
        left, right = _numbered(folder / "image_0"), _numbered(folder / "image_1")
        beyond = sorted(k for k in set(left) | set(right) if k >= len(times))
        if beyond:
            raise InputError(
                f"{folder}: image {beyond[0]:06d} lies beyond the {len(times)} lines of times.txt; "
                "allowed: a line per frame"
            )
        present = sorted(set(left) & set(right))
        if not present:
            raise InputError(f"{folder}: image_0/ and image_1/ hold no numbered image pair (000000.png, …)")
        self.size = check_image_files([p for k in present for p in (left[k], right[k])])  # type: ignore[assignment]
        self.folder = folder
        self.source = f"KITTI folder {folder}"
        self._left, self._right = left, right
        self.slots = tuple(
            FrameSlot(k, float(t), "" if (k in left and k in right) else "image_missing") for k, t in enumerate(times)
        )
        calib = folder / "calib.txt"
        self.camera = read_kitti_calib(calib) if calib.is_file() else None
        self.poses_file = folder / "poses.txt" if (folder / "poses.txt").is_file() else None

    def pairs(self, start: int = 0) -> Iterator[tuple[FrameSlot, np.ndarray | None, np.ndarray | None]]:
        """The slots from ``start`` on with their grey images (``cv2.imread``)."""
        for slot in self.slots[start:]:
            if slot.missing:
                yield slot, None, None
                continue
            images = []
            for path in (self._left[slot.index], self._right[slot.index]):
                image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
                if image is None:
                    raise InputError(f"{path}: OpenCV cannot decode it")
                images.append(grey(image))
            yield slot, images[0], images[1]
