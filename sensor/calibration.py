"""Stereo calibration of the rig as in de Saxe & Cebon 2018, §4.1 (field tests): a checkerboard in seeded poses, OpenCV.

de Saxe & Cebon 2018 calibrated each camera by Zhang's method (Zhang 2000) with Heikkilä's distortion model
(Heikkilä & Silvén 1997) and the pair by Fusiello's rectification (Fusiello et al. 2000), all with OpenCV.
:func:`calibrate_rig` does the same on simulated images:

1. ``views`` seeded target poses both cameras see whole (:func:`sensor.calibration_target.sample_board_poses`),
   imaged by the true distorted cameras — the left, and the right with its misalignment, from the rig's own
   camera poses (:meth:`sensor.camera.StereoRig.camera_in_trailer`) — by an exact ray cast
   (:mod:`sensor.calibration_target`) with the rig's image noise;
2. corners found by ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix``, plus Gaussian corner noise
   ``corner_noise_px`` (per coordinate) standing for a poorer detector, target or focus;
3. ``cv2.calibrateCamera`` per camera (k1, k2, p1, p2, k3 free, fx and fy free), ``cv2.stereoCalibrate``
   (R, T with ``X_right = R·X_left + T``), ``cv2.stereoRectify`` (zero disparity at infinity, ``alpha`` = 0: the
   rectified images contain only valid pixels).

``stereo_refinement`` says what ``cv2.stereoCalibrate`` solves for (:data:`STEREO_REFINEMENTS`). ``extrinsics``
keeps each camera's own intrinsics and distortion fixed and fits R, T alone (``CALIB_FIX_INTRINSIC``): each camera's
model then carries its own, independent error from its own corners, and the rectified disparity, which is the
difference of the two cameras' rays, carries the difference of those errors — a disparity error that varies
across the image. ``joint`` starts from the per-camera estimates and refines both cameras' intrinsics and
distortion together with R, T on the pairs of views (``CALIB_USE_INTRINSIC_GUESS``, Bouguet's stereo calibration
as in OpenCV's stereo calibration sample): the two models are then fitted to the same board poses seen by both
cameras at once, and what is left in the disparity is what the pair's views do not constrain. ``joint_same_focal``
is ``joint`` with the two cameras' focal lengths one parameter (``CALIB_SAME_FOCAL_LENGTH``), for a pair of the same
camera and lens: the difference of the two estimated focal lengths is the least constrained part of ``joint``, and
a difference ``Δf`` puts a disparity error ``Δf·x`` that changes sign across the image (``x`` the normalised column),
which a camera moving along its axis reads as a turn of its translation (docs/field_bias.md, "The pair's
focal-length difference turns the rear camera's motion"). A pair whose lenses really differ in focal length keeps
that difference in its rectification with this mode. The per-camera RMS
(:attr:`CalibrationResult.rms_left`, ``rms_right``) stay those of the per-camera fits either way.

The result (:class:`CalibrationResult`) writes and reads OpenCV YAML (``cv2.FileStorage``), builds the
rectification maps (``cv2.initUndistortRectifyMap``) and says which focal length, principal point and baseline the
odometry must use on the rectified images (:meth:`CalibrationResult.rectified_rig_parameters`).
:func:`sensor.calibration_report.calibration_summary` compares it with the truth (``offtrack calibrate``).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import cv2
import numpy as np

from sensor.calibration_target import (
    Board,
    Camera,
    detect_corners,
    order_like,
    sample_board_poses,
    true_right_from_left,
)
from sensor.camera import Lens, StereoRig
from sensor.vo.config import VOConfig
from vehicle_model.errors import InputError

FORMAT = "offtrack-stereo-calibration-1"
"""Value of the ``format`` key of a calibration file."""

_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)

STEREO_REFINEMENTS = ("extrinsics", "joint", "joint_same_focal")
"""What ``cv2.stereoCalibrate`` refines (module notes): R, T alone, or both cameras' intrinsics with them (with one
focal length for the two cameras: ``joint_same_focal``)."""

_STEREO_FLAGS = {
    "extrinsics": cv2.CALIB_FIX_INTRINSIC,
    "joint": cv2.CALIB_USE_INTRINSIC_GUESS,
    "joint_same_focal": cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_SAME_FOCAL_LENGTH,
}


@dataclass(frozen=True, eq=False)
class RectifiedParameters:
    """What the odometry must use on images rectified with a :class:`CalibrationResult`.

    Attributes
    ----------
    f, cu, cv : float
        Focal length and principal point of the rectified images [px] (``P1``; ``cv`` is ``P2``'s too).
    baseline : float
        Baseline [m]: ``−P2[0, 3] / P2[0, 0]``.
    width, height : int
        Rectified image size [px].
    rotation_left : numpy.ndarray
        ``R1`` (3×3): the rectified left camera's axes from the actual left camera's, ``X_rect = R1·X_left``.
        The odometry's motion is in the rectified left frame: its pose on the trailer is
        :meth:`rectified_left_in_trailer`.
    """

    f: float
    cu: float
    cv: float
    baseline: float
    width: int
    height: int
    rotation_left: np.ndarray

    def vo_config(self, **overrides: object) -> VOConfig:
        """A :class:`sensor.vo.VOConfig` with ``f``, ``cu``, ``cv``, ``baseline`` from the calibration."""
        return VOConfig(f=self.f, cu=self.cu, cv=self.cv, baseline=self.baseline, **overrides)  # type: ignore[arg-type]

    def rectified_left_in_trailer(self, left_in_trailer: np.ndarray) -> np.ndarray:
        """``T_trailer←rectified-left`` (4×4) from the left camera's ``T_trailer←left``: rotation times ``R1ᵀ``."""
        out = np.array(left_in_trailer, dtype=float, copy=True)
        out[:3, :3] = out[:3, :3] @ self.rotation_left.T
        return out


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """A stereo calibration (OpenCV conventions; lengths in metres, pixels in OpenCV's pixel-centre convention).

    Attributes
    ----------
    image_size : tuple of int
        ``(width, height)`` [px].
    k_left, k_right : numpy.ndarray
        Camera matrices (3×3).
    dist_left, dist_right : numpy.ndarray
        ``(5,)`` distortion ``[k1, k2, p1, p2, k3]``.
    r, t : numpy.ndarray
        ``X_right = r·X_left + t`` (3×3, (3,) [m]).
    r1, r2, p1, p2, q : numpy.ndarray
        ``cv2.stereoRectify``'s rectifying rotations, projections (3×4) and disparity-to-depth matrix (4×4).
    per_view_left, per_view_right : numpy.ndarray
        ``(n,)`` RMS reprojection error of each view in each camera's own calibration [px].
    per_view_stereo : numpy.ndarray
        ``(n, 2)`` RMS reprojection error of each view (left, right) in the stereo calibration [px].
    rms_left, rms_right, rms_stereo : float
        Overall RMS reprojection errors [px].
    views, target, square_size, corner_noise_px, seed, alpha, stereo_refinement
        The settings it was made with.
    """

    image_size: tuple[int, int]
    k_left: np.ndarray
    dist_left: np.ndarray
    k_right: np.ndarray
    dist_right: np.ndarray
    r: np.ndarray
    t: np.ndarray
    r1: np.ndarray
    r2: np.ndarray
    p1: np.ndarray
    p2: np.ndarray
    q: np.ndarray
    per_view_left: np.ndarray
    per_view_right: np.ndarray
    per_view_stereo: np.ndarray
    rms_left: float
    rms_right: float
    rms_stereo: float
    views: int
    target: tuple[int, int]
    square_size: float
    corner_noise_px: float
    seed: int
    alpha: float = 0.0
    stereo_refinement: str = "extrinsics"
    _maps: dict = field(default_factory=dict, repr=False)

    # -- files ----------------------------------------------------------------------------------------
    _MATRICES: ClassVar[tuple[str, ...]] = ("k_left", "dist_left", "k_right", "dist_right", "r", "t")
    _MATRICES += ("r1", "r2", "p1", "p2", "q")
    _PER_VIEW: ClassVar[tuple[str, ...]] = ("per_view_left", "per_view_right", "per_view_stereo")
    _KEYS: ClassVar[dict[str, str]] = {"k_left": "K1", "dist_left": "D1", "k_right": "K2", "dist_right": "D2"}

    def write(self, path: str | Path) -> Path:
        """Write OpenCV YAML (``cv2.FileStorage``): K1, D1, K2, D2, R, T, R1, R2, P1, P2, Q, residuals, settings."""
        path = _yaml_path(path)
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
        if not fs.isOpened():
            raise InputError(f"calibration file {path}: cannot be written")
        try:
            fs.write("format", FORMAT)
            fs.write("image_width", int(self.image_size[0]))
            fs.write("image_height", int(self.image_size[1]))
            for name in self._MATRICES:
                value = np.asarray(getattr(self, name), dtype=np.float64)
                fs.write(self._KEYS.get(name, name.upper()), value.reshape(-1, 1) if value.ndim == 1 else value)
            for name in self._PER_VIEW:
                fs.write(name, np.asarray(getattr(self, name), dtype=np.float64).reshape(self.views, -1))
            for name in ("rms_left", "rms_right", "rms_stereo", "square_size", "corner_noise_px", "alpha"):
                fs.write(name, float(getattr(self, name)))
            for name, value in (
                ("views", self.views),
                ("target_cols", self.target[0]),
                ("target_rows", self.target[1]),
            ):
                fs.write(name, int(value))
            fs.write("seed", int(self.seed))
            fs.write("stereo_refinement", str(self.stereo_refinement))
        finally:
            fs.release()
        return path

    @classmethod
    def read(cls, path: str | Path) -> CalibrationResult:
        """Read a file written by :meth:`write` (InputError naming the file and the missing or bad key)."""
        path = Path(path)
        if not path.is_file():
            raise InputError(f"calibration file {path}: not found")
        try:
            fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        except (cv2.error, SystemError):  # OpenCV's parser on a file that is not YAML/XML/JSON text
            raise InputError(f"calibration file {path}: not an OpenCV YAML file (offtrack calibrate's)") from None
        try:
            if fs.getNode("format").string() != FORMAT:
                raise InputError(f"calibration file {path}: format is not {FORMAT!r}")

            def node(key: str) -> cv2.FileNode:
                n = fs.getNode(key)
                if n.empty():
                    raise InputError(f"calibration file {path}: key {key!r} is missing")
                return n

            mats = {}
            for name in cls._MATRICES:
                m = node(cls._KEYS.get(name, name.upper())).mat()
                if m is None:
                    raise InputError(
                        f"calibration file {path}: key {cls._KEYS.get(name, name.upper())!r} is not a matrix"
                    )
                mats[name] = m.ravel() if name in ("dist_left", "dist_right", "t") else m
            views = int(node("views").real())
            per_view = {name: node(name).mat() for name in cls._PER_VIEW}
            result = cls(
                image_size=(int(node("image_width").real()), int(node("image_height").real())),
                per_view_left=per_view["per_view_left"].ravel(),
                per_view_right=per_view["per_view_right"].ravel(),
                per_view_stereo=per_view["per_view_stereo"].reshape(views, 2),
                rms_left=node("rms_left").real(),
                rms_right=node("rms_right").real(),
                rms_stereo=node("rms_stereo").real(),
                views=views,
                target=(int(node("target_cols").real()), int(node("target_rows").real())),
                square_size=node("square_size").real(),
                corner_noise_px=node("corner_noise_px").real(),
                seed=int(node("seed").real()),
                alpha=node("alpha").real(),
                stereo_refinement=_stereo_refinement(fs, path),
                **mats,
            )
        finally:
            fs.release()
        return result

    # -- use --------------------------------------------------------------------------------------------
    def rectify_maps(
        self, *, fixed_point: bool = True
    ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """``cv2.initUndistortRectifyMap`` maps of the left and right cameras (cached per ``fixed_point``).

        Fixed point (CV_16SC2 + CV_16UC1, 1/32 px) remaps about twice as fast as float (two CV_32FC1 maps).
        """
        if fixed_point not in self._maps:
            m1type = cv2.CV_16SC2 if fixed_point else cv2.CV_32FC1
            self._maps[fixed_point] = tuple(
                cv2.initUndistortRectifyMap(k, d, r, p, self.image_size, m1type)
                for k, d, r, p in (
                    (self.k_left, self.dist_left, self.r1, self.p1),
                    (self.k_right, self.dist_right, self.r2, self.p2),
                )
            )
        return self._maps[fixed_point]

    def rectify(self, left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rectify a distorted pair (``cv2.remap``, bilinear, black outside)."""
        (l1, l2), (r1, r2) = self.rectify_maps()
        return cv2.remap(left, l1, l2, cv2.INTER_LINEAR), cv2.remap(right, r1, r2, cv2.INTER_LINEAR)

    def rectified_rig_parameters(self) -> RectifiedParameters:
        """Focal length, principal point and baseline of the rectified pair, and ``R1`` (OpenCV stereoRectify docs)."""
        return RectifiedParameters(
            f=float(self.p1[0, 0]),
            cu=float(self.p1[0, 2]),
            cv=float(self.p1[1, 2]),
            baseline=float(-self.p2[0, 3] / self.p2[0, 0]),  # P2[0, 3] = f·Tx of the rectified pair
            width=int(self.image_size[0]),
            height=int(self.image_size[1]),
            rotation_left=np.asarray(self.r1, dtype=float).copy(),
        )


def _stereo_refinement(fs: cv2.FileStorage, path: Path) -> str:
    """A file's ``stereo_refinement``: ``extrinsics`` when the key is absent (files written before it was stored)."""
    n = fs.getNode("stereo_refinement")
    value = "extrinsics" if n.empty() else n.string()
    if value not in STEREO_REFINEMENTS:
        allowed = ", ".join(STEREO_REFINEMENTS)
        raise InputError(f"calibration file {path}: stereo_refinement = {value!r}; allowed: {allowed}")
    return value


def _yaml_path(path: str | Path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in (".yaml", ".yml"):
        raise InputError(f"calibration file {path}: allowed: a .yaml or .yml path (OpenCV YAML)")
    if path.exists() and path.is_dir():
        raise InputError(f"calibration file {path}: is a directory")
    if not path.parent.is_dir():
        raise InputError(f"calibration file {path}: directory {path.parent} does not exist")
    return path


# -- the procedure ----------------------------------------------------------------------------------------
def _check_settings(
    views: object,
    target: object,
    square_size: object,
    corner_noise_px: object,
    seed: object,
    alpha: object,
    stereo_refinement: object = "extrinsics",
) -> Board:
    errors = []
    if stereo_refinement not in STEREO_REFINEMENTS:
        allowed = ", ".join(STEREO_REFINEMENTS)
        errors.append(f"stereo_refinement = {stereo_refinement!r} is not allowed; allowed: {allowed}")
    if not (isinstance(views, int) and not isinstance(views, bool) and 5 <= views <= 100):
        errors.append(f"views = {views!r} is out of range; allowed: an integer in [5, 100]")
    if not (
        isinstance(corner_noise_px, int | float) and math.isfinite(corner_noise_px) and 0.0 <= corner_noise_px <= 5.0
    ):
        errors.append(f"corner_noise_px = {corner_noise_px!r} is out of range; allowed: [0, 5] px")
    if not (isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0):
        errors.append(f"seed = {seed!r} is not allowed; allowed: an integer ≥ 0")
    if not (isinstance(alpha, int | float) and (alpha == -1 or 0.0 <= alpha <= 1.0)):
        errors.append(f"alpha = {alpha!r} is out of range; allowed: [0, 1] or -1 (OpenCV's default scaling)")
    if not (isinstance(target, tuple | list) and len(target) == 2 and all(isinstance(n, int) for n in target)):
        errors.append(f"target = {target!r} is not allowed; allowed: (cols, rows) inner corners, integers")
    if not isinstance(square_size, int | float):
        errors.append(f"square_size = {square_size!r} is not allowed; allowed: a number of metres in [0.005, 1]")
    if errors:
        raise InputError("; ".join(errors))
    return Board(int(target[0]), int(target[1]), float(square_size))  # type: ignore[index]


def calibrate_rig(
    rig: StereoRig,
    lens_left: Lens,
    lens_right: Lens,
    *,
    views: int,
    target: tuple[int, int],
    square_size: float,
    corner_noise_px: float,
    seed: int,
    alpha: float = 0.0,
    stereo_refinement: str = "extrinsics",
) -> CalibrationResult:
    """Calibrate the rig's two distorted cameras from simulated views of a checkerboard (module docstring).

    Parameters
    ----------
    rig : StereoRig
        The true rig: image size, K (``rig.intrinsics()``), baseline, the right camera's misalignment, the image
        noise ``noise_std``.
    lens_left, lens_right : Lens
        The true lenses.
    views : int
        Views of the target used, 5–100 (a view that either camera fails to detect is replaced by a new pose).
    target : tuple of int
        ``(cols, rows)`` inner corners (different numbers, 3–30 each).
    square_size : float
        Side of a square [m].
    corner_noise_px : float
        Standard deviation of Gaussian noise added to each detected corner coordinate [px].
    seed : int
        Seed of the poses, the image noise and the corner noise (``numpy.random.default_rng``).
    alpha : float
        ``cv2.stereoRectify``'s free scaling: 0 keeps only valid pixels, 1 all source pixels.
    stereo_refinement : str
        What the stereo calibration refines (:data:`STEREO_REFINEMENTS`, module notes).

    Returns
    -------
    CalibrationResult

    Raises
    ------
    InputError
        A bad setting (named), no pose both cameras see, or too few detected views.
    """
    board = _check_settings(views, target, square_size, corner_noise_px, seed, alpha, stereo_refinement)
    with one_opencv_thread():  # OpenCV's parallel loops sum in a varying order; on one thread a seed repeats exactly
        return _calibrate(
            rig, lens_left, lens_right, board, views, square_size, corner_noise_px, seed, alpha, stereo_refinement
        )


@contextlib.contextmanager
def one_opencv_thread() -> Iterator[None]:
    """OpenCV on one thread for the block (its parallel loops sum in a varying order), then as before."""
    previous = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(previous)


def _calibrate(
    rig: StereoRig,
    lens_left: Lens,
    lens_right: Lens,
    board: Board,
    views: int,
    square_size: float,
    corner_noise_px: float,
    seed: int,
    alpha: float,
    stereo_refinement: str,
) -> CalibrationResult:
    """:func:`calibrate_rig` once its settings are checked: image the target, detect its corners, solve."""
    rng = np.random.default_rng([int(seed), 0xCA11B])
    k = rig.intrinsics()
    left = Camera.build(k, lens_left, rig.width, rig.height)
    right = left if lens_right == lens_left else Camera.build(k, lens_right, rig.width, rig.height)
    right_from_left = true_right_from_left(rig)
    poses = sample_board_poses(left, right, right_from_left, rig.baseline, board, views, rng)
    obj = board.object_points()
    found_left: list[np.ndarray] = []
    found_right: list[np.ndarray] = []
    spare = 0
    while poses:
        pose = poses.pop(0)
        corners = []
        for cam, cam_from_board in ((left, pose), (right, right_from_left @ pose)):
            image = cam.render(cam_from_board, board, noise_std=rig.noise_std, rng=rng)
            detected = detect_corners(image, board)
            if detected is None:
                break
            corners.append(order_like(detected, cam.project(cam_from_board, obj)))
        if len(corners) == 2:
            found_left.append(corners[0])
            found_right.append(corners[1])
        elif spare < 2 * views:
            spare += 1
            poses += sample_board_poses(left, right, right_from_left, rig.baseline, board, 1, rng)
        else:
            raise InputError(
                f"calibration: the target was found in too few views ({len(found_left)} of {views}); "
                "allowed: a target the detector finds (larger square_size, more corners)"
            )
    if corner_noise_px > 0:
        found_left = [c + rng.normal(0.0, corner_noise_px, c.shape) for c in found_left]
        found_right = [c + rng.normal(0.0, corner_noise_px, c.shape) for c in found_right]
    return _solve(rig, board, obj, found_left, found_right, views, corner_noise_px, seed, alpha, stereo_refinement)


def _solve(
    rig: StereoRig,
    board: Board,
    obj: np.ndarray,
    found_left: list[np.ndarray],
    found_right: list[np.ndarray],
    views: int,
    corner_noise_px: float,
    seed: int,
    alpha: float,
    stereo_refinement: str,
) -> CalibrationResult:
    """The rendered views' corners solved by :func:`solve_stereo_calibration`."""
    return solve_stereo_calibration(
        [obj] * len(found_left),
        found_left,
        found_right,
        (rig.width, rig.height),
        target=(board.cols, board.rows),
        square_size=board.square,
        alpha=alpha,
        corner_noise_px=corner_noise_px,
        seed=seed,
        stereo_refinement=stereo_refinement,
    )


def solve_stereo_calibration(
    object_points: list[np.ndarray],
    left_corners: list[np.ndarray],
    right_corners: list[np.ndarray],
    image_size: tuple[int, int],
    *,
    target: tuple[int, int],
    square_size: float,
    alpha: float,
    corner_noise_px: float = 0.0,
    seed: int = 0,
    stereo_refinement: str = "extrinsics",
) -> CalibrationResult:
    """Zhang per camera, the stereo calibration, Fusiello rectification (OpenCV calib3d).

    Parameters
    ----------
    object_points
        Per view, the board's corners in its own frame [m], ``(n, 3)``.
    left_corners, right_corners
        Per view, the corners found in the left and right image [px], ``(n, 2)``, in the order of ``object_points``.
    image_size
        ``(width, height)`` [px].
    target, square_size
        The board's inner corners ``(cols, rows)`` and square size [m], recorded in the result.
    alpha
        ``cv2.stereoRectify``'s free scaling: 0 keeps only valid pixels, 1 keeps every source pixel.
    corner_noise_px, seed
        Recorded in the result: the noise added to rendered corners and its seed (0 for photos).
    stereo_refinement
        ``extrinsics``: R, T with each camera's intrinsics fixed; ``joint``: both cameras' intrinsics and
        distortion refined with R, T from the per-camera estimates; ``joint_same_focal``: ``joint`` with one focal
        length for both cameras (:data:`STEREO_REFINEMENTS`, module notes).

    Returns
    -------
    CalibrationResult
        Intrinsics, extrinsics, rectification and the per-view reprojection RMS of each camera and of the pair.
    """
    if stereo_refinement not in STEREO_REFINEMENTS:
        allowed = ", ".join(STEREO_REFINEMENTS)
        raise InputError(f"stereo_refinement = {stereo_refinement!r} is not allowed; allowed: {allowed}")
    size = (int(image_size[0]), int(image_size[1]))
    objs = [np.asarray(o, dtype=np.float32).reshape(-1, 1, 3) for o in object_points]
    img_l = [np.asarray(c, dtype=np.float32).reshape(-1, 1, 2) for c in left_corners]
    img_r = [np.asarray(c, dtype=np.float32).reshape(-1, 1, 2) for c in right_corners]
    mono = []
    for pts in (img_l, img_r):
        # Zhang 2000 with Brown–Conrady k1, k2, p1, p2, k3. Started from zero distortion, the full model can settle
        # in a wrong minimum under strong barrel distortion (k1 ≈ −0.2 at 100°: 170 px at the corners), so first
        # fit without k3, then free k3 from there.
        _, kk, dd, _, _ = cv2.calibrateCamera(objs, pts, size, None, None, flags=cv2.CALIB_FIX_K3, criteria=_CRITERIA)
        rms, kk, dd, _, _, _, _, per_view = cv2.calibrateCameraExtended(
            objs, pts, size, kk, dd, flags=cv2.CALIB_USE_INTRINSIC_GUESS, criteria=_CRITERIA
        )
        mono.append((float(rms), kk, dd.ravel(), np.asarray(per_view, dtype=float).ravel()))
    (rms_l, k1, d1, pv_l), (rms_r, k2, d2, pv_r) = mono
    rms_s, k1_s, d1_s, k2_s, d2_s, r, t, _, _, _, _, per_view = cv2.stereoCalibrateExtended(
        objs,
        img_l,
        img_r,
        k1,
        d1,
        k2,
        d2,
        size,
        np.eye(3),
        np.zeros((3, 1)),
        flags=_STEREO_FLAGS[stereo_refinement],
        criteria=_CRITERIA,
    )
    if stereo_refinement != "extrinsics":  # the pair's own intrinsics; with them fixed they are the per-camera ones
        k1, k2 = k1_s, k2_s
        d1, d2 = np.asarray(d1_s, dtype=float).ravel(), np.asarray(d2_s, dtype=float).ravel()
    r1, r2, p1, p2, q, _, _ = cv2.stereoRectify(
        k1, d1, k2, d2, size, r, t, flags=cv2.CALIB_ZERO_DISPARITY, alpha=alpha
    )  # Fusiello et al. 2000 / Bouguet
    return CalibrationResult(
        image_size=size,
        k_left=k1,
        dist_left=d1,
        k_right=k2,
        dist_right=d2,
        r=r,
        t=t.ravel(),
        r1=r1,
        r2=r2,
        p1=p1,
        p2=p2,
        q=q,
        per_view_left=pv_l,
        per_view_right=pv_r,
        per_view_stereo=np.asarray(per_view, dtype=float).reshape(-1, 2),
        rms_left=rms_l,
        rms_right=rms_r,
        rms_stereo=float(rms_s),
        views=len(objs),
        target=(int(target[0]), int(target[1])),
        square_size=float(square_size),
        corner_noise_px=float(corner_noise_px),
        seed=int(seed),
        alpha=float(alpha),
        stereo_refinement=stereo_refinement,
    )
