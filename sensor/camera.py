"""The trailer-mounted stereo rig: intrinsics, mounting, misalignment, and camera-axis conventions.

Frames
------
* **World**: ISO 8855 ground frame, X, Y in the road plane, Z up, ground at Z = 0 (on a terrain: X, Y
  horizontal, the ground at the terrain's height, docs/terrain_camera.md).
* **Trailer**: ISO, origin on the ground below the kingpin, x forward, y left, z up; heading
  ψ2 = ψ1 − Γ (on a terrain also lifted and turned by the unit's kinematic pitch and roll,
  :mod:`vehicle_model.terrain_pose`).
* **Camera (OpenCV)**: origin at the optical centre, x right, y down, z forward (the optical axis).
  Image coordinates: pixel (u, v) = (column, row), the centre of the top-left pixel at (0, 0).
* **Camera (OpenGL/pyrender)**: x right, y up, looking down −z. :func:`opencv_to_opengl` is the one
  place that converts.

Mounting (de Saxe & Cebon 2018, §2.2 and §3.1)
----------------------------------------------
The rig's mount point — the midpoint between the two optical centres — sits on the trailer roof at
``station`` metres from the kingpin (negative: behind it; default the trailer's rear,
``params.trailer.rear_x``), ``lateral`` metres to the left and ``mount_height`` above the ground.
The paper's camera-to-vehicle angle ψ_c2v is measured **clockwise** from the trailer's forward
axis: 180° faces rearwards, 90° right, 270° left (the field test's side cameras). In ISO terms
(yaw anticlockwise positive) the cameras face ``−ψ_c2v``. The optical axes are horizontal (no
tilt or roll, the paper's §3.1). The left and right cameras sit at ∓ ``baseline/2`` along the camera
x axis.

Misalignment (the paper's §4.4)
-------------------------------
The right camera may be rotated about its own optical centre by roll φ (about its z axis), pitch θ
(about x) and yaw ψ (about y), composed as in the paper's eq (9): ``R_mis = R_z(φ)·R_y(ψ)·R_x(θ)``,
the orientation of the actual right camera in its ideal frame (``T_ideal←actual``). A world point
then appears in the misaligned image at ``w̃ = K·R_misᵀ·K⁻¹·w̃₀`` (eq (8) with ``R = R_misᵀ``);
the paper's correction of φ = 0.15°, ψ = −0.10° thus undoes a misalignment of roll −0.15°,
yaw +0.10°. Positive yaw turns the optical axis towards the camera's +x (right).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import Field

from vehicle_model.errors import InputError
from vehicle_model.geometry import ChainPose, CombinationPose, kingpin_position, trailer_heading, unit_frame
from vehicle_model.parameters import VehicleParams
from vehicle_model.settings import Settings
from vehicle_model.terrain import Terrain
from vehicle_model.terrain_pose import is_flat, unit_attitude

Which = Literal["left", "right"]

MAX_RENDER_PX = 8192
"""The largest rendered image side [px] (a rig's width or height times its supersampling): the offscreen
framebuffer's size, well inside what OpenGL drivers allocate."""

_CV_TO_GL = np.diag([1.0, -1.0, -1.0, 1.0])


def opencv_to_opengl(pose: np.ndarray) -> np.ndarray:
    """Convert a camera pose between OpenCV axes and OpenGL/pyrender axes.

    OpenCV cameras look down +z with y down; OpenGL cameras look down −z with y up: the two frames
    differ by a rotation of 180° about the camera's x axis. Given ``T_world←camera`` with the camera
    in OpenCV axes, returns ``T_world←camera`` with the camera in OpenGL axes. The conversion is its
    own inverse, so the same function converts back (:func:`opengl_to_opencv` is an alias).

    Parameters
    ----------
    pose : numpy.ndarray
        ``(..., 4, 4)`` homogeneous poses.

    Returns
    -------
    numpy.ndarray
        Poses of the same shape (a new array).
    """
    pose = np.asarray(pose, dtype=float)
    if pose.shape[-2:] != (4, 4):
        raise InputError(f"camera pose must have shape (..., 4, 4), got {pose.shape}")
    return pose @ _CV_TO_GL


opengl_to_opencv = opencv_to_opengl
"""Inverse of :func:`opencv_to_opengl` (the same 180° rotation about x)."""


def rotation_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Camera rotation of de Saxe & Cebon 2018, eq (9): ``R_z(roll)·R_y(yaw)·R_x(pitch)`` (OpenCV axes).

    Parameters
    ----------
    roll, pitch, yaw : float
        Angles [rad] about the optical axis z, the x axis and the y axis.
    """
    cf, sf = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(yaw), math.sin(yaw)
    ct, st = math.cos(pitch), math.sin(pitch)
    rz = np.array([[cf, -sf, 0.0], [sf, cf, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, ct, -st], [0.0, st, ct]])
    return rz @ ry @ rx  # de Saxe & Cebon 2018, eq (9)


_RADIAL = "Brown–Conrady radial coefficient; |k| ≤ 1 covers wide-angle automotive lenses (|k1| ≲ 0.4), no fisheye"
_TANGENTIAL = "Brown–Conrady tangential coefficient; |p| ≤ 0.05 is a lens glued crooked by degrees (≲ 0.005 usual)"


class Lens(Settings):
    """Brown–Conrady distortion coefficients in OpenCV's order ``(k1, k2, p1, p2, k3)`` (dimensionless).

    Parameters
    ----------
    k1, k2, k3 : float
        Radial coefficients of r², r⁴, r⁶ (k1 < 0: barrel distortion, typical of wide-angle lenses).
    p1, p2 : float
        Tangential (decentring) coefficients.
    """

    k1: float = Field(0.0, ge=-1.0, le=1.0, description=_RADIAL)
    k2: float = Field(0.0, ge=-1.0, le=1.0, description=_RADIAL)
    p1: float = Field(0.0, ge=-0.05, le=0.05, description=_TANGENTIAL)
    p2: float = Field(0.0, ge=-0.05, le=0.05, description=_TANGENTIAL)
    k3: float = Field(0.0, ge=-1.0, le=1.0, description=_RADIAL)

    @property
    def coefficients(self) -> np.ndarray:
        """``(5,)`` array ``[k1, k2, p1, p2, k3]``, OpenCV's ``distCoeffs``."""
        return np.array([self.k1, self.k2, self.p1, self.p2, self.k3], dtype=float)

    @property
    def is_zero(self) -> bool:
        """True for an ideal pinhole (all coefficients zero)."""
        return not np.any(self.coefficients)

    def radial_limit(self) -> float:
        """Largest undistorted radius r [normalised] up to which the radial map r ↦ r·(1 + k1r² + k2r⁴ + k3r⁶) rises.

        Beyond it the lens model folds over (two rays land on one pixel); ``inf`` if it never does (up to r = 10).
        """
        r = np.linspace(0.0, 10.0, 20001)
        r2 = r * r
        slope = 1.0 + 3.0 * self.k1 * r2 + 5.0 * self.k2 * r2**2 + 7.0 * self.k3 * r2**3  # d/dr of the radial map
        bad = np.nonzero(slope <= 0.0)[0]
        return math.inf if bad.size == 0 else float(r[bad[0]])


@dataclass(frozen=True)
class Misalignment:
    """Rotation of the right camera about its optical centre relative to its ideal pose [rad].

    Use :meth:`from_degrees` at the user interface.
    """

    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        for name in ("roll", "pitch", "yaw"):
            v = getattr(self, name)
            if not (math.isfinite(v) and abs(v) <= math.radians(20.0)):
                raise InputError(f"rig.misalignment.{name} = {math.degrees(v):.4g}° is out of range; allowed: ±20°")

    @classmethod
    def from_degrees(cls, roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0) -> Misalignment:
        """Misalignment from angles in degrees."""
        return cls(math.radians(roll), math.radians(pitch), math.radians(yaw))

    @property
    def rotation(self) -> np.ndarray:
        """``R_mis`` (3×3): the actual right camera's axes in its ideal frame (the paper's eq (9))."""
        return rotation_rpy(self.roll, self.pitch, self.yaw)

    @property
    def is_zero(self) -> bool:
        return self.roll == 0.0 and self.pitch == 0.0 and self.yaw == 0.0


@dataclass(frozen=True)
class StereoRig:
    """A horizontal stereo pair on the trailer roof (defaults: the paper's §3.1).

    Parameters
    ----------
    width, height : int
        Image size [px] (1344 × 391).
    hfov : float
        Horizontal field of view [rad] (100°).
    baseline : float
        Distance between the optical centres [m] (0.5 m).
    station : float or None
        Longitudinal position of the mount from the kingpin [m], negative behind it; None: the
        trailer's rear (``params.trailer.rear_x``).
    lateral : float
        Lateral offset of the mount [m], left positive.
    mount_height : float
        Height of the optical centres above the ground [m] (3.0 m).
    psi_c2v : float
        Camera-to-vehicle angle [rad], clockwise from the trailer's forward axis (π: rear-facing).
    misalignment : Misalignment
        Rotation of the right camera (the paper's §4.4).
    noise_std : float
        Standard deviation of additive Gaussian image noise [grey levels].
    exposure_std : float
        Relative standard deviation of a per-frame, per-camera brightness gain (exposure and
        lighting variation), e.g. 0.05 for ±5 %.
    znear, zfar : float
        Clipping distances of the renderer [m].
    unit : int
        The towed unit the rig is mounted on (1: the first; its kingpin is the origin of :attr:`station`).
    supersample : int
        Samples per pixel side of the rendering, 1 to 4: the renderer draws ``supersample`` × the image size and
        averages each ``supersample × supersample`` block (a sensor's pixel integrating the light over its area), so
        an edge that moves by a fraction of a pixel moves the grey levels by that fraction; 1: one sample at the
        pixel centre.

    Use :meth:`from_degrees` to give angles in degrees.
    """

    width: int = 1344
    height: int = 391
    hfov: float = math.radians(100.0)
    baseline: float = 0.5
    station: float | None = None
    lateral: float = 0.0
    mount_height: float = 3.0
    psi_c2v: float = math.pi
    misalignment: Misalignment = Misalignment()
    noise_std: float = 0.0
    exposure_std: float = 0.0
    znear: float = 0.5
    zfar: float = 3000.0
    unit: int = 1
    supersample: int = 1

    def __post_init__(self) -> None:
        checks = [
            ("width", 16 <= self.width <= 8192, "[16, 8192] px"),
            ("height", 16 <= self.height <= 8192, "[16, 8192] px"),
            ("hfov", math.radians(1.0) <= self.hfov <= math.radians(170.0), "[1°, 170°]"),
            ("baseline", 0.0 < self.baseline <= 10.0, "(0, 10] m"),
            ("station", self.station is None or -50.0 <= self.station <= 20.0, "[-50, 20] m or None (trailer rear)"),
            ("lateral", abs(self.lateral) <= 5.0, "[-5, 5] m"),
            ("mount_height", 0.2 <= self.mount_height <= 10.0, "[0.2, 10] m"),
            ("psi_c2v", math.isfinite(self.psi_c2v), "a finite angle"),
            ("noise_std", 0.0 <= self.noise_std <= 100.0, "[0, 100] grey levels"),
            ("exposure_std", 0.0 <= self.exposure_std <= 0.5, "[0, 0.5]"),
            ("znear", 0.01 <= self.znear < self.zfar, "0.01 m ≤ znear < zfar"),
            ("unit", isinstance(self.unit, int) and 1 <= self.unit <= 16, "a towed unit, 1 to 16"),
            ("supersample", isinstance(self.supersample, int) and 1 <= self.supersample <= 4, "an integer, 1 to 4"),
            (
                "supersample",
                max(self.width, self.height) * self.supersample <= MAX_RENDER_PX,
                f"width and height × supersample ≤ {MAX_RENDER_PX} px (the rendered size)",
            ),
        ]
        for name, ok, allowed in checks:
            if not ok:
                value = getattr(self, name)
                if name == "hfov":
                    value = f"{math.degrees(value):.4g}°"
                raise InputError(f"rig.{name} = {value!r} is out of range; allowed: {allowed}")
        if not isinstance(self.misalignment, Misalignment):
            raise InputError("rig.misalignment must be a Misalignment (use Misalignment.from_degrees)")

    @classmethod
    def from_degrees(
        cls,
        *,
        hfov_deg: float = 100.0,
        psi_c2v_deg: float = 180.0,
        roll_deg: float = 0.0,
        pitch_deg: float = 0.0,
        yaw_deg: float = 0.0,
        **kwargs,
    ) -> StereoRig:
        """A rig with its angles in degrees (field of view, ψ_c2v, right-camera misalignment).

        Other keyword arguments are passed through (``baseline``, ``station``, ``width``, …).
        """
        try:
            return cls(
                hfov=math.radians(hfov_deg),
                psi_c2v=math.radians(psi_c2v_deg),
                misalignment=Misalignment.from_degrees(roll_deg, pitch_deg, yaw_deg),
                **kwargs,
            )
        except TypeError as exc:
            raise InputError(f"unknown stereo-rig setting: {exc}") from None

    def replace(self, **changes) -> StereoRig:
        """A copy with some fields changed (SI units)."""
        return dataclasses.replace(self, **changes)

    # ---------------------------------------------------------------------------------------------
    @property
    def focal_length(self) -> float:
        """Focal length [px]: ``f = (w/2) / tan(hfov/2)`` (square pixels)."""
        return 0.5 * self.width / math.tan(0.5 * self.hfov)

    @property
    def principal_point(self) -> tuple[float, float]:
        """Principal point at the image centre, OpenCV pixel convention: ``((w−1)/2, (h−1)/2)``."""
        return 0.5 * (self.width - 1), 0.5 * (self.height - 1)

    @property
    def vfov(self) -> float:
        """Vertical field of view [rad]."""
        return 2.0 * math.atan(0.5 * self.height / self.focal_length)

    def intrinsics(self) -> np.ndarray:
        """Camera matrix K (3×3), identical for both cameras (pinhole, no distortion)."""
        f = self.focal_length
        cx, cy = self.principal_point
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])

    def projection_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """KITTI-style rectified projections ``P0 = K·[I | 0]`` and ``P1 = K·[I | −b·e_x]``.

        ``P1[0, 3] = −f·b``: a point at depth Z has disparity ``u_left − u_right = f·b/Z``.
        """
        k = self.intrinsics()
        p0 = np.hstack([k, np.zeros((3, 1))])
        p1 = np.hstack([k, k @ np.array([[-self.baseline], [0.0], [0.0]])])
        return p0, p1

    def facing_yaw(self) -> float:
        """ISO yaw of the optical axes in the trailer frame [rad]: ``−ψ_c2v``."""
        return -self.psi_c2v

    def resolve_station(self, params: VehicleParams | None = None) -> float:
        """The mount station [m]: :attr:`station`, or the rear of the towed unit :attr:`unit` of ``params``."""
        if self.station is not None:
            return float(self.station)
        if params is None:
            raise InputError("rig.station is None (the trailer's rear): pass the vehicle params to resolve it")
        if not 1 <= self.unit <= len(params.trailers):
            raise InputError(f"rig.unit = {self.unit}: a towed unit of {params.name!r}, 1 to {len(params.trailers)}")
        return float(params.trailers[self.unit - 1].rear_x)

    def mount_rotation(self) -> np.ndarray:
        """``R_trailer←camera`` (3×3) of the ideal cameras: columns are the camera's x, y, z axes."""
        a = self.facing_yaw()
        z = np.array([math.cos(a), math.sin(a), 0.0])  # optical axis, horizontal
        y = np.array([0.0, 0.0, -1.0])  # image down = trailer down
        x = np.cross(y, z)  # image right
        return np.column_stack([x, y, z])

    def camera_in_trailer(self, which: Which, params: VehicleParams | None = None) -> np.ndarray:
        """Pose ``T_trailer←camera`` (4×4) of one camera, OpenCV camera axes.

        Parameters
        ----------
        which : {"left", "right"}
            The camera. The right camera includes the :attr:`misalignment`.
        params : VehicleParams, optional
            Needed only when :attr:`station` is None (mount at the trailer's rear).
        """
        if which not in ("left", "right"):
            raise InputError(f"camera must be 'left' or 'right', got {which!r}")
        r = self.mount_rotation()
        mount = np.array([self.resolve_station(params), self.lateral, self.mount_height])
        sign = -1.0 if which == "left" else 1.0
        t = np.eye(4)
        t[:3, :3] = r
        t[:3, 3] = mount + sign * 0.5 * self.baseline * r[:, 0]
        if which == "right" and not self.misalignment.is_zero:
            t[:3, :3] = r @ self.misalignment.rotation  # rotation about its own optical centre
        return t

    def camera_in_world(
        self, params: VehicleParams, pose: CombinationPose | ChainPose, which: Which, terrain: Terrain | None = None
    ) -> np.ndarray:
        """Pose ``T_world←camera`` of one camera at a combination pose, OpenCV camera axes.

        Parameters
        ----------
        params : VehicleParams
            The combination (kingpin positions, the unit's rear).
        pose : CombinationPose or ChainPose
            Tractor CG position [m], tractor heading ψ1 [rad] and articulation Γ [rad]
            (:attr:`vehicle_model.simulator.VehicleState.pose`), or every coupling's articulation
            (:attr:`~vehicle_model.simulator.VehicleState.chain_pose`, needed for a rig on a unit behind the first);
            fields that are arrays of one shape ``S`` give poses of shape ``S + (4, 4)``.
        which : {"left", "right"}
            The camera.
        terrain : Terrain, optional
            The ground the combination stands on: the unit's frame is lifted to its height and turned by its pitch
            and roll (:func:`vehicle_model.terrain_pose.unit_attitude`, docs/terrain_camera.md). ``None`` or a
            :class:`~vehicle_model.terrain.FlatTerrain`: the level road, the pose exactly as without it.
        """
        if not is_flat(terrain):
            return self._camera_on_terrain(params, pose, which, terrain)
        if self.unit == 1 and isinstance(pose, ChainPose):
            pose = pose.combination
        if self.unit == 1:
            x, y, psi1, gamma = pose
            kp = kingpin_position(params, x, y, psi1)
            psi2 = np.asarray(trailer_heading(psi1, gamma))
        else:
            kp, psi2 = unit_frame(params, pose, self.unit)
            psi2 = np.asarray(psi2)
        c, s = np.cos(psi2), np.sin(psi2)
        world_trailer = np.zeros((*psi2.shape, 4, 4))
        world_trailer[..., 0, 0], world_trailer[..., 0, 1] = c, -s
        world_trailer[..., 1, 0], world_trailer[..., 1, 1] = s, c
        world_trailer[..., 2, 2] = world_trailer[..., 3, 3] = 1.0
        world_trailer[..., 0, 3], world_trailer[..., 1, 3] = kp[..., 0], kp[..., 1]
        return world_trailer @ self.camera_in_trailer(which, params)

    def _camera_on_terrain(
        self, params: VehicleParams, pose: CombinationPose | ChainPose, which: Which, terrain: Terrain
    ) -> np.ndarray:
        """:meth:`camera_in_world` on a terrain: the unit's frame at its kinematic height, pitch and roll."""
        origin, _ = unit_frame(params, pose, self.unit)
        att = unit_attitude(params, pose, terrain, self.unit)
        world_unit = np.zeros((*np.shape(att.z), 4, 4))
        world_unit[..., :3, :3] = att.rotation
        world_unit[..., 0, 3], world_unit[..., 1, 3] = origin[..., 0], origin[..., 1]
        world_unit[..., 2, 3] = att.z
        world_unit[..., 3, 3] = 1.0
        return world_unit @ self.camera_in_trailer(which, params)

    def misalignment_homography(self) -> np.ndarray:
        """``H = K·R_misᵀ·K⁻¹``: maps ideal right-image pixels to the misaligned ones (the paper's eq (8))."""
        k = self.intrinsics()
        return k @ self.misalignment.rotation.T @ np.linalg.inv(k)


def project(k: np.ndarray, camera_from_world: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Pixel coordinates (OpenCV convention) of world points ``(n, 3)`` seen by a camera.

    Parameters
    ----------
    k : numpy.ndarray
        Camera matrix (3×3).
    camera_from_world : numpy.ndarray
        ``T_camera←world`` (4×4), OpenCV axes (the inverse of a camera pose).
    points : numpy.ndarray
        ``(n, 3)`` world points.

    Returns
    -------
    numpy.ndarray
        ``(n, 2)`` pixels ``(u, v)``; NaN for points behind the camera.
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    pc = p @ camera_from_world[:3, :3].T + camera_from_world[:3, 3]
    uvw = pc @ k.T
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = uvw[:, :2] / uvw[:, 2:3]
    uv[pc[:, 2] <= 0] = np.nan
    return uv
