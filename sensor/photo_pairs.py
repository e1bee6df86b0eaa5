"""Which photos form the views of a stereo calibration, and whether they are images of one size.

:func:`stereo_pairs` finds the left and right photo of each view in one folder (``left01.jpg`` / ``right01.jpg``,
or sub-folders ``left/`` and ``right/`` or ``image_0/`` and ``image_1/``) or from two glob patterns; partners are
found by name (the file name with ``left``/``right`` taken out), else in sorted order. :func:`check_images` reads
every photo whole before any work (its structure and all its pixels: a truncated file of any format is refused);
:func:`check_photo_size` refuses photos too small for the board. Each failure is one
:class:`~vehicle_model.errors.InputError` naming the files.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

from vehicle_model.errors import InputError

__all__ = [
    "IMAGE_SUFFIXES",
    "MIN_PHOTO_SIDE",
    "MIN_SQUARE_PX",
    "check_images",
    "check_photo_size",
    "smallest_photo",
    "stereo_pairs",
]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")
"""File suffixes taken as photos (case-insensitive)."""
MIN_SQUARE_PX = 4
"""Fewest pixels a square of the board must span for its corners to be found: a corner's ``cornerSubPix`` window
(at least 2 px each side, :func:`sensor.board_calibration.corner_window_for`) must not reach the next corner."""
MIN_PHOTO_SIDE = 16
"""Shortest photo side [px]: ``cv2.findChessboardCorners`` thresholds with a block of a tenth of the shorter side,
which must be 3 px or more (an odd size above 1)."""

_SIDE = re.compile(r"left|right", re.IGNORECASE)


def _images_in(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)


def _key(path: Path) -> str:
    """The file name with its first ``left``/``right`` taken out (``left01.jpg`` → ``01.jpg``)."""
    return _SIDE.sub("", path.name, count=1).lower()


def _pair(left: list[Path], right: list[Path], what: str) -> list[tuple[Path, Path]]:
    """Partners by name (:func:`_key`), else in sorted order when the counts agree."""
    if not left and not right:
        raise InputError(f"{what}: no images found (allowed suffixes: {', '.join(IMAGE_SUFFIXES)})")
    if not left or not right:
        side, files = ("left", right) if not left else ("right", left)
        raise InputError(
            f"{what}: no {side} images found for {len(files)} {'right' if side == 'left' else 'left'} ones"
        )
    lkeys = {_key(p): p for p in left}
    rkeys = {_key(p): p for p in right}
    if len(lkeys) == len(left) and len(rkeys) == len(right) and (set(lkeys) & set(rkeys)):
        alone = sorted(
            [lkeys[k].name for k in set(lkeys) - set(rkeys)] + [rkeys[k].name for k in set(rkeys) - set(lkeys)]
        )
        if alone:
            raise InputError(
                f"{what}: left/right count mismatch ({len(left)} left, {len(right)} right); without a partner: "
                + ", ".join(alone[:10])
                + (f" (and {len(alone) - 10} more)" if len(alone) > 10 else "")
            )
        return [(lkeys[k], rkeys[k]) for k in sorted(lkeys)]
    if len(left) != len(right):
        more, extra = ("left", left[len(right) :]) if len(left) > len(right) else ("right", right[len(left) :])
        raise InputError(
            f"{what}: left/right count mismatch ({len(left)} left, {len(right)} right); the names do not pair them, "
            f"and in sorted order these {more} images have no partner: " + ", ".join(p.name for p in extra[:10])
        )
    return list(zip(left, right, strict=True))


def stereo_pairs(
    images: Path | None = None, left: str | None = None, right: str | None = None
) -> list[tuple[Path, Path]]:
    """The (left, right) photo pairs of the views (module notes, step 1).

    Parameters
    ----------
    images : Path, optional
        A folder holding ``left*``/``right*`` photos, or sub-folders ``left/`` and ``right/`` (or ``image_0/`` and
        ``image_1/``).
    left, right : str, optional
        Glob patterns of the left and the right photos (instead of ``images``), e.g. ``"calib/left*.png"``.

    Raises
    ------
    InputError
        No folder or no images, both or neither of ``images`` and the patterns, a photo without a partner.
    """
    if images is not None and (left is not None or right is not None):
        raise InputError("give either --images DIR or --left GLOB --right GLOB, not both")
    if images is not None:
        folder = Path(images)
        if not folder.is_dir():
            raise InputError(f"--images {folder}: not a folder")
        for a, b in (("left", "right"), ("image_0", "image_1")):
            if (folder / a).is_dir() and (folder / b).is_dir():
                return _pair(_images_in(folder / a), _images_in(folder / b), f"--images {folder}")
        sides: dict[str, list[Path]] = {"left": [], "right": []}
        for path in _images_in(folder):
            if (side := _SIDE.search(path.name)) is not None:
                sides[side.group().lower()].append(path)
        return _pair(sides["left"], sides["right"], f"--images {folder}")
    if left is None or right is None:
        raise InputError("give --images DIR, or both --left GLOB and --right GLOB")

    def glob(pattern: str, option: str) -> list[Path]:
        base = Path(pattern)
        anchor = Path(base.anchor) if base.is_absolute() else Path(".")
        relative = str(base.relative_to(base.anchor)) if base.is_absolute() else pattern
        found = sorted(p for p in anchor.glob(relative) if p.is_file())
        if not found:
            raise InputError(f"{option} {pattern!r}: matches no file")
        return found

    return _pair(glob(left, "--left"), glob(right, "--right"), "--left/--right")


def check_images(pairs: Sequence[tuple[Path, Path]]) -> tuple[int, int]:
    """Every photo is an image and all have one size; return it ``(width, height)`` (module notes, step 2).

    Each file's structure is verified and its pixels decoded to the end (Pillow), so a truncated or corrupt photo
    of any format is refused here, not later taken for a view without the board.

    Raises
    ------
    InputError
        One line naming the files that are not whole images, or the sizes found and the files of the odd ones
        out.
    """
    from PIL import Image

    sizes: dict[tuple[int, int], list[str]] = {}
    bad: list[str] = []
    for path in (p for pair in pairs for p in pair):
        try:
            with Image.open(path) as im:
                size = (int(im.size[0]), int(im.size[1]))
                im.verify()  # the structure: a PNG's chunks and their checksums
            with Image.open(path) as im:
                im.load()  # the pixels to the end: a truncated JPEG is refused as a truncated PNG is
        except Exception as exc:  # Pillow raises many kinds for a file that is not an image
            bad.append(f"{path} ({type(exc).__name__}: {str(exc)[:60]})")
            continue
        sizes.setdefault(size, []).append(path.name)
    if bad:
        raise InputError(f"cannot read {len(bad)} image(s): " + ", ".join(bad[:5]) + ("; …" if len(bad) > 5 else ""))
    if len(sizes) > 1:
        common = max(sizes, key=lambda s: len(sizes[s]))
        odd = [f"{name} is {w}×{h}" for (w, h), names in sizes.items() if (w, h) != common for name in names]
        raise InputError(
            f"mixed resolutions: {len(sizes[common])} images are {common[0]}×{common[1]} px, but "
            + ", ".join(odd[:10])
            + ("; …" if len(odd) > 10 else "")
            + "; allowed: one size for every photo"
        )
    return next(iter(sizes))


def smallest_photo(cols: int, rows: int) -> tuple[int, int]:
    """The smallest photo ``(long side, short side)`` [px] a board of ``cols`` × ``rows`` inner corners can be found
    in (:data:`MIN_SQUARE_PX` a square, and :data:`MIN_PHOTO_SIDE`)."""
    squares = sorted((cols + 1, rows + 1), reverse=True)
    return (max(MIN_SQUARE_PX * squares[0], MIN_PHOTO_SIDE), max(MIN_SQUARE_PX * squares[1], MIN_PHOTO_SIDE))


def check_photo_size(size: tuple[int, int], cols: int, rows: int, board: str) -> None:
    """Refuse photos too small to hold the board (:func:`smallest_photo`, either way up), before any detection;
    ``board`` names it in the message."""
    long_side, short_side = smallest_photo(cols, rows)
    if max(size) < long_side or min(size) < short_side:
        raise InputError(
            f"the photos are {size[0]}×{size[1]} px; allowed: at least {long_side}×{short_side} px (either way up) "
            f"for the {board}, {MIN_SQUARE_PX} px a square"
        )
