"""What the sun does to each frame: sky, shadows' shade, veiling glare and bloom, lagging auto-exposure.

Applied by :class:`sensor.renderer.StereoRenderer` after the GPU pass when :attr:`Lighting.sun` is set
(:mod:`sensor.lighting` bakes the static light). Per view, from the rendered grey image ``g`` and its
alpha ``a`` (0: sky, else the shade of the ground, 255 in sun):

* scene radiance in grey levels at gain 1: ``L = g·a/255`` on surfaces, the sky model on the sky —
  brighter towards the horizon and around the sun (computed on a coarse grid of view rays and
  upsampled: it is smooth);
* glare: a solar halo ``S / (1 + (θ/θ_h)²)`` around the sun's direction (θ the angle of each pixel's
  ray from the sun; it saturates near the sun) plus a uniform veil that grows as the sun approaches
  the field of view (lower contrast), both cut when an object hides the sun;
* exposure: one gain for both cameras (a synchronised pair), metered on the left image's mean; the
  gain follows ``target_level / mean`` in the log domain with a first-order lag of
  ``exposure_lag_s``, so turning towards the sun first blows the image out, then darkens it, and
  turning away leaves it dark for a while. Image = ``clip(gain · (L + glare))``.

The lag makes frame ``k``'s image depend on frame ``k − 1``'s: :class:`AutoExposure` carries the gain
from frame to frame when frames come in order and starts converged on a jump.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from .lighting import Lighting, sun_direction

__all__ = ["AutoExposure", "FrameLight"]

_GRID = 8
"""Coarse grid step [px] of the sky and glare model."""

HALO_DEG = 3.0
"""Angular radius of the solar halo's core [deg]."""

VEIL_MARGIN_DEG = 25.0
"""The veiling glare fades out as the sun moves this far beyond the edge of the field of view [deg]."""


class FrameLight:
    """Sky and glare of one camera geometry (intrinsics and image size) under one sun.

    Parameters
    ----------
    lighting : Lighting
        Sun settings (``sun`` must be True).
    k : numpy.ndarray
        ``(3, 3)`` camera matrix (OpenCV).
    width, height : int
        Image size [px].
    sky_rgb : tuple of float
        The flat sky colour of the world (0–1); the sky model is scaled around its grey.
    """

    def __init__(self, lighting: Lighting, k: np.ndarray, width: int, height: int, sky_rgb=(0.8, 0.85, 0.92)) -> None:
        self.lighting = lighting
        self.width, self.height = int(width), int(height)
        self.sun = sun_direction(lighting)
        us = np.arange(0, width + _GRID, _GRID, dtype=np.float64)
        vs = np.arange(0, height + _GRID, _GRID, dtype=np.float64)
        uu, vv = np.meshgrid(us, vs)
        rays = np.stack([uu, vv, np.ones_like(uu)], axis=-1) @ np.linalg.inv(k).T
        self.rays = rays / np.linalg.norm(rays, axis=-1, keepdims=True)  # camera frame, coarse grid
        self.k = np.asarray(k, float)
        self.sky_grey = 255.0 * float(np.dot([0.299, 0.587, 0.114], sky_rgb))
        # Half-angle of the field of view's bounding cone, for the veil.
        corner = np.array([width / 2.0, height / 2.0])
        self.half_fov = math.atan(float(np.linalg.norm(corner)) / k[0, 0])

    def _coarse(self, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Sky radiance, halo (grey levels at gain 1) on the coarse grid and the sun's angle from the axis."""
        lt = self.lighting
        world = self.rays @ rotation.T  # world-frame ray directions
        elev = np.clip(world[..., 2], -1.0, 1.0)
        cos_sun = np.clip(world @ self.sun, -1.0, 1.0)
        theta = np.degrees(np.arccos(cos_sun))
        halo = lt.sun_radiance / (1.0 + (theta / HALO_DEG) ** 2)
        sky = np.zeros_like(elev)
        if lt.sky:
            # Brighter towards the horizon (air mass) and around the sun (forward scattering).
            horizon = 0.6 + 0.3 * np.exp(-np.clip(elev, 0.0, None) / 0.12)
            circum = 0.8 * np.exp(-theta / 25.0)
            sky = self.sky_grey * (horizon + circum)
        else:
            sky = np.full_like(elev, self.sky_grey)
        axis = rotation[:, 2]
        sun_off_axis = math.degrees(math.acos(float(np.clip(axis @ self.sun, -1.0, 1.0))))
        return sky.astype(np.float32), halo.astype(np.float32), sun_off_axis

    def _sun_pixel(self, rotation: np.ndarray) -> tuple[int, int] | None:
        """Pixel of the sun's centre, or None when it is behind the camera or outside the image."""
        d = rotation.T @ self.sun
        if d[2] <= 1e-6:
            return None
        p = self.k @ (d / d[2])
        u, v = round(float(p[0])), round(float(p[1]))
        return (u, v) if 0 <= u < self.width and 0 <= v < self.height else None

    def radiance(self, grey: np.ndarray, alpha: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        """Scene radiance plus glare at gain 1 [grey levels], float32 ``(height, width)``.

        Parameters
        ----------
        grey, alpha : numpy.ndarray
            The rendered view's grey image and alpha channel (rows top-down).
        rotation : numpy.ndarray
            ``(3, 3)`` camera-to-world rotation (OpenCV camera axes).
        """
        lt = self.lighting
        sky_c, halo_c, off_axis = self._coarse(rotation)
        fine = cv2.resize(np.dstack([sky_c, halo_c]), (sky_c.shape[1] * _GRID, sky_c.shape[0] * _GRID))
        fine = fine[: self.height, : self.width]
        sky, halo = fine[..., 0], fine[..., 1]
        shade = cv2.multiply(grey, alpha, scale=1.0 / 255.0, dtype=cv2.CV_32F)
        out = np.where(alpha == 0, sky, shade)
        # Glare: the halo everywhere (it is what the lens scatters), the veil by the sun's closeness to
        # the field of view; both cut when an object (not the sky) covers the sun's pixel.
        pixel = self._sun_pixel(rotation)
        hidden = pixel is not None and alpha[pixel[1], pixel[0]] != 0
        if off_axis > 90.0 or hidden:
            return out
        beyond = max(0.0, off_axis - math.degrees(self.half_fov))
        veil = lt.glare * max(0.0, 1.0 - beyond / VEIL_MARGIN_DEG) ** 2
        return cv2.add(out, halo) + np.float32(veil)


class AutoExposure:
    """The exposure gain of the stereo pair, lagging behind the image brightness.

    Parameters
    ----------
    lighting : Lighting
        ``auto_exposure``, ``exposure_lag_s``, ``target_level``, ``gain_range``.
    frame_interval_s : float
        Time between consecutive frames [s] (1 / camera rate): the lag acts over it.
    """

    def __init__(self, lighting: Lighting, frame_interval_s: float = 0.1) -> None:
        if not 0.0 < frame_interval_s <= 10.0:
            raise ValueError(f"frame_interval_s = {frame_interval_s!r} must be in (0, 10] s")
        self.lighting = lighting
        self.frame_interval_s = float(frame_interval_s)
        self.gain = 1.0
        self.frame: int | None = None

    def update(self, metered: float, frame: int) -> float:
        """The gain for ``frame`` given the mean grey level ``metered`` of its image at gain 1.

        Frames in order (``frame`` = previous + 1) move the gain by the lag; any other frame (the
        first, a jump, a re-render) starts at the converged gain.
        """
        lt = self.lighting
        if not lt.auto_exposure:
            self.frame = frame
            self.gain = 1.0
            return 1.0
        lo, hi = lt.gain_range
        target = float(np.clip(lt.target_level / max(metered, 1e-3), lo, hi))
        if self.frame is not None and frame == self.frame + 1 and lt.exposure_lag_s > 0:
            alpha = 1.0 - math.exp(-self.frame_interval_s / lt.exposure_lag_s)
            self.gain = math.exp(math.log(self.gain) + alpha * (math.log(target) - math.log(self.gain)))
        elif not (self.frame is not None and frame == self.frame):
            self.gain = target
        self.frame = frame
        return self.gain

    @staticmethod
    def apply(radiance: np.ndarray, gain: float) -> np.ndarray:
        """``clip(gain · radiance)`` as uint8."""
        return cv2.convertScaleAbs(radiance, alpha=float(gain))
