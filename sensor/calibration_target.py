"""The checkerboard calibration target: its geometry, seeded poses in front of the rig, an exact render, detection.

Imaging the target
------------------
The target is drawn by an exact ray cast in numpy, not by the OpenGL renderer: the project allows one GL
renderer per process (the run's own, sized for the run's wide pinhole render), a planar checkerboard has a
closed-form image, and the ray cast needs no pinhole-then-remap step, so the only blur is the pixel's own
area. For every pixel of the *distorted* camera the ray is ``undistort(K⁻¹·(u, v))`` (``cv2.undistortPoints``,
Brown–Conrady; computed once per camera on a 3 × 3 sub-pixel grid), intersected with the target plane
(``λ = (n·t)/(n·r)``), coloured by the checker square it hits and averaged over the nine sub-samples (box
anti-aliasing); the rig's Gaussian image noise is added last. Only the target's bounding box is ray cast.

Board frame (OpenCV's convention for ``calibrateCamera``): corner ``(i, j)`` (column i, row j) at
``(i·s, j·s, 0)``, listed row by row; the target's normal ``+z`` points away from the camera. The board has
``(cols + 1) × (rows + 1)`` squares and a white border one square wide.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from sensor.camera import Lens, StereoRig
from sensor.lens import ideal_extent, undistort_pixels
from vehicle_model.errors import InputError

BLACK, WHITE, BACKGROUND = 30.0, 225.0, 110.0
"""Grey levels of the dark and light squares and of the background behind the target."""

SUPERSAMPLE = 3
"""Sub-samples per pixel along each axis of the ray cast (3 × 3 box anti-aliasing)."""


@dataclass(frozen=True)
class Board:
    """A checkerboard target: ``cols × rows`` inner corners, squares of ``square`` metres."""

    cols: int
    rows: int
    square: float

    def __post_init__(self) -> None:
        if not (
            isinstance(self.cols, int) and isinstance(self.rows, int) and 3 <= self.cols <= 30 and 3 <= self.rows <= 30
        ):
            raise InputError(
                f"target = ({self.cols!r}, {self.rows!r}) is out of range; allowed: 3–30 inner corners each"
            )
        if self.cols == self.rows:
            raise InputError(
                f"target = ({self.cols}, {self.rows}): a square board is ambiguous under 90° rotation; "
                "allowed: different numbers of inner corners (e.g. (9, 6))"
            )
        if not (math.isfinite(self.square) and 0.005 <= self.square <= 1.0):
            raise InputError(f"square_size = {self.square!r} is out of range; allowed: [0.005, 1] m")

    @property
    def pattern_size(self) -> tuple[int, int]:
        """OpenCV ``patternSize``: (points per row, points per column)."""
        return self.cols, self.rows

    def object_points(self) -> np.ndarray:
        """``(rows·cols, 3)`` float32 corners in the board frame, row by row [m]."""
        i, j = np.meshgrid(np.arange(self.cols), np.arange(self.rows))
        pts = np.column_stack([i.ravel(), j.ravel(), np.zeros(i.size)]) * self.square
        return pts.astype(np.float32)

    @property
    def centre(self) -> np.ndarray:
        """The middle of the corner grid in the board frame [m]."""
        return np.array([0.5 * (self.cols - 1), 0.5 * (self.rows - 1), 0.0]) * self.square

    @property
    def outer_size(self) -> tuple[float, float]:
        """Width and height of the whole target including its white border [m]."""
        return (self.cols + 3) * self.square, (self.rows + 3) * self.square

    def outline(self, per_edge: int = 40) -> np.ndarray:
        """``(4·per_edge, 3)`` points along the target's outer edge (white border included) [m]."""
        s = self.square
        x0, x1, y0, y1 = -2.0 * s, (self.cols + 1) * s, -2.0 * s, (self.rows + 1) * s
        t = np.linspace(0.0, 1.0, per_edge, endpoint=False)
        edges = [
            np.column_stack([x0 + (x1 - x0) * t, np.full_like(t, y0)]),
            np.column_stack([np.full_like(t, x1), y0 + (y1 - y0) * t]),
            np.column_stack([x1 - (x1 - x0) * t, np.full_like(t, y1)]),
            np.column_stack([np.full_like(t, x0), y1 - (y1 - y0) * t]),
        ]
        xy = np.concatenate(edges)
        return np.column_stack([xy, np.zeros(len(xy))])

    def shade(self, bx: np.ndarray, by: np.ndarray) -> np.ndarray:
        """Grey level at board coordinates ``(bx, by)`` [m]: checker squares, white border, background outside."""
        s = self.square
        a = np.floor(bx / s)
        b = np.floor(by / s)
        squares = (a >= -1) & (a <= self.cols - 1) & (b >= -1) & (b <= self.rows - 1)
        border = (bx >= -2.0 * s) & (bx < (self.cols + 1) * s) & (by >= -2.0 * s) & (by < (self.rows + 1) * s)
        dark = squares & (((a + b) % 2) == 0)
        out = np.where(border, WHITE, BACKGROUND)
        return np.where(dark, BLACK, out)


@dataclass(frozen=True, eq=False)
class Camera:
    """One distorted camera for the ray cast: intrinsics, lens, image size and its sub-pixel ray grid.

    Attributes
    ----------
    k : numpy.ndarray
        Camera matrix (3×3).
    lens : Lens
        Distortion.
    width, height : int
        Image size [px].
    rays : numpy.ndarray
        ``(height, width, SUPERSAMPLE², 2)`` float32 normalised ray coordinates ``(x, y)`` (ray ``(x, y, 1)``).
    extent : tuple of float
        Ideal-pixel bounding box of the image (:func:`sensor.lens.ideal_extent`).
    """

    k: np.ndarray
    lens: Lens
    width: int
    height: int
    rays: np.ndarray
    extent: tuple[float, float, float, float]

    @classmethod
    def build(cls, k: np.ndarray, lens: Lens, width: int, height: int) -> Camera:
        """Undistort every pixel (to 1e-12) and interpolate the 3 × 3 sub-pixel rays bilinearly within each pixel."""
        k = np.asarray(k, dtype=float)
        # rays at the pixel centres and one pixel beyond the border on every side
        u, v = np.meshgrid(np.arange(-1, width + 1, dtype=float), np.arange(-1, height + 1, dtype=float))
        centres = undistort_pixels(k, lens, np.column_stack([u.ravel(), v.ravel()]), p=np.eye(3))
        grid = centres.reshape(height + 2, width + 2, 2)
        offsets = (np.arange(SUPERSAMPLE) + 0.5) / SUPERSAMPLE - 0.5  # −1/3, 0, +1/3
        rays = np.empty((height, width, SUPERSAMPLE * SUPERSAMPLE, 2), dtype=np.float32)
        n = 0
        for dv in offsets:
            for du in offsets:
                # bilinear interpolation between the pixel centre and its neighbours in the offset's direction
                su, sv = int(np.sign(du)), int(np.sign(dv))
                wu, wv = abs(du), abs(dv)
                c00 = grid[1 : height + 1, 1 : width + 1]
                c10 = grid[1 : height + 1, 1 + su : width + 1 + su]
                c01 = grid[1 + sv : height + 1 + sv, 1 : width + 1]
                c11 = grid[1 + sv : height + 1 + sv, 1 + su : width + 1 + su]
                rays[:, :, n] = (1 - wu) * (1 - wv) * c00 + wu * (1 - wv) * c10 + (1 - wu) * wv * c01 + wu * wv * c11
                n += 1
        return cls(k, lens, width, height, rays, ideal_extent(k, lens, width, height))

    def project(self, camera_from_board: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Distorted pixels ``(n, 2)`` of board points ``(n, 3)`` (``cv2.projectPoints`` with the lens)."""
        rvec, _ = cv2.Rodrigues(np.ascontiguousarray(camera_from_board[:3, :3], dtype=np.float64))
        tvec = np.ascontiguousarray(camera_from_board[:3, 3], dtype=np.float64)
        out, _ = cv2.projectPoints(np.asarray(points, dtype=np.float64), rvec, tvec, self.k, self.lens.coefficients)
        return out.reshape(-1, 2)

    def sees(self, camera_from_board: np.ndarray, board: Board, margin_px: float) -> bool:
        """Whether the whole target (border included) lies inside the image, ``margin_px`` from its edges."""
        pts = board.outline() @ camera_from_board[:3, :3].T + camera_from_board[:3, 3]
        if np.any(pts[:, 2] <= 0.05):
            return False
        ideal = pts[:, :2] / pts[:, 2:3] @ np.diag([self.k[0, 0], self.k[1, 1]]) + self.k[:2, 2]
        u0, v0, u1, v1 = self.extent
        if ideal[:, 0].min() < u0 or ideal[:, 0].max() > u1 or ideal[:, 1].min() < v0 or ideal[:, 1].max() > v1:
            return False  # beyond the lens's field of view: the distortion model is not meaningful there
        uv = self.project(camera_from_board, board.outline())
        return bool(
            uv[:, 0].min() >= margin_px
            and uv[:, 0].max() <= self.width - 1 - margin_px
            and uv[:, 1].min() >= margin_px
            and uv[:, 1].max() <= self.height - 1 - margin_px
        )

    def render(
        self,
        camera_from_board: np.ndarray,
        board: Board,
        *,
        noise_std: float = 0.0,
        rng: np.random.Generator | None = None,
    ) -> np.ndarray:
        """The distorted grey image ``(height, width)`` uint8 of the target at ``camera_from_board`` (ray cast).

        For each sub-pixel ray ``r = (x, y, 1)``: ``λ = (n·t)/(n·r)`` with the plane's normal ``n = R·e_z`` and
        origin ``t``; the board coordinates of the hit are ``Rᵀ·(λ·r − t)`` (ray–plane intersection).
        """
        img = np.full((self.height, self.width), BACKGROUND, dtype=np.float32)
        uv = self.project(camera_from_board, board.outline())
        u0 = max(math.floor(uv[:, 0].min()) - 3, 0)
        u1 = min(math.ceil(uv[:, 0].max()) + 4, self.width)
        v0 = max(math.floor(uv[:, 1].min()) - 3, 0)
        v1 = min(math.ceil(uv[:, 1].max()) + 4, self.height)
        if u1 > u0 and v1 > v0:
            rot = camera_from_board[:3, :3].astype(np.float32)
            t = camera_from_board[:3, 3].astype(np.float32)
            x = self.rays[v0:v1, u0:u1, :, 0]
            y = self.rays[v0:v1, u0:u1, :, 1]
            a0 = rot[0, 0] * x + rot[1, 0] * y + rot[2, 0]  # (R·e_i)·r for the board axes i = x, y, z
            a1 = rot[0, 1] * x + rot[1, 1] * y + rot[2, 1]
            a2 = rot[0, 2] * x + rot[1, 2] * y + rot[2, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                lam = np.float32(rot[:, 2] @ t) / a2
            bx = lam * a0 - np.float32(rot[:, 0] @ t)
            by = lam * a1 - np.float32(rot[:, 1] @ t)
            shade = np.where(lam > 0, board.shade(bx, by), BACKGROUND)
            img[v0:v1, u0:u1] = shade.mean(axis=-1)
        if noise_std > 0:
            if rng is None:
                raise InputError("Camera.render: image noise needs a numpy Generator (rng)")
            img += rng.standard_normal(img.shape, dtype=np.float32) * np.float32(noise_std)
        return np.clip(img + 0.5, 0, 255).astype(np.uint8)


def _rotation_about(axis: np.ndarray, angle: float) -> np.ndarray:
    rot, _ = cv2.Rodrigues(np.asarray(axis, dtype=float) / np.linalg.norm(axis) * angle)
    return rot


def sample_board_poses(
    left: Camera,
    right: Camera,
    right_from_left: np.ndarray,
    baseline: float,
    board: Board,
    views: int,
    rng: np.random.Generator,
    *,
    fill: tuple[float, float] = (0.5, 0.85),
    tilt_deg: tuple[float, float] = (20.0, 50.0),
    roll_deg: float = 15.0,
    margin_px: float = 8.0,
) -> list[np.ndarray]:
    """Seeded target poses ``T_left←board`` (4×4) that both cameras see whole, spread across the field of view.

    Each pose: the target's height fills ``fill`` of the image height (this sets its distance); its centre sits
    at a horizontal position stratified across the views (so the edges of the wide image, where the distortion
    is strongest, are covered) and a random vertical position, in the view of the rig's mid point; it faces the
    rig, tilted by ``tilt_deg`` about a random in-plane axis and rolled by up to ``roll_deg``. Poses that either
    camera does not see whole (``margin_px`` from the edges) are drawn again.

    Raises
    ------
    InputError
        No poses can be found (the baseline too long for the target, or the target too large).
    """
    k = left.k
    f = float(k[0, 0])
    strata = rng.permutation(views)
    poses: list[np.ndarray] = []
    attempts = 0
    u_lo, _, u_hi, _ = left.extent
    for n in range(views):
        for attempt in range(400):
            attempts += 1
            frac = rng.uniform(*fill)
            depth = f * board.outer_size[1] / (frac * left.height)
            q = (strata[n] + rng.uniform()) / views if attempt < 200 else rng.uniform()
            u = u_lo + q * (u_hi - u_lo)  # ideal pixel of the target's centre in the mid-point camera
            v = rng.uniform(0.35, 0.65) * (left.height - 1)
            ray = np.array([(u - k[0, 2]) / f, (v - k[1, 2]) / k[1, 1], 1.0])
            centre = depth * ray + np.array([0.5 * baseline, 0.0, 0.0])  # the mid point is +b/2 along left x
            z = ray / np.linalg.norm(ray)
            x = np.array([1.0, 0.0, 0.0]) - z[0] * z
            x /= np.linalg.norm(x)
            base = np.column_stack([x, np.cross(z, x), z])  # faces the rig, board x ≈ image right
            beta = rng.uniform(0.0, 2.0 * math.pi)
            tilt = _rotation_about(
                np.array([math.cos(beta), math.sin(beta), 0.0]), math.radians(rng.uniform(*tilt_deg))
            )
            roll = _rotation_about(np.array([0.0, 0.0, 1.0]), math.radians(rng.uniform(-roll_deg, roll_deg)))
            rot = base @ tilt @ roll
            pose = np.eye(4)
            pose[:3, :3] = rot
            pose[:3, 3] = centre - rot @ board.centre
            if left.sees(pose, board, margin_px) and right.sees(right_from_left @ pose, board, margin_px):
                poses.append(pose)
                break
        else:
            raise InputError(
                f"calibration: no target pose found that both cameras see whole after {attempts} tries "
                f"(target {board.cols} × {board.rows} inner corners of {board.square:g} m, baseline {baseline:g} m); "
                "allowed: a target that fits both images (smaller square_size or fewer corners for a wide baseline)"
            )
    return poses


def detect_corners(image: np.ndarray, board: Board) -> np.ndarray | None:
    """Checkerboard corners ``(rows·cols, 2)`` float64 in OpenCV's order, or None if not found.

    ``cv2.findChessboardCorners`` (adaptive threshold, normalised), falling back to the much slower
    ``cv2.findChessboardCornersSB`` (Duda & Frese 2018); refined by ``cv2.cornerSubPix`` with a window a quarter
    of the smallest corner spacing (2–7 px half-width). How far the corners land from their true projections on
    the rendered target, and what each detector costs: benchmarks/README.md, "Costs behind design choices".
    """
    found, corners = cv2.findChessboardCorners(
        image, board.pattern_size, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    )
    if not found:
        found, corners = cv2.findChessboardCornersSB(image, board.pattern_size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
        if not found:
            return None
    corners = np.asarray(corners, dtype=np.float32).reshape(-1, 1, 2)
    grid = corners.reshape(board.rows, board.cols, 2)
    spacing = min(
        float(np.linalg.norm(np.diff(grid, axis=1), axis=-1).min()),
        float(np.linalg.norm(np.diff(grid, axis=0), axis=-1).min()),
    )
    half = int(np.clip(spacing / 4.0, 2, 7))
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    corners = cv2.cornerSubPix(image, corners, (half, half), (-1, -1), criteria)
    return corners.reshape(-1, 2).astype(np.float64)


def order_like(detected: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """The detected corners in the board's own order: as found or reversed, whichever is nearer ``expected``.

    A checkerboard's corner list may start at either end (its 180° symmetry); a real target resolves this with a
    marker (ChArUco), the simulation with the pose it drew. Only the labelling is taken from the truth.
    """
    forward = float(np.linalg.norm(detected - expected, axis=1).mean())
    backward = float(np.linalg.norm(detected[::-1] - expected, axis=1).mean())
    return detected if forward <= backward else detected[::-1].copy()


def true_right_from_left(rig: StereoRig) -> np.ndarray:
    """``T_right←left`` (4×4) of the rig's actual cameras, misalignment included (OpenCV axes)."""
    rig = rig if rig.station is not None else rig.replace(station=0.0)  # only the relative pose matters
    return np.linalg.inv(rig.camera_in_trailer("right")) @ rig.camera_in_trailer("left")
