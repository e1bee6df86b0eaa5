"""Stereo calibration from photos of a checkerboard or ChArUco board, with a residual report per view (OpenCV).

The simulated calibration (:mod:`sensor.calibration`) images a target it renders itself; this module takes a real
camera pair's photos of a printed board and solves the same way (de Saxe & Cebon 2018, §4.1: Zhang's method with
Heikkilä's distortion model, then the pair, all with OpenCV):

1. **Pairs** (:func:`sensor.photo_pairs.stereo_pairs`): the left and right photos of each view.
2. **Checks before any work** (:func:`check_options`, :func:`sensor.photo_pairs.check_images`,
   :func:`sensor.photo_pairs.check_photo_size`): the settings are in range, every file is a whole image (decoded in
   full, so a truncated JPEG is refused as a truncated PNG is), all have one size large enough for the board, and
   each left photo has a right partner — each failure is one :class:`~vehicle_model.errors.InputError` naming the
   files.
3. **Detection** (:func:`detect_view`): a checkerboard by ``cv2.findChessboardCorners`` (``findChessboardCornersSB``
   as a fallback) and ``cv2.cornerSubPix`` with a window fitted to each corner (:func:`corner_windows`), the right
   photo's corners put in the left one's order (a checkerboard's corner list may start at either end); a ChArUco
   board by ``cv2.aruco.CharucoDetector``, keeping the corners both photos see (by their ids).
4. **Solve** (:func:`calibrate_views`): ``cv2.calibrateCamera`` per camera (first with k3 fixed, then k3 freed from
   there, as :mod:`sensor.calibration`), ``cv2.stereoCalibrate`` with the intrinsics fixed, ``cv2.stereoRectify``
   (zero disparity at infinity; Fusiello et al. 2000 / Bouguet).
5. **Outlier views**: a view whose stereo reprojection RMS exceeds :data:`OUTLIER_FACTOR` times the median of the
   views and :data:`OUTLIER_FLOOR_PX` (a blurred photo, a board bent or half in shadow) is rejected and the pair
   solved again without it, once.

The result is a :class:`sensor.calibration.CalibrationResult`, so it writes the OpenCV YAML a run and
``offtrack estimate`` load; :class:`PhotoCalibration` adds each view's record (used or rejected, why, its RMS).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np

from sensor.calibration import CalibrationResult, one_opencv_thread, solve_stereo_calibration
from sensor.calibration_target import Board
from sensor.photo_pairs import check_images, check_photo_size
from vehicle_model.errors import InputError

__all__ = [
    "MIN_CHARUCO_CORNERS",
    "OUTLIER_FACTOR",
    "OUTLIER_FLOOR_PX",
    "BoardPattern",
    "PhotoCalibration",
    "ViewRecord",
    "calibrate_photos",
    "calibrate_views",
    "check_options",
    "corner_window_for",
    "corner_windows",
    "detect_view",
    "refine_corners",
]

MIN_CHARUCO_CORNERS = 6
"""Fewest ChArUco corners both photos of a view must share: a plane's homography needs 4, 6 leave some redundancy."""
OUTLIER_FACTOR = 3.0
"""A view whose stereo RMS exceeds this many times the median view's (and :data:`OUTLIER_FLOOR_PX`) is rejected."""
OUTLIER_FLOOR_PX = 1.0
"""… and is at least this large [px]: corners found to a pixel are not outliers however sharp the other views are."""


@dataclass(frozen=True)
class BoardPattern:
    """The printed board.

    Parameters
    ----------
    kind : {"chessboard", "charuco"}
        A plain checkerboard, or a ChArUco board (a checkerboard with ArUco markers in its white squares).
    cols, rows : int
        Inner corners along a row and along a column (a ChArUco board of ``cols + 1`` × ``rows + 1`` squares).
    square : float
        Side of a square [m].
    marker : float, optional
        Side of a ChArUco marker [m] (default 0.75 of the square).
    dictionary : str
        The ArUco dictionary of a ChArUco board, an OpenCV name (``DICT_4X4_50``, ``DICT_5X5_100``, …).
    """

    kind: Literal["chessboard", "charuco"] = "chessboard"
    cols: int = 9
    rows: int = 6
    square: float = 0.025
    marker: float | None = None
    dictionary: str = "DICT_4X4_50"

    def __post_init__(self) -> None:
        if self.kind not in ("chessboard", "charuco"):
            raise InputError(f"--pattern {self.kind!r}: allowed: chessboard or charuco")
        Board(self.cols, self.rows, self.square)  # corners 3–30 each and different, square 5 mm–1 m
        if self.kind == "charuco":
            if not hasattr(cv2.aruco, self.dictionary) or not self.dictionary.startswith("DICT_"):
                raise InputError(
                    f"--dictionary {self.dictionary!r}: allowed: an OpenCV ArUco dictionary, e.g. DICT_4X4_50"
                )
            if not (0.0 < self.marker_side < self.square):
                raise InputError(f"--marker {self.marker_side!r} m: allowed: a marker side in (0, {self.square}) m")

    @property
    def marker_side(self) -> float:
        """The ChArUco marker's side [m]."""
        return 0.75 * self.square if self.marker is None else float(self.marker)

    @property
    def label(self) -> str:
        """``chessboard 9×6 inner corners, 25.0 mm squares`` (for messages)."""
        return f"{self.kind} {self.cols}×{self.rows} inner corners, {1e3 * self.square:.1f} mm squares"

    def object_points(self) -> np.ndarray:
        """``(rows·cols, 3)`` inner corners of the checkerboard in the board frame [m], row by row."""
        return Board(self.cols, self.rows, self.square).object_points().astype(np.float64)

    def charuco_board(self) -> Any:
        """``cv2.aruco.CharucoBoard`` of ``cols + 1`` × ``rows + 1`` squares."""
        aruco = cv2.aruco
        dictionary = aruco.getPredefinedDictionary(getattr(aruco, self.dictionary))
        return aruco.CharucoBoard((self.cols + 1, self.rows + 1), self.square, self.marker_side, dictionary)

    def charuco_detector(self) -> Any:
        """``cv2.aruco.CharucoDetector`` of the board."""
        return cv2.aruco.CharucoDetector(self.charuco_board())


@dataclass
class ViewRecord:
    """One view (a left and a right photo) and what became of it.

    Attributes
    ----------
    left, right : Path
        The photos.
    used : bool
        Whether the calibration used the view.
    reason : str
        Why not ("" when used).
    object_points : numpy.ndarray or None
        ``(n, 3)`` board corners seen in both photos [m].
    left_corners, right_corners : numpy.ndarray or None
        ``(n, 2)`` their pixels in each photo.
    rms_left, rms_right : float
        RMS reprojection error of the view in each camera's own calibration [px] (NaN if not used).
    rms_stereo : tuple of float
        (left, right) RMS in the stereo calibration [px] (NaN if not used).
    """

    left: Path
    right: Path
    used: bool = False
    reason: str = ""
    object_points: np.ndarray | None = None
    left_corners: np.ndarray | None = None
    right_corners: np.ndarray | None = None
    rms_left: float = math.nan
    rms_right: float = math.nan
    rms_stereo: tuple[float, float] = (math.nan, math.nan)

    @property
    def corners(self) -> int:
        """Corners seen in both photos (0 when the board was not found)."""
        return 0 if self.object_points is None else len(self.object_points)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready record (files, used, reason, corners, RMS in px)."""
        return {
            "left": str(self.left),
            "right": str(self.right),
            "used": self.used,
            "reason": self.reason,
            "corners": self.corners,
            "rms_left_px": self.rms_left,
            "rms_right_px": self.rms_right,
            "rms_stereo_px": list(self.rms_stereo),
        }


@dataclass
class PhotoCalibration:
    """A stereo calibration from photos: the result and the record of every view.

    Attributes
    ----------
    result : CalibrationResult
        K, distortion, R, T, the rectification and the residuals of the views used (OpenCV YAML via ``write``).
    views : list of ViewRecord
        Every view given, used or rejected with its reason.
    pattern : BoardPattern
        The board.
    image_size : tuple of int
        ``(width, height)`` [px].
    """

    result: CalibrationResult
    views: list[ViewRecord]
    pattern: BoardPattern
    image_size: tuple[int, int]
    notes: list[str] = field(default_factory=list)

    @property
    def used(self) -> list[ViewRecord]:
        """The views the calibration used."""
        return [v for v in self.views if v.used]

    def summary(self) -> dict[str, Any]:
        """The residual report (JSON-ready): RMS per camera and stereo, each view, rejections by reason, K, baseline."""
        r = self.result
        par = r.rectified_rig_parameters()
        rejected: dict[str, int] = {}
        for v in self.views:
            if not v.used:
                key = v.reason.split(":")[0]
                rejected[key] = rejected.get(key, 0) + 1
        return {
            "board": {
                "pattern": self.pattern.kind,
                "inner_corners": [self.pattern.cols, self.pattern.rows],
                "square_m": self.pattern.square,
                **(
                    {"marker_m": self.pattern.marker_side, "dictionary": self.pattern.dictionary}
                    if self.pattern.kind == "charuco"
                    else {}
                ),
            },
            "image_size": list(self.image_size),
            "views_given": len(self.views),
            "views_used": len(self.used),
            "rejected": rejected,
            "rms_px": {"left": r.rms_left, "right": r.rms_right, "stereo": r.rms_stereo},
            "left": _intrinsics(r.k_left, r.dist_left),
            "right": _intrinsics(r.k_right, r.dist_right),
            "baseline_m": float(np.linalg.norm(r.t)),
            "rectified": {"f": par.f, "cu": par.cu, "cv": par.cv, "baseline": par.baseline},
            "views": [v.to_dict() for v in self.views],
        }


def _intrinsics(k: np.ndarray, dist: np.ndarray) -> dict[str, Any]:
    return {
        "fx": float(k[0, 0]),
        "fy": float(k[1, 1]),
        "cx": float(k[0, 2]),
        "cy": float(k[1, 2]),
        "dist": [float(x) for x in np.asarray(dist).ravel()],
    }


# ---------------------------------------------------------------------------------------------------- detection


def _read(path: Path) -> np.ndarray:
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise InputError(f"cannot read image {path}: OpenCV cannot decode it")
    return image


def _same_order(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """The right photo's checkerboard corners in the left photo's order.

    A checkerboard's corner list may start at either end (180° symmetry). The two cameras of a pair look the same
    way, so the first-to-last corner direction is the same in both photos; a reversed list points the other way.
    """
    a = left[-1] - left[0]
    b = right[-1] - right[0]
    return right if float(np.dot(a, b)) >= 0.0 else right[::-1].copy()


def _charuco(image: np.ndarray, detector: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """ChArUco corner ids ``(n,)`` and pixels ``(n, 2)``, or None if none was found."""
    corners, ids, _, _ = detector.detectBoard(image)
    if ids is None or len(ids) == 0:
        return None
    return np.asarray(ids, dtype=int).ravel(), np.asarray(corners, dtype=np.float64).reshape(-1, 2)


def _chessboard(image: np.ndarray, pattern: BoardPattern, corner_window: int | None) -> np.ndarray | None:
    """Checkerboard corners ``(rows·cols, 2)`` in OpenCV's order, or None if not found.

    ``cv2.findChessboardCorners`` (adaptive threshold, normalised), ``cv2.findChessboardCornersSB`` (Duda & Frese
    2018) when it fails, then ``cv2.cornerSubPix`` with a half-window of ``corner_window`` px, by default fitted to
    each corner (:func:`corner_windows`).
    """
    size = (pattern.cols, pattern.rows)
    found, corners = cv2.findChessboardCorners(
        image, size, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    )
    if not found:
        found, corners = cv2.findChessboardCornersSB(image, size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
        if not found:
            return None
    corners = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    if corner_window is None:
        windows = corner_windows(corners, pattern)
    else:
        windows = np.full(len(corners), int(corner_window))
    return refine_corners(image, corners, windows)


def corner_window_for(corners: np.ndarray, pattern: BoardPattern) -> int:
    """``cv2.cornerSubPix``'s half-window for a whole view [px]: a third of its smallest corner spacing, 2–11 px.

    The rule before :func:`corner_windows` (which fits the window to each corner); kept for ``--corner-window``'s
    documentation of what a fixed window does and for comparison.
    """
    grid = np.asarray(corners, dtype=float).reshape(pattern.rows, pattern.cols, 2)
    spacing = min(
        float(np.linalg.norm(np.diff(grid, axis=1), axis=-1).min()),
        float(np.linalg.norm(np.diff(grid, axis=0), axis=-1).min()),
    )
    return int(np.clip(spacing / 3.0, 2, 11))


CORNER_WINDOW_RANGE = (2, 11)
"""Smallest and largest half-window of :func:`corner_windows` [px]."""
EDGE_CLEARANCE_PX = 1.5
"""How far inside the nearest edge that does not pass through a corner its window stops [px] (blur spreads an
edge's gradient over about a pixel each side)."""


def _padded_grid(grid: np.ndarray) -> np.ndarray:
    """The corner grid ``(rows, cols, 2)`` with one more row and column of corners on each side, extrapolated
    linearly: the outer squares' far corners (the board's printed squares beyond the inner corners)."""
    rows, cols, _ = grid.shape
    out = np.empty((rows + 2, cols + 2, 2))
    out[1:-1, 1:-1] = grid
    out[0, 1:-1] = 2.0 * grid[0] - grid[1]
    out[-1, 1:-1] = 2.0 * grid[-1] - grid[-2]
    out[:, 0] = 2.0 * out[:, 1] - out[:, 2]
    out[:, -1] = 2.0 * out[:, -2] - out[:, -3]
    return out


def corner_windows(corners: np.ndarray, pattern: BoardPattern, samples: int = 64) -> np.ndarray:
    """``cv2.cornerSubPix``'s half-window for each corner [px]: as large as a third of its own spacing allows while
    no edge that does not pass through the corner enters its window.

    ``cornerSubPix`` finds the point where the image gradients of its window all point at it: a corner's four edges
    do, any other edge in the window pulls the result towards it. Under strong foreshortening the squares become
    slanted parallelograms and the far edges of the four squares about a corner come much nearer to it than the
    corners do, so a rule on the spacing alone (:func:`corner_window_for`) lets them in. Here each corner's
    half-window is the smaller of a third of the distance to its nearest neighbouring corner and the window's own
    (Chebyshev) distance to the nearest of those far edges less :data:`EDGE_CLEARANCE_PX`, clipped to
    :data:`CORNER_WINDOW_RANGE`. The squares beyond the outer corners are extrapolated (:func:`_padded_grid`).

    Parameters
    ----------
    corners
        ``(rows·cols, 2)`` detected corners in OpenCV's row-major order.
    pattern
        The board.
    samples
        Points per far edge at which the window's distance is measured.
    """
    rows, cols = pattern.rows, pattern.cols
    grid = _padded_grid(np.asarray(corners, dtype=float).reshape(rows, cols, 2))
    centre = grid[1:-1, 1:-1]  # (rows, cols, 2)
    t = np.linspace(0.0, 1.0, samples)[:, None]
    nearest_edge = np.full((rows, cols), np.inf)
    nearest_corner = np.full((rows, cols), np.inf)
    for di in (-1, 1):
        for dj in (-1, 1):
            a = grid[1 + di : rows + 1 + di, 1:-1]  # the neighbour along a column
            b = grid[1:-1, 1 + dj : cols + 1 + dj]  # the neighbour along a row
            d = grid[1 + di : rows + 1 + di, 1 + dj : cols + 1 + dj]  # the square's far corner
            for start in (a, b):
                points = start[..., None, :] + t * (d - start)[..., None, :]  # (rows, cols, samples, 2)
                chebyshev = np.abs(points - centre[..., None, :]).max(axis=-1).min(axis=-1)
                nearest_edge = np.minimum(nearest_edge, chebyshev)
            for neighbour in (a, b):
                nearest_corner = np.minimum(nearest_corner, np.linalg.norm(neighbour - centre, axis=-1))
    lo, hi = CORNER_WINDOW_RANGE
    window = np.minimum(nearest_corner / 3.0, nearest_edge - EDGE_CLEARANCE_PX)
    return np.clip(np.floor(window), lo, hi).astype(int).ravel()


def refine_corners(image: np.ndarray, corners: np.ndarray, windows: np.ndarray) -> np.ndarray:
    """``cv2.cornerSubPix`` of each corner with its own half-window (:func:`corner_windows`), ``(n, 2)``."""
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    out = np.asarray(corners, dtype=np.float32).reshape(-1, 1, 2).copy()
    for half in np.unique(windows):
        chosen = np.flatnonzero(windows == half)
        refined = cv2.cornerSubPix(image, np.ascontiguousarray(out[chosen]), (int(half), int(half)), (-1, -1), criteria)
        out[chosen] = refined
    return out.reshape(-1, 2).astype(np.float64)


def detect_view(
    left: Path, right: Path, pattern: BoardPattern, detector: Any = None, *, corner_window: int | None = None
) -> ViewRecord:
    """Find the board in both photos of a view (module notes, step 3); the record says why not when it fails.

    ``detector`` is the board's ``cv2.aruco.CharucoDetector`` (made here when None); ``corner_window`` the
    checkerboard's ``cv2.cornerSubPix`` half-window [px] (None: :func:`corner_window_for` each photo).
    """
    view = ViewRecord(left, right)
    images = (_read(left), _read(right))
    if pattern.kind == "chessboard":
        found = [_chessboard(image, pattern, corner_window) for image in images]
        missing = [side for side, c in zip(("left", "right"), found, strict=True) if c is None]
        if missing:
            view.reason = _not_found(missing)
            return view
        view.object_points = pattern.object_points()
        view.left_corners = found[0]
        view.right_corners = _same_order(found[0], found[1])  # type: ignore[arg-type]
        return view
    detector = detector if detector is not None else pattern.charuco_detector()
    found_c = [_charuco(image, detector) for image in images]
    missing = [side for side, c in zip(("left", "right"), found_c, strict=True) if c is None]
    if missing:
        view.reason = _not_found(missing)
        return view
    (ids_l, px_l), (ids_r, px_r) = found_c  # type: ignore[misc]
    common, il, ir = np.intersect1d(ids_l, ids_r, return_indices=True)
    if len(common) < MIN_CHARUCO_CORNERS:
        view.reason = f"too few corners: {len(common)} seen in both photos (at least {MIN_CHARUCO_CORNERS})"
        return view
    view.object_points = np.asarray(detector.getBoard().getChessboardCorners(), dtype=np.float64)[common]
    view.left_corners, view.right_corners = px_l[il], px_r[ir]
    return view


def _not_found(missing: list[str]) -> str:
    where = "either photo" if len(missing) == 2 else f"the {missing[0]} photo"
    return f"board not found: not in {where}"


# -------------------------------------------------------------------------------------------------------- solve


def _solve(views: list[ViewRecord], size: tuple[int, int], pattern: BoardPattern, alpha: float) -> CalibrationResult:
    """The views' corners solved (:func:`~sensor.calibration.solve_stereo_calibration`); each view gets its RMS."""
    result = solve_stereo_calibration(
        [v.object_points for v in views],  # type: ignore[misc]
        [v.left_corners for v in views],  # type: ignore[misc]
        [v.right_corners for v in views],  # type: ignore[misc]
        size,
        target=(pattern.cols, pattern.rows),
        square_size=pattern.square,
        alpha=alpha,
    )
    for view, left, right, pair in zip(
        views, result.per_view_left, result.per_view_right, result.per_view_stereo, strict=True
    ):
        view.used, view.reason = True, ""
        view.rms_left, view.rms_right, view.rms_stereo = float(left), float(right), (float(pair[0]), float(pair[1]))
    return result


def calibrate_views(
    views: list[ViewRecord],
    size: tuple[int, int],
    pattern: BoardPattern,
    *,
    min_views: int = 5,
    alpha: float = 0.0,
    reject_outliers: bool = True,
) -> PhotoCalibration:
    """Solve from detected views, reject outlier views once and solve again (module notes, steps 4–5).

    With ``reject_outliers`` off every view with the board in both photos is used.

    Raises
    ------
    InputError
        Fewer than ``min_views`` views with the board in both photos: one line naming the photos without it.
    """
    found = [v for v in views if v.object_points is not None]
    if len(found) < min_views:
        lost = [
            f"{v.left.name}/{v.right.name} ({v.reason.split(': ', 1)[-1]})" for v in views if v.object_points is None
        ]
        raise InputError(
            f"too few views: the board ({pattern.label}) was found in both photos of {len(found)} of {len(views)} "
            f"pairs, at least {min_views} needed"
            + ("; not found: " + ", ".join(lost[:8]) if lost else "")
            + ("; …" if len(lost) > 8 else "")
        )
    with one_opencv_thread():
        result = _solve(found, size, pattern, alpha)
        worst = np.array([max(v.rms_stereo) for v in found])
        limit = max(OUTLIER_FLOOR_PX, OUTLIER_FACTOR * float(np.median(worst)))
        outliers = [v for v, w in zip(found, worst, strict=True) if w > limit and reject_outliers]
        notes: list[str] = []
        if outliers and len(found) - len(outliers) >= min_views:
            for v in outliers:
                v.used = False
                v.reason = (
                    f"reprojection outlier: stereo RMS {max(v.rms_stereo):.2f} px > {limit:.2f} px "
                    f"({OUTLIER_FACTOR:g}× the median view, at least {OUTLIER_FLOOR_PX:g} px)"
                )
            kept = [v for v in found if v not in outliers]
            result = _solve(kept, size, pattern, alpha)
        elif outliers:
            notes.append(f"{len(outliers)} outlier view(s) kept: without them fewer than {min_views} views remain")
    return PhotoCalibration(result, views, pattern, size, notes)


def check_options(*, min_views: int = 5, alpha: float = 0.0, corner_window: int | None = None) -> None:
    """Refuse calibration settings out of range (one line naming the option), before any photo is read."""
    if not (isinstance(min_views, int) and min_views >= 3):
        raise InputError(f"--min-views {min_views!r}: allowed: an integer ≥ 3")
    if not (0.0 <= alpha <= 1.0 or alpha == -1.0):  # also NaN
        raise InputError(f"--alpha {alpha!r}: allowed: [0, 1] or -1 (OpenCV's default scaling)")
    if corner_window is not None and not (isinstance(corner_window, int) and 2 <= corner_window <= 50):
        raise InputError(f"--corner-window {corner_window!r}: allowed: an integer in [2, 50] px")


def calibrate_photos(
    pairs: Sequence[tuple[Path, Path]],
    pattern: BoardPattern,
    *,
    min_views: int = 5,
    alpha: float = 0.0,
    corner_window: int | None = None,
    reject_outliers: bool = True,
) -> PhotoCalibration:
    """Calibrate a stereo pair from photos of a board (module notes): checks, detection, solve.

    Parameters
    ----------
    pairs : sequence of (Path, Path)
        The left and right photo of each view (:func:`sensor.photo_pairs.stereo_pairs`).
    pattern : BoardPattern
        The board.
    min_views : int
        Fewest views with the board in both photos (at least 3).
    alpha : float
        ``cv2.stereoRectify``'s free scaling: 0 keeps only valid pixels, 1 all source pixels.
    corner_window : int, optional
        A checkerboard's ``cv2.cornerSubPix`` half-window [px], 2–50 (default: :func:`corner_window_for` each photo).
    reject_outliers : bool
        Reject outlier views (module notes, step 5); off: every view with the board in both photos is used.

    Returns
    -------
    PhotoCalibration

    Raises
    ------
    InputError
        A file that is not an image, mixed sizes, too few views — one line each, naming the files.
    """
    check_options(min_views=min_views, alpha=alpha, corner_window=corner_window)
    size = check_images(pairs)
    check_photo_size(size, pattern.cols, pattern.rows, pattern.label)
    detector = pattern.charuco_detector() if pattern.kind == "charuco" else None
    with one_opencv_thread():
        views = [detect_view(left, right, pattern, detector, corner_window=corner_window) for left, right in pairs]
    return calibrate_views(views, size, pattern, min_views=min_views, alpha=alpha, reject_outliers=reject_outliers)
