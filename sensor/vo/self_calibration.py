"""Online stereo self-calibration of the right camera's rotation from the odometry's own stereo matches.

de Saxe & Cebon 2018 (§4.4) found the sensor ruled by sub-0.2° rotations of the right camera about its optical
centre and removed them by hand with the homography of their eq (8). This estimator finds the rotation while
driving and hands back the eq (8) correction ``K·R̂·K⁻¹`` for the next frame's right image.

Model (first order in the angles)
---------------------------------
A right camera rotated by ``R = R_z(φ)·R_y(ψ)·R_x(θ)`` (the paper's eq (9); roll φ about z, pitch θ about x, yaw ψ
about y, OpenCV axes) sees the ideal right image moved by ``K·Rᵀ·K⁻¹`` (the paper's eq (8),
:meth:`sensor.camera.StereoRig.misalignment_homography`). With ``R ≈ I + [ω]×``, ``ω = (θ, ψ, φ)`` and the
normalised coordinates ``x = (u − c_u)/f``, ``y = (v − c_v)/f`` of the ideal right point, the ray
``p = (x, y, 1)`` becomes ``p − ω × p`` and, after division by its third component,

    x' = x − ψ·(1 + x²) + φ·y + θ·x·y,            (SC1)
    y' = y + θ·(1 + y²) − φ·x − ψ·x·y.            (SC2)

Rectified stereo has ``y_l = y`` and ``x_l − x = B/Z`` (baseline ``B``, depth ``Z`` in the left camera), so a
stereo match (u_l, v_l, u_r, v_r) gives

* a **vertical disparity** (every match): ``f·(y'_r − y_l) = f·[θ(1 + y²) − φx − ψxy]`` (SC2) — roll, pitch and,
  weakly through ``x·y``, yaw, with no scale needed;
* a **horizontal disparity offset**: ``f·(x_l − x'_r) = f·B/Z + f·[ψ(1 + x²) − φy − θxy]`` (SC1) — the yaw
  term is a disparity offset that looks exactly like a change of depth, so it needs a known depth.

Scale: the road plane
---------------------
The depth is fixed by the camera's mounting height above the road plane, which the trailer knows to the
millimetre (``camera.mount_height``) and which holds whatever the wheels do: a road point on the ray ``p_l``
lies on ``n·X = h`` (``n`` the downward unit normal in left-camera axes, ``h`` the height), so
``B/Z = B·(n·p_l)/h`` and each ground match measures the yaw offset directly. Points are taken for road points
when their disparity is within ``ground_tolerance`` of the plane's (a relative height error) and the plane's
disparity is at least ``min_ground_disparity_px``. The alternative, the distance travelled from the trailer's
wheel speed against the odometry's translation, would tie the estimate to the wheels — longitudinal slip and a
tyre radius that varies with load and pressure by 1–2 %, while 0.02° of yaw is a 0.35–0.7 % depth change at
5–10 m on a 0.5 m baseline — and the sensor's point (the paper's §1.2) is its independence from the wheels.

Estimator
---------
The images the odometry sees are already corrected by the previous estimate ``ω̂₀``, so a match measures the
residual ``δ = ω − ω̂₀`` (SC1–SC2, rows ``z = A·δ``); the rows ``A·ω = z + A·ω̂₀`` are pseudo-measurements of the
absolute angles (exact at the fixed point ``δ = 0``). Recursive least squares with exponential forgetting
``λ`` (Ljung & Söderström 1983, §2.2; information form, one batch per frame) weighs them:

    Λ_k = λ·Λ_{k−1} + Aᵀ·W·A,   η_k = λ·η_{k−1} + Aᵀ·W·(z + A·ω̂₀),   ω̂_k = Λ_k⁻¹·η_k,    (SC3)

so the memory is about ``1/(1 − λ)`` frames and a slow twist is tracked. ``W`` are Huber weights (Huber 1981)
on residuals scaled by a robust (MAD) scale per row kind, found by a few IRLS passes, over the squared noise
floor ``noise_px`` (so a frame after a step change carries its full information), and rows beyond
``reject_sigma`` scales get weight 0. ``sqrt(diag Λ⁻¹)`` is the quality figure (the angles' standard
deviation under the model).

The mount's twist as a term of the model (``twist_regressor``, opt-in) is :mod:`sensor.vo.twist_calibration`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import Field

from vehicle_model.settings import Settings

__all__ = [
    "SELF_CALIBRATION_COLUMNS",
    "RoadPlane",
    "SelfCalibrationSettings",
    "SelfCalibrationStep",
    "StereoSelfCalibration",
    "stereo_rows",
]

SELF_CALIBRATION_COLUMNS: tuple[str, ...] = (
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "sigma_deg",
    "residual_px",
    "rows",
    "ground",
)
"""Per frame: the estimated angles after the frame [°], the largest standard deviation of the three [°], the
RMS vertical-disparity residual of the used matches [px], the rows used and how many were road points."""

MAD_SIGMA = 1.4826  # MAD → standard deviation of a normal distribution

MAX_TWIST_DEG_PER_MPS2 = 1.0
"""The gain estimate is clipped to ± this per axis [°/(m/s²)] (the bound of :mod:`sensor.mount_flex`'s twist)."""


class SelfCalibrationSettings(Settings):
    """Parameters of :class:`StereoSelfCalibration`, each with its range and the reason for it.

    Attributes
    ----------
    forgetting : float
        λ of (SC3); memory ≈ 1/(1 − λ) frames.
    scale : {"mount_height", "vertical_only"}
        ``mount_height``: yaw from road points' disparity offset; ``vertical_only``: only vertical disparities
        (yaw then only through the weak ``x·y`` term of (SC2)).
    noise_px : float
        Floor of the robust residual scale [px].
    huber_k : float
        Huber threshold in scales.
    reject_sigma : float
        Rows beyond this many scales get weight 0 (after the first IRLS pass).
    ground_tolerance : float
        Relative height tolerance of a road point, |d − d_plane| ≤ tolerance·d_plane.
    min_ground_disparity_px : float
        Smallest plane disparity [px] of a road point (far road points are too uncertain to classify).
    min_rows : int
        Fewer vertical rows than this: no update this frame (nothing forgotten either).
    prior_std_deg : float
        Standard deviation of the zero start [°].
    max_angle_deg : float
        The estimate is clipped to ± this per axis [°].
    irls_iterations : int
        IRLS passes per frame.
    road_half_width : float
        Road points must lie within ± this of the trailer's centreline [m] (its own track; the verges and
        fields beside it lie at other heights).
    twist_regressor : {"none", "lateral_acceleration"}
        ``lateral_acceleration``: the angles are a level plus a gain times the rig's unit's measured lateral
        acceleration less its recent mean, (SC4)–(SC7); ``none``: (SC3) alone.
    twist_forgetting : float
        λ_g of (SC6), the gains' forgetting per frame.
    twist_prior_std_deg_per_mps2 : float
        Standard deviation of the gains' zero start and floor of their uncertainty, (SC6) [°/(m/s²)].
    """

    forgetting: float = Field(
        0.98, ge=0.8, le=1.0, description="RLS forgetting per frame; memory 1/(1−λ) frames: 5 at 0.8, none at 1"
    )
    scale: Literal["mount_height", "vertical_only"] = "mount_height"
    noise_px: float = Field(
        0.3, ge=0.01, le=5.0, description="[px] floor of the robust residual scale; matches are at best ~0.3 px"
    )
    huber_k: float = Field(1.345, ge=0.5, le=10.0, description="Huber threshold in scales; 1.345 is 95 % efficient")
    reject_sigma: float = Field(4.0, ge=2.0, le=50.0, description="rows beyond this many scales are dropped")
    ground_tolerance: float = Field(
        0.1, gt=0.0, le=0.5, description="relative height tolerance of a road point; 0.5 takes kerbs for road"
    )
    min_ground_disparity_px: float = Field(
        4.0, ge=0.5, le=100.0, description="[px] far road points below this are too uncertain to classify"
    )
    min_rows: int = Field(20, ge=6, le=2000, description="fewer matches: no update (3 angles need a spread)")
    prior_std_deg: float = Field(1.0, gt=0.0, le=10.0, description="[°] std of the zero start")
    max_angle_deg: float = Field(3.0, gt=0.0, le=10.0, description="[°] estimate clipped per axis; a first order model")
    irls_iterations: int = Field(3, ge=1, le=20, description="IRLS passes per frame; 20 converges any frame")
    road_half_width: float = Field(
        2.5, gt=0.0, le=20.0, description="[m] road points within this of the trailer's centreline; 20 takes fields"
    )
    twist_regressor: Literal["none", "lateral_acceleration"] = "none"
    twist_forgetting: float = Field(
        0.998, ge=0.9, le=1.0, description="gains' forgetting per frame (SC6); memory 10 frames at 0.9, none at 1"
    )
    twist_prior_std_deg_per_mps2: float = Field(
        0.1,
        gt=0.0,
        le=MAX_TWIST_DEG_PER_MPS2,
        description="[°/(m/s²)] gains' prior std and uncertainty floor; above 1° per m/s² no mount holds a camera",
    )


@dataclass(frozen=True)
class RoadPlane:
    """The road plane ``n·X = height`` in left-camera (OpenCV) axes; ``normal`` is the downward unit normal.

    ``lateral``/``offset``: the trailer's lateral coordinate of a camera point is ``lateral·X + offset`` [m]
    (None: no lateral window).
    """

    normal: np.ndarray
    height: float
    lateral: np.ndarray | None = None
    offset: float = 0.0

    @classmethod
    def from_camera_pose(cls, camera_in_trailer: np.ndarray) -> RoadPlane:
        """The plane ``z = 0`` of a trailer frame (z up, road at 0) seen from a camera at ``T_trailer←camera``."""
        rotation, t = camera_in_trailer[:3, :3], camera_in_trailer[:3, 3]
        normal = -rotation.T @ np.array([0.0, 0.0, 1.0])
        return cls(normal / np.linalg.norm(normal), float(t[2]), rotation[1].copy(), float(t[1]))


@dataclass(frozen=True)
class SelfCalibrationStep:
    """What one :meth:`StereoSelfCalibration.update` did.

    Attributes
    ----------
    updated : bool
        The frame had enough rows and changed the estimate.
    angles : tuple[float, float, float]
        (roll, pitch, yaw) after the frame [rad].
    sigma : tuple[float, float, float]
        Their standard deviations [rad].
    residual_px : float
        RMS vertical-disparity residual of the rows kept [px] (NaN without an update).
    rows, ground : int
        Rows with weight > 0, and how many of them were road points.
    """

    updated: bool
    angles: tuple[float, float, float]
    sigma: tuple[float, float, float]
    residual_px: float = math.nan
    rows: int = 0
    ground: int = 0

    def record(self) -> dict[str, float]:
        """The :data:`SELF_CALIBRATION_COLUMNS` of this frame (angles in degrees)."""
        roll, pitch, yaw = (math.degrees(a) for a in self.angles)
        return {
            "roll_deg": roll,
            "pitch_deg": pitch,
            "yaw_deg": yaw,
            "sigma_deg": math.degrees(max(self.sigma)),
            "residual_px": self.residual_px,
            "rows": float(self.rows),
            "ground": float(self.ground),
        }


def stereo_rows(
    matches: np.ndarray, k: np.ndarray, baseline: float, plane: RoadPlane | None, settings: SelfCalibrationSettings
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linear rows (SC1)–(SC2) of stereo matches: ``z ≈ A·(φ, θ, ψ)`` in pixels.

    Parameters
    ----------
    matches : numpy.ndarray
        (n, 4) stereo matches (u_l, v_l, u_r, v_r) [px] of images with camera matrix ``k``.
    k : numpy.ndarray
        3×3 camera matrix of the (rectified) pair.
    baseline : float
        Stereo baseline [m].
    plane : RoadPlane | None
        The road plane; None: vertical rows only.
    settings : SelfCalibrationSettings
        Road-point tolerances.

    Returns
    -------
    a : numpy.ndarray
        (m, 3) rows [px/rad]: first the n vertical rows, then one per road point.
    z : numpy.ndarray
        (m,) measurements [px].
    ground : numpy.ndarray
        (m,) True on the road-point rows.
    """
    m = np.asarray(matches, dtype=float).reshape(-1, 4)
    f, cu, cv = float(k[0, 0]), float(k[0, 2]), float(k[1, 2])
    xl, yl = (m[:, 0] - cu) / f, (m[:, 1] - cv) / f
    xr, yr = (m[:, 2] - cu) / f, (m[:, 3] - cv) / f
    a_v = f * np.column_stack([-xr, 1.0 + yr**2, -xr * yr])  # (SC2): ∂y'/∂(φ, θ, ψ)
    z_v = f * (yr - yl)
    rows, values, kinds = [a_v], [z_v], [np.zeros(len(z_v), dtype=bool)]
    if plane is not None:
        z_g, road, ray = road_matches(
            m, k, baseline, plane, settings.min_ground_disparity_px, settings.ground_tolerance
        )
        if plane.lateral is not None:  # on the trailer's own track: X = Z·p_l with Z = h/(n·p_l)
            depth = plane.height / np.maximum(ray, 1e-9)
            side = depth * (plane.lateral[0] * xl + plane.lateral[1] * yl + plane.lateral[2]) + plane.offset
            road &= np.abs(side) <= settings.road_half_width
        a_g = f * np.column_stack([-yr, -xr * yr, 1.0 + xr**2])  # (SC1): −∂x'/∂(φ, θ, ψ)
        rows.append(a_g[road])
        values.append(z_g[road])
        kinds.append(np.ones(int(road.sum()), dtype=bool))
    return np.vstack(rows), np.concatenate(values), np.concatenate(kinds)


def road_matches(
    matches: np.ndarray,
    k: np.ndarray,
    baseline: float,
    plane: RoadPlane,
    min_disparity_px: float,
    tolerance: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The matches on the road plane: their disparity less the plane's [px], which are road points, and ``n·p_l``.

    A match is a road point where the plane's disparity ``f·b·(n·p_l)/h`` at its left pixel is at least
    ``min_disparity_px`` and its own disparity is within ``tolerance`` of it, relatively (a height error).

    Parameters
    ----------
    matches : numpy.ndarray
        (n, 4) stereo matches (u_l, v_l, u_r, v_r) [px] of rectified images with camera matrix ``k``.
    k : numpy.ndarray
        3×3 camera matrix.
    baseline : float
        Stereo baseline [m].
    plane : RoadPlane
        The road plane in left-camera axes.
    min_disparity_px, tolerance : float
        The classification's thresholds.
    """
    m = np.asarray(matches, dtype=float).reshape(-1, 4)
    f, cu, cv = float(k[0, 0]), float(k[0, 2]), float(k[1, 2])
    xl, yl = (m[:, 0] - cu) / f, (m[:, 1] - cv) / f
    ray = plane.normal[0] * xl + plane.normal[1] * yl + plane.normal[2]  # n·p_l: 1/Z = n·p_l / h
    d_plane = f * baseline * ray / plane.height
    residual = (m[:, 0] - m[:, 2]) - d_plane
    road = (ray > 0) & (d_plane >= min_disparity_px)
    road &= np.abs(residual) <= tolerance * np.maximum(d_plane, 1e-9)
    return residual, road, ray


def huber_weight(r: np.ndarray, k: float) -> np.ndarray:
    """Huber IRLS weight of scaled residuals ``r``: 1 inside ±k, k/|r| outside."""
    a = np.abs(r)
    return np.where(a <= k, 1.0, k / np.maximum(a, 1e-12))


@dataclass
class StereoSelfCalibration:
    """Recursive, robust estimate of the right camera's residual rotation (module docstring, (SC1)–(SC3)).

    Parameters
    ----------
    k : numpy.ndarray
        3×3 camera matrix of the images the odometry gets.
    baseline : float
        Stereo baseline [m].
    plane : RoadPlane | None
        The road plane in left-camera axes (needed for ``scale="mount_height"``).
    settings : SelfCalibrationSettings
        Parameters.

    Examples
    --------
    >>> calib = StereoSelfCalibration(k, 0.5, plane)          # doctest: +SKIP
    >>> h = calib.correction_homography()                    # doctest: +SKIP
    >>> right = cv2.warpPerspective(right, h, size)          # doctest: +SKIP
    >>> calib.update(vo.process(left, right).stereo_matches)  # doctest: +SKIP
    """

    k: np.ndarray
    baseline: float
    plane: RoadPlane | None = None
    settings: SelfCalibrationSettings = field(default_factory=SelfCalibrationSettings)

    def __post_init__(self) -> None:
        s = self.settings
        if not 0.0 < s.forgetting <= 1.0:
            raise ValueError(f"forgetting must be in (0, 1], got {s.forgetting}")
        if s.scale == "mount_height" and self.plane is None:
            raise ValueError("scale mount_height needs the road plane")
        self.k = np.asarray(self.k, dtype=float)
        self.reset()

    def reset(self) -> None:
        """Back to the zero start with the prior's information."""
        self._info = np.eye(3) / math.radians(self.settings.prior_std_deg) ** 2
        self._eta = np.zeros(3)
        self._omega = np.zeros(3)

    @property
    def angles(self) -> tuple[float, float, float]:
        """The current estimate (roll, pitch, yaw) [rad] (eq (9) order of :class:`sensor.camera.Misalignment`)."""
        return (float(self._omega[0]), float(self._omega[1]), float(self._omega[2]))

    @property
    def sigma(self) -> tuple[float, float, float]:
        """Standard deviations of :attr:`angles` [rad]: ``sqrt(diag Λ⁻¹)``."""
        d = np.sqrt(np.diag(np.linalg.inv(self._info)))
        return (float(d[0]), float(d[1]), float(d[2]))

    def angles_at(self, regressor: float | None = None) -> tuple[float, float, float]:
        """The estimate (roll, pitch, yaw) [rad] for a frame at ``regressor``; :attr:`angles` here (no twist term)."""
        return self.angles

    def rotation(self, regressor: float | None = None) -> np.ndarray:
        """``R̂ = R_z(φ)·R_y(ψ)·R_x(θ)`` of the estimate at ``regressor`` (de Saxe & Cebon 2018, eq (9))."""
        roll, pitch, yaw = self.angles_at(regressor)
        cf, sf, cp, sp, ct, st = (f(a) for a in (roll, yaw, pitch) for f in (math.cos, math.sin))
        rz = np.array([[cf, -sf, 0.0], [sf, cf, 0.0], [0.0, 0.0, 1.0]])
        ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
        rx = np.array([[1.0, 0.0, 0.0], [0.0, ct, -st], [0.0, st, ct]])
        return rz @ ry @ rx

    def correction_homography(self, regressor: float | None = None) -> np.ndarray | None:
        """``K·R̂·K⁻¹``, the warp of the right image that removes the estimate at ``regressor`` (de Saxe & Cebon
        2018, eqs (8)–(9)); None at zero."""
        if not np.any(self.angles_at(regressor)):
            return None
        return self.k @ self.rotation(regressor) @ np.linalg.inv(self.k)

    def update(
        self,
        matches: np.ndarray,
        used: tuple[float, float, float] | None = None,
        inliers: np.ndarray | None = None,
        regressor: float | None = None,
    ) -> SelfCalibrationStep:
        """Take one frame's stereo matches of the corrected images (SC3).

        Parameters
        ----------
        matches : numpy.ndarray
            (n, 4) (u_l, v_l, u_r, v_r) [px] of the images the odometry saw (right image corrected by ``used``).
        used : tuple[float, float, float] | None
            The angles [rad] the right image was corrected with; None: the current estimate at ``regressor``.
        inliers : numpy.ndarray | None
            Boolean mask over ``matches`` (e.g. the odometry's RANSAC inliers); used when it keeps at least
            ``min_rows`` matches, else every match is used (the robust weights still apply).
        regressor : float | None
            The frame's measured regressor of a twist term (:mod:`sensor.vo.twist_calibration`); ignored here.

        Returns
        -------
        SelfCalibrationStep
        """
        s = self.settings
        m = np.asarray(matches, dtype=float).reshape(-1, 4)
        if inliers is not None and len(inliers) == len(m) and int(np.sum(inliers)) >= s.min_rows:
            m = m[np.asarray(inliers, dtype=bool)]
        if len(m) < s.min_rows:
            return SelfCalibrationStep(False, self.angles_at(regressor), self.sigma_at(regressor))
        plane = self.plane if s.scale == "mount_height" else None
        a3, z, ground = stereo_rows(m, self.k, self.baseline, plane, s)
        omega0 = np.asarray(self.angles_at(regressor) if used is None else used, dtype=float)
        y = z + a3 @ omega0  # pseudo-measurements of the absolute angles
        a = self._design(a3, regressor)
        info0, eta0 = self._forget()
        omega, w = self._omega.copy(), np.ones(len(z))
        for iteration in range(s.irls_iterations + 1):
            r = y - a @ omega
            w = np.zeros(len(z))
            for kind in (False, True):
                sel = ground == kind
                if not sel.any():
                    continue
                rk = r[sel]
                scale = max(s.noise_px, MAD_SIGMA * float(np.median(np.abs(rk - np.median(rk)))))
                wk = huber_weight(rk / scale, s.huber_k) / s.noise_px**2  # information at the noise floor
                if iteration > 0:
                    wk[np.abs(rk) > s.reject_sigma * scale] = 0.0
                w[sel] = wk
            if iteration == s.irls_iterations:
                break
            aw = a * w[:, None]
            omega = np.linalg.solve(info0 + a.T @ aw, eta0 + aw.T @ y)
        aw = a * w[:, None]
        self._info = info0 + a.T @ aw
        self._eta = eta0 + aw.T @ y
        self._omega = self._clip(np.linalg.solve(self._info, self._eta))
        kept = w > 0
        vertical = kept & ~ground
        res = (y - a @ self._omega)[vertical]
        return SelfCalibrationStep(
            True,
            self.angles_at(regressor),
            self.sigma_at(regressor),
            residual_px=float(np.sqrt(np.mean(res**2))) if res.size else math.nan,
            rows=int(kept.sum()),
            ground=int((kept & ground).sum()),
        )

    def sigma_at(self, regressor: float | None = None) -> tuple[float, float, float]:
        """Standard deviations [rad] of :meth:`angles_at` ``regressor``; :attr:`sigma` here."""
        return self.sigma

    def _design(self, a: np.ndarray, regressor: float | None) -> np.ndarray:
        """The rows over the parameters from the rows over the angles (SC1)–(SC2): the angles themselves here."""
        return a

    def _forget(self) -> tuple[np.ndarray, np.ndarray]:
        """The information and its vector after forgetting, before the frame's rows (SC3)."""
        s = self.settings
        return s.forgetting * self._info, s.forgetting * self._eta

    def _clip(self, x: np.ndarray) -> np.ndarray:
        """The parameters clipped to their bounds (``max_angle_deg``)."""
        limit = math.radians(self.settings.max_angle_deg)
        return np.clip(x, -limit, limit)
