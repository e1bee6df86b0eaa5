"""Synthetic data with exact ground truth for testing the visual odometry.

(a) :func:`random_point_matches` — random 3-D points and a known motion give exact (noise-free)
    stereo projections in both pairs, for the motion estimator alone.
(b) :func:`render_planar_pair` / :func:`planar_sequence` — textured planar scenes rendered exactly
    without any GL: a plane seen by a pinhole camera is related to its texture image by a homography
    (H = K·R_cw·[A − c·e₃ᵀ] for the plane point A·(s, t, 1)), so each view is a ``cv2.warpPerspective``
    of a procedural texture. The scene is a textured ground plane and optionally a vertical textured
    wall ahead; each pixel shows the nearer surface (sky, a flat grey, elsewhere). Views are rendered
    at 2× and box-downsampled for anti-aliasing.

Axes: cameras follow OpenCV (x right, y down, z forward). The world frame is the level start frame of
the camera: X right, Y down (gravity), Z forward; the ground is the plane Y = +height. Poses are
camera-to-world 4×4 matrices T_wc; the ground-truth libviso2 Tr_delta between frames k−1 and k is
inv(T_wc,k)·T_wc,k−1 (docs/visual_odometry.md §10).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from sensor.vo.config import VOConfig

__all__ = [
    "PlanarScene",
    "PlanarSequence",
    "StereoRig",
    "backproject",
    "camera_pose",
    "make_texture",
    "planar_sequence",
    "project_world",
    "random_point_matches",
    "relative_motion",
    "render_planar_pair",
    "right_pose",
]

_SKY = 170  # grey level of pixels that see neither plane


@dataclass(frozen=True)
class StereoRig:
    """Ideal rectified pinhole stereo rig (defaults: de Saxe & Cebon 2018 §3.1, docs/design.md §8).

    Parameters
    ----------
    width, height : int
        Image size [px].
    horizontal_fov : float
        Horizontal field of view [rad].
    baseline : float
        Baseline [m]; the right camera is at +baseline along the left camera's x axis.
    """

    width: int = 1344
    height: int = 391
    horizontal_fov: float = math.radians(100.0)
    baseline: float = 0.5

    @property
    def f(self) -> float:
        """Focal length [px]."""
        return 0.5 * self.width / math.tan(0.5 * self.horizontal_fov)

    @property
    def cu(self) -> float:
        """Principal column [px] (image centre, pixel centres at integers)."""
        return 0.5 * (self.width - 1)

    @property
    def cv(self) -> float:
        """Principal row [px]."""
        return 0.5 * (self.height - 1)

    @property
    def K(self) -> np.ndarray:
        """3×3 camera matrix."""
        return np.array([[self.f, 0.0, self.cu], [0.0, self.f, self.cv], [0.0, 0.0, 1.0]])

    def vo_config(self, **overrides: object) -> VOConfig:
        """A :class:`VOConfig` with this rig's calibration and libviso2 defaults otherwise."""
        return VOConfig(f=self.f, cu=self.cu, cv=self.cv, baseline=self.baseline, **overrides)  # type: ignore[arg-type]


# ---------------------------------------------------------------------------- (a) random points


def relative_motion(pose_prev: np.ndarray, pose_cur: np.ndarray) -> np.ndarray:
    """libviso2's Tr_delta = inv(T_wc,k)·T_wc,k−1 from two camera-to-world poses (docs/visual_odometry.md §10)."""
    return np.linalg.solve(pose_cur, pose_prev)


def random_point_matches(
    motion: np.ndarray,
    config: VOConfig,
    n: int,
    rng: np.random.Generator,
    depth: tuple[float, float] = (4.0, 40.0),
    size: tuple[int, int] = (1344, 391),
) -> tuple[np.ndarray, np.ndarray]:
    """Exact stereo projections of random points before and after a known motion.

    Parameters
    ----------
    motion : numpy.ndarray
        4×4 Tr_delta mapping previous-left-camera points into the current left-camera frame.
    config : VOConfig
        Calibration.
    n : int
        Number of points.
    rng : numpy.random.Generator
        Random source.
    depth : tuple[float, float]
        Depth range [m] of the points in the previous frame.
    size : tuple[int, int]
        (width, height) [px]: every projection lies inside the image.

    Returns
    -------
    xy, points : numpy.ndarray
        (n, 8) matches (u1p, v1p, u2p, v2p, u1c, v1c, u2c, v2c) [px] and (n, 3) points [m] in the
        previous left-camera frame.
    """
    width, height = size
    kept: list[np.ndarray] = []
    points_kept: list[np.ndarray] = []
    count = 0
    while count < n:
        m = 4 * n
        z = rng.uniform(*depth, m)
        u = rng.uniform(0, width - 1, m)
        v = rng.uniform(0, height - 1, m)
        points = np.stack([(u - config.cu) * z / config.f, (v - config.cv) * z / config.f, z], axis=1)
        moved = points @ motion[:3, :3].T + motion[:3, 3]
        prev = _stereo_projection(points, config)
        cur = _stereo_projection(moved, config)
        xy = np.concatenate([prev, cur], axis=1)
        inside = (
            (moved[:, 2] > 0.5)
            & (xy[:, 0::2] >= 0).all(axis=1)
            & (xy[:, 0::2] <= width - 1).all(axis=1)
            & (xy[:, 1::2] >= 0).all(axis=1)
            & (xy[:, 1::2] <= height - 1).all(axis=1)
        )
        kept.append(xy[inside])
        points_kept.append(points[inside])
        count += int(inside.sum())
    return np.concatenate(kept)[:n], np.concatenate(points_kept)[:n]


def _stereo_projection(points: np.ndarray, config: VOConfig) -> np.ndarray:
    x, y, z = points.T
    u1 = config.f * x / z + config.cu
    v1 = config.f * y / z + config.cv
    return np.stack([u1, v1, u1 - config.f * config.baseline / z, v1], axis=1)


# ------------------------------------------------------------------------------ (b) planar scenes


def make_texture(size: int, rng: np.random.Generator, smoothing: float = 0.0) -> np.ndarray:
    """Procedural texture: multi-scale smooth noise plus blocky, corner-like speckle.

    Parameters
    ----------
    size : int
        Side length [texels] (square, power of two recommended).
    rng : numpy.random.Generator
        Random source.
    smoothing : float
        Standard deviation [texels] of a final Gaussian blur (0: none). Blurring removes the finest
        extrema: in the default sequence's views about 8 500 features with 0, 6 000 without the
        wall, 4 000 without the wall and with 4.

    Returns
    -------
    numpy.ndarray
        (size, size) uint8.
    """
    out = np.zeros((size, size), dtype=np.float32)
    # Smooth value noise, octaves from 256 down to 4 texels.
    cell = 256
    amplitude = 1.0
    while cell >= 4:
        coarse = rng.standard_normal((size // cell + 1, size // cell + 1)).astype(np.float32)
        up = cv2.resize(coarse, ((size // cell + 1) * cell,) * 2, interpolation=cv2.INTER_CUBIC)
        out += amplitude * up[:size, :size]
        cell //= 2
        amplitude *= 0.8
    out *= 18.0 / out.std()
    # Blocky speckle (random-valued squares → sharp corners) at two scales.
    for block, weight in ((6, 30.0), (3, 15.0)):
        coarse = rng.standard_normal((size // block + 1, size // block + 1)).astype(np.float32)
        up = cv2.resize(coarse, ((size // block + 1) * block,) * 2, interpolation=cv2.INTER_NEAREST)
        out += weight * up[:size, :size]
    # Sparse bright and dark dots (blob-like).
    dots = np.zeros((size, size), dtype=np.float32)
    k = size * size // 200
    rows, cols = rng.integers(0, size, k), rng.integers(0, size, k)
    dots[rows, cols] = rng.choice([-1.0, 1.0], k) * 90.0
    out += cv2.GaussianBlur(dots, (0, 0), 1.0) * 4.0
    if smoothing > 0:
        out = cv2.GaussianBlur(out, (0, 0), smoothing, borderType=cv2.BORDER_REFLECT)
    return np.clip(out + 128.0, 0, 255).astype(np.uint8)


@dataclass(frozen=True, eq=False)
class PlanarScene:
    """A textured ground plane and an optional textured vertical wall.

    Parameters
    ----------
    texture : numpy.ndarray
        (T, T) uint8 texture, tiled periodically over both planes.
    texel : float
        Texel size [m].
    height : float
        Height [m] of the camera start position above the ground (ground plane Y = +height).
    wall_distance : float | None
        Distance [m] of the wall plane Z = wall_distance ahead of the start, None for no wall.
    """

    texture: np.ndarray
    texel: float = 0.025
    height: float = 3.0
    wall_distance: float | None = 60.0

    @cached_property
    def pyramid(self) -> list[np.ndarray]:
        """Mip levels of the texture (Gaussian pyramid, level k has texels 2^k times larger)."""
        levels = [self.texture]
        while len(levels) < 7 and min(levels[-1].shape) >= 16:
            levels.append(cv2.pyrDown(levels[-1]))
        return levels

    @classmethod
    def procedural(cls, seed: int = 0, size: int = 2048, smoothing: float = 0.0, **kwargs: object) -> PlanarScene:
        """Scene with a :func:`make_texture` texture from ``seed`` (``smoothing`` in texels)."""
        texture = make_texture(size, np.random.default_rng(seed), smoothing)
        return cls(texture=texture, **kwargs)  # type: ignore[arg-type]


def _render_view(scene: PlanarScene, rig: StereoRig, pose: np.ndarray, supersample: int) -> np.ndarray:
    """One camera image for camera-to-world pose ``pose``.

    Each plane is a homography of the texture. Anti-aliasing: every pixel samples the mip level whose
    texels match its footprint on the plane, √area = λ/(f·texel·√|n·d|) texels for the ray
    c + λ·d (d with unit z in the camera), and the image is rendered at ``supersample``× and
    box-downsampled.
    """
    s = supersample
    w, h = rig.width * s, rig.height * s
    f_ss = s * rig.f
    k = np.array([[f_ss, 0.0, s * rig.cu + 0.5 * (s - 1)], [0.0, f_ss, s * rig.cv + 0.5 * (s - 1)], [0, 0, 1]])
    r_wc, centre = pose[:3, :3], pose[:3, 3]
    r_cw = r_wc.T
    t = scene.texel
    half = 0.5 * scene.texture.shape[0] * t
    # Per-pixel rays in the world frame and their parameter λ at each plane.
    x = (np.arange(w, dtype=np.float64) - k[0, 2]) / f_ss
    y = (np.arange(h, dtype=np.float64) - k[1, 2]) / f_ss
    dy = r_wc[1, 0] * x[None, :] + r_wc[1, 1] * y[:, None] + r_wc[1, 2]
    dz = r_wc[2, 0] * x[None, :] + r_wc[2, 1] * y[:, None] + r_wc[2, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        surfaces = [(np.where(dy > 1e-9, (scene.height - centre[1]) / dy, np.inf), dy,
                     np.array([[t, 0, -half], [0, 0, scene.height], [0, t, -half]]))]  # fmt: skip
        if scene.wall_distance is not None:
            lam_wall = np.where(dz > 1e-9, (scene.wall_distance - centre[2]) / dz, np.inf)
            surfaces.append(
                (lam_wall, dz, np.array([[t, 0, -half], [0, t, -0.37 * half], [0, 0, scene.wall_distance]]))
            )
    image = np.full((h, w), float(_SKY), dtype=np.float32)
    pyramid = scene.pyramid
    for i, (lam, cosine, plane) in enumerate(surfaces):
        nearest = lam if len(surfaces) == 1 else np.minimum(lam, surfaces[1 - i][0])
        visible = np.isfinite(lam) & (lam > 0) & (lam <= nearest)
        if not visible.any():
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            footprint = lam / (f_ss * t * np.sqrt(np.abs(cosine)))
        level = np.clip(np.floor(np.log2(np.maximum(footprint, 1.0))), 0, len(pyramid) - 1).astype(np.int64)
        level[~visible] = -1
        homography = k @ r_cw @ (plane - np.outer(centre, [0.0, 0.0, 1.0]))
        for lv in np.flatnonzero(np.bincount(level[visible], minlength=len(pyramid))):
            mask = level == lv
            rows = np.flatnonzero(mask.any(axis=1))
            r0, r1 = int(rows[0]), int(rows[-1]) + 1
            shift = np.array([[1.0, 0, 0], [0, 1.0, -r0], [0, 0, 1.0]])
            scale = np.diag([2.0**lv, 2.0**lv, 1.0])  # level-lv texel i sits at level-0 texel 2^lv·i
            warped = cv2.warpPerspective(
                pyramid[lv], shift @ homography @ scale, (w, r1 - r0), flags=cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_WRAP,
            )  # fmt: skip
            sub = mask[r0:r1]
            image[r0:r1][sub] = warped[sub]
    if s > 1:
        image = cv2.resize(image, (rig.width, rig.height), interpolation=cv2.INTER_AREA)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def render_planar_pair(
    scene: PlanarScene, rig: StereoRig, pose: np.ndarray, supersample: int = 2
) -> tuple[np.ndarray, np.ndarray]:
    """Render the left and right images of the rig at left-camera pose ``pose`` (camera-to-world).

    Parameters
    ----------
    scene : PlanarScene
        The scene.
    rig : StereoRig
        Cameras.
    pose : numpy.ndarray
        4×4 camera-to-world pose T_wc of the left camera.
    supersample : int
        Render at this multiple of the resolution and box-downsample (anti-aliasing).

    Returns
    -------
    left, right : numpy.ndarray
        (height, width) uint8 images.
    """
    return _render_view(scene, rig, pose, supersample), _render_view(scene, rig, right_pose(rig, pose), supersample)


def backproject(scene: PlanarScene, rig: StereoRig, pose: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """World points seen at pixels (u, v) of a camera at pose T_wc (nearest plane; NaN for sky).

    Parameters
    ----------
    scene : PlanarScene
        The scene.
    rig : StereoRig
        Intrinsics.
    pose : numpy.ndarray
        4×4 camera-to-world pose of the camera.
    u, v : numpy.ndarray
        Pixel coordinates [px].

    Returns
    -------
    numpy.ndarray
        (N, 3) world points [m].
    """
    rays = np.stack([(np.asarray(u, float) - rig.cu) / rig.f, (np.asarray(v, float) - rig.cv) / rig.f, np.ones(len(u))])
    d = pose[:3, :3] @ rays  # (3, N) world directions
    centre = pose[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.where(d[1] > 1e-12, (scene.height - centre[1]) / d[1], np.inf)
        if scene.wall_distance is not None:
            lam = np.minimum(lam, np.where(d[2] > 1e-12, (scene.wall_distance - centre[2]) / d[2], np.inf))
    lam = np.where(np.isfinite(lam) & (lam > 0), lam, np.nan)
    return (centre[:, None] + d * lam).T


def project_world(rig: StereoRig, pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Pixel coordinates (N, 2) of world points in a camera at pose T_wc."""
    cam = (points - pose[:3, 3]) @ pose[:3, :3]
    return np.stack([rig.f * cam[:, 0] / cam[:, 2] + rig.cu, rig.f * cam[:, 1] / cam[:, 2] + rig.cv], axis=1)


def right_pose(rig: StereoRig, pose: np.ndarray) -> np.ndarray:
    """Pose of the right camera for left-camera pose ``pose`` (+baseline along the camera x axis)."""
    out = pose.copy()
    out[:3, 3] = pose[:3, 3] + pose[:3, 0] * rig.baseline
    return out


def camera_pose(x: float, z: float, yaw: float, pitch: float) -> np.ndarray:
    """Camera-to-world pose at (x, 0, z) with heading ``yaw`` [rad] (about world −Y, i.e. to the right
    for positive yaw in these y-down axes) and ``pitch`` [rad] down."""
    cy, sy = math.cos(yaw), math.sin(yaw)
    cp, sp = math.cos(pitch), math.sin(pitch)
    r_yaw = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    r_pitch = np.array([[1, 0, 0], [0, cp, sp], [0, -sp, cp]])  # z axis tilts towards +Y (down)
    pose = np.eye(4)
    pose[:3, :3] = r_yaw @ r_pitch
    pose[:3, 3] = [x, 0.0, z]
    return pose


@dataclass(frozen=True, eq=False)
class PlanarSequence:
    """A rendered stereo sequence with its ground truth.

    Attributes
    ----------
    left, right : list[numpy.ndarray]
        Images per frame.
    poses : numpy.ndarray
        (n, 4, 4) camera-to-world poses of the left camera.
    rig : StereoRig
        Cameras.
    scene : PlanarScene
        The scene.
    """

    left: list[np.ndarray]
    right: list[np.ndarray]
    poses: np.ndarray
    rig: StereoRig
    scene: PlanarScene

    def true_motion(self, k: int) -> np.ndarray:
        """Ground-truth Tr_delta from frame k−1 to frame k."""
        return relative_motion(self.poses[k - 1], self.poses[k])


def planar_sequence(
    n_frames: int,
    step: float = 0.5,
    yaw_rate: float = math.radians(1.0),
    pitch: float = math.radians(8.0),
    rig: StereoRig | None = None,
    scene: PlanarScene | None = None,
    supersample: int = 2,
) -> PlanarSequence:
    """Camera moving forward ``step`` m per frame while turning ``yaw_rate`` rad per frame.

    Parameters
    ----------
    n_frames : int
        Number of frames.
    step : float
        Forward distance per frame [m].
    yaw_rate : float
        Heading change per frame [rad] (positive: turning right, y-down axes).
    pitch : float
        Downward pitch of the camera [rad].
    rig : StereoRig | None
        Cameras (default 1344×391, 100° field of view, 0.5 m baseline).
    scene : PlanarScene | None
        Scene (default procedural texture seed 0, camera 3 m above the ground, wall at 60 m).
    supersample : int
        Anti-aliasing factor of the renderer.

    Returns
    -------
    PlanarSequence
    """
    rig = rig or StereoRig()
    scene = scene or PlanarScene.procedural()
    poses = []
    x = z = yaw = 0.0
    for _ in range(n_frames):
        poses.append(camera_pose(x, z, yaw, pitch))
        # Advance along the mean heading of the step (arc chord).
        mid = yaw + 0.5 * yaw_rate
        x += step * math.sin(mid)
        z += step * math.cos(mid)
        yaw += yaw_rate
    pairs = [render_planar_pair(scene, rig, p, supersample) for p in poses]
    return PlanarSequence(
        left=[p[0] for p in pairs], right=[p[1] for p in pairs], poses=np.array(poses), rig=rig, scene=scene
    )
