"""Brown–Conrady lens distortion of the rendered cameras: the lens, the wider pinhole render, the remap maps.

The renderer draws ideal pinhole images. A real wide-angle lens bends the rays: a point whose ideal normalised
image coordinates are ``(x, y)`` (``x = X/Z``, ``y = Y/Z`` in OpenCV camera axes) appears at (Brown 1966;
Conrady 1919; OpenCV calib3d docs, "Camera Calibration and 3D Reconstruction")::

    r² = x² + y²
    x_d = x·(1 + k1·r² + k2·r⁴ + k3·r⁶) + 2·p1·x·y + p2·(r² + 2·x²)
    y_d = y·(1 + k1·r² + k2·r⁴ + k3·r⁶) + p1·(r² + 2·y²) + 2·p2·x·y
    u = fx·x_d + cx,   v = fy·y_d + cy

This module turns a pinhole render into the distorted image (the camera's own K and a :class:`Lens`):

1. :func:`wide_pinhole_rig` — the pinhole image the renderer must draw so that every distorted pixel has a
   source. It keeps the **same focal length** (the pixel scale at the image centre is unchanged, so the remap
   does not blur the centre) and enlarges the **width and height** by an even number of pixels, so the
   principal point stays at the image centre; the horizontal field of view widens to match
   (``hfov' = 2·atan(w'/(2f))``). A barrel lens (k1 < 0) needs the larger image: e.g. the default 1344 × 391 px,
   100° rig with k1 = −0.2, k2 = 0.05, p1 = 0.001, p2 = −0.0005 renders 1686 × 499 px (hfov 112.4°), 1.6 times
   the pixels.
2. :func:`distortion_maps` — the ``cv2.remap`` maps (computed once): for each distorted pixel, the pinhole pixel
   it sees, ``K'·undistort(K⁻¹·(u, v))`` with ``cv2.undistortPoints`` iterated to 1e-12 (its default five
   iterations leave 0.05–0.09 px at the corners of a 100° lens, and so does ``cv2.initInverseRectificationMap``
   which uses them). Fixed-point maps (``cv2.convertMaps`` to CV_16SC2, 1/32 px) remap faster than float maps
   (benchmarks/README.md, "Costs behind design choices").
3. :class:`LensDistortion` — both cameras of a rig: the wide rig and the maps, and :meth:`LensDistortion.apply`.

Image noise belongs to the sensor, i.e. after the remap: render noise-free, distort, then add noise.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import cv2
import numpy as np

from sensor.camera import Lens, StereoRig
from vehicle_model.errors import InputError

UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
"""Termination of ``cv2.undistortPoints``' fixed-point iteration: converged to 1e-12 (normalised units)."""


def _pixel_grid(width: int, height: int) -> np.ndarray:
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    return np.stack([u.ravel(), v.ravel()], axis=1)


def _coefficients(lens: Lens | np.ndarray) -> np.ndarray:
    return lens.coefficients if isinstance(lens, Lens) else np.asarray(lens, dtype=np.float64).ravel()


def distort_pixels(k: np.ndarray, lens: Lens | np.ndarray, ideal: np.ndarray) -> np.ndarray:
    """Distorted pixels of ideal (pinhole, same K) pixels ``(n, 2)``: the Brown–Conrady model via ``cv2.projectPoints``.

    ``lens`` is a :class:`Lens` or OpenCV ``distCoeffs`` (e.g. an estimated calibration's).
    """
    ideal = np.asarray(ideal, dtype=np.float64).reshape(-1, 2)
    k = np.asarray(k, dtype=np.float64)
    xy = (ideal - k[:2, 2]) / np.array([k[0, 0], k[1, 1]])
    rays = np.column_stack([xy, np.ones(len(xy))])
    out, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), k, _coefficients(lens))
    return out.reshape(-1, 2)


def undistort_pixels(
    k: np.ndarray,
    lens: Lens | np.ndarray,
    distorted: np.ndarray,
    *,
    r: np.ndarray | None = None,
    p: np.ndarray | None = None,
) -> np.ndarray:
    """Ideal pixels of distorted pixels ``(n, 2)``: ``cv2.undistortPoints`` converged to 1e-12.

    Parameters
    ----------
    k : numpy.ndarray
        Camera matrix of the distorted camera.
    lens : Lens or numpy.ndarray
        Its distortion (a :class:`Lens` or OpenCV ``distCoeffs``).
    distorted : numpy.ndarray
        ``(n, 2)`` pixels.
    r, p : numpy.ndarray, optional
        Rectifying rotation and new camera / projection matrix (``cv2.undistortPoints``' R and P); default
        identity and ``k`` (ideal pixels of the same camera). Pass ``p=np.eye(3)`` for normalised coordinates.
    """
    pts = np.asarray(distorted, dtype=np.float64).reshape(-1, 1, 2)
    p = np.asarray(k, dtype=np.float64) if p is None else np.asarray(p, dtype=np.float64)
    out = cv2.undistortPoints(pts, np.asarray(k, dtype=np.float64), _coefficients(lens), None, r, p, UNDISTORT_CRITERIA)
    return out.reshape(-1, 2)


def check_invertible(k: np.ndarray, lens: Lens, width: int, height: int, name: str = "lens") -> None:
    """Refuse a lens whose model folds over inside the image (the distortion would not be one-to-one).

    Raises
    ------
    InputError
        Naming the lens (``name``, e.g. ``camera.lens``), where it folds and the image's corner radius.
    """
    limit = lens.radial_limit()
    if math.isinf(limit):
        return
    # the distorted radius at the fold, against the image's farthest corner in normalised units
    r2 = limit * limit
    r_fold = limit * (1.0 + lens.k1 * r2 + lens.k2 * r2**2 + lens.k3 * r2**3)
    corners = np.array([[0.0, 0.0], [width - 1.0, 0.0], [0.0, height - 1.0], [width - 1.0, height - 1.0]])
    xy = (corners - k[:2, 2]) / np.array([k[0, 0], k[1, 1]])
    r_corner = float(np.max(np.hypot(xy[:, 0], xy[:, 1])))
    if r_fold <= 1.02 * r_corner:
        raise InputError(
            f"{name} = (k1={lens.k1:g}, k2={lens.k2:g}, k3={lens.k3:g}) folds over at normalised radius "
            f"{limit:.3g}, inside the image (corner radius {r_corner:.3g}); allowed: a distortion that rises "
            "monotonically to the image corners (e.g. smaller |k1| or a positive k2)"
        )


def ideal_extent(k: np.ndarray, lens: Lens, width: int, height: int) -> tuple[float, float, float, float]:
    """Bounding box ``(u_min, v_min, u_max, v_max)`` [px, same K] of the ideal positions of all distorted pixels."""
    check_invertible(k, lens, width, height)
    # the extremes lie on the border: sample every border pixel (plus a coarse interior grid for safety)
    u = np.arange(width, dtype=np.float64)
    v = np.arange(height, dtype=np.float64)
    border = np.concatenate(
        [
            np.column_stack([u, np.zeros_like(u)]),
            np.column_stack([u, np.full_like(u, height - 1.0)]),
            np.column_stack([np.zeros_like(v), v]),
            np.column_stack([np.full_like(v, width - 1.0), v]),
            _pixel_grid(width, height)[:: max(1, (width * height) // 4000)],
        ]
    )
    ideal = undistort_pixels(k, lens, border)
    lo, hi = ideal.min(axis=0), ideal.max(axis=0)
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def wide_pinhole_rig(rig: StereoRig, *lenses: Lens, margin_px: int = 2) -> StereoRig:
    """The rig the renderer must draw so that every pixel of the distorted images has a pinhole source.

    Same focal length as ``rig``; width and height enlarged symmetrically (so the principal point stays at the
    centre, shifted by the padding); ``hfov`` widened to keep the focal length. One wide rig serves both cameras
    (pass both lenses). Every other field, the misalignment included, is unchanged (``dataclasses.replace``).

    Parameters
    ----------
    rig : StereoRig
        The distorted cameras' rig: its ``width``, ``height`` and K are those of the distorted images.
    *lenses : Lens
        The lenses of the cameras (one or both).
    margin_px : int
        Extra pixels on every side beyond the one bilinear interpolation needs.

    Returns
    -------
    StereoRig
        ``rig`` with the wider ``width``, ``height`` and ``hfov``; ``rig`` itself if every lens is ideal.
    """
    if not lenses or all(lens.is_zero for lens in lenses):
        return rig
    if not 0 <= margin_px <= 64:
        raise InputError(f"margin_px = {margin_px!r} is out of range; allowed: [0, 64] px")
    k = rig.intrinsics()
    pad_u = pad_v = 0
    for lens in lenses:
        u0, v0, u1, v1 = ideal_extent(k, lens, rig.width, rig.height)
        pad_u = max(pad_u, math.ceil(max(-u0, u1 - (rig.width - 1), 0.0)) + 1 + margin_px)
        pad_v = max(pad_v, math.ceil(max(-v0, v1 - (rig.height - 1), 0.0)) + 1 + margin_px)
    width, height = rig.width + 2 * pad_u, rig.height + 2 * pad_v
    hfov = 2.0 * math.atan(0.5 * width / rig.focal_length)  # same f: f = (w'/2)/tan(hfov'/2)
    if not (width <= 8192 and height <= 8192 and hfov <= math.radians(170.0)):
        raise InputError(
            f"the lens needs a {width} × {height} px pinhole render with hfov {math.degrees(hfov):.1f}°; "
            "allowed: at most 8192 px and 170° (reduce the distortion or the field of view)"
        )
    return dataclasses.replace(rig, width=width, height=height, hfov=hfov)


def pinhole_matrix(wide: StereoRig) -> np.ndarray:
    """Camera matrix K' of the wide pinhole render (its focal length and centred principal point)."""
    return wide.intrinsics()


def distortion_maps(
    rig: StereoRig, lens: Lens, wide: StereoRig, *, fixed_point: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """``cv2.remap`` maps that turn the wide pinhole render into the distorted image of ``rig``'s camera.

    For each distorted pixel ``(u, v)`` the source is ``K'·undistort(K⁻¹·(u, v))`` (OpenCV calib3d docs,
    ``undistortPoints``), K the rig's matrix, K' the wide render's.

    Parameters
    ----------
    rig : StereoRig
        The distorted camera (``width``, ``height``, K).
    lens : Lens
        Its distortion.
    wide : StereoRig
        The pinhole render (:func:`wide_pinhole_rig`).
    fixed_point : bool
        Convert to CV_16SC2 + CV_16UC1 maps (``cv2.convertMaps``; 1/32 px resolution, faster remap); else two
        CV_32FC1 maps.

    Returns
    -------
    map1, map2
        The maps for ``cv2.remap(image, map1, map2, cv2.INTER_LINEAR)``; the output is ``height × width``.
    """
    k = rig.intrinsics()
    src = undistort_pixels(k, lens, _pixel_grid(rig.width, rig.height), p=pinhole_matrix(wide))
    src = src.reshape(rig.height, rig.width, 2).astype(np.float32)
    lo = src.reshape(-1, 2).min(axis=0)
    hi = src.reshape(-1, 2).max(axis=0)
    if lo.min() < 0.0 or hi[0] > wide.width - 1 or hi[1] > wide.height - 1:
        raise InputError(
            f"the pinhole render {wide.width} × {wide.height} px is too small for the lens {lens}; "
            "use wide_pinhole_rig(rig, lens)"
        )
    map_x, map_y = np.ascontiguousarray(src[..., 0]), np.ascontiguousarray(src[..., 1])
    if fixed_point:
        return cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
    return map_x, map_y


def remap(image: np.ndarray, maps: tuple[np.ndarray, np.ndarray], *, border_value: float = 0.0) -> np.ndarray:
    """Apply remap maps with bilinear interpolation (``cv2.remap``, constant border)."""
    return cv2.remap(
        image,
        maps[0],
        maps[1],
        interpolation=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=border_value,
    )


@dataclass(frozen=True, eq=False)
class LensDistortion:
    """The distortion stage of a stereo rig: the wide pinhole rig to render and the maps of both cameras.

    Build with :meth:`build`; pickling keeps the maps (a few MB), so a worker need not recompute them.

    Attributes
    ----------
    rig : StereoRig
        The distorted cameras (the images the VO or the calibration sees).
    lens_left, lens_right : Lens
        The lenses.
    wide : StereoRig
        What the renderer draws (:func:`wide_pinhole_rig`).
    maps_left, maps_right : tuple of numpy.ndarray
        ``cv2.remap`` maps (:func:`distortion_maps`).
    """

    rig: StereoRig
    lens_left: Lens
    lens_right: Lens
    wide: StereoRig
    maps_left: tuple[np.ndarray, np.ndarray]
    maps_right: tuple[np.ndarray, np.ndarray]

    @classmethod
    def build(
        cls, rig: StereoRig, lens_left: Lens, lens_right: Lens | None = None, *, fixed_point: bool = True
    ) -> LensDistortion:
        """Wide rig and maps for ``rig`` with these lenses (``lens_right`` defaults to ``lens_left``)."""
        lens_right = lens_left if lens_right is None else lens_right
        wide = wide_pinhole_rig(rig, lens_left, lens_right)
        return cls(
            rig,
            lens_left,
            lens_right,
            wide,
            distortion_maps(rig, lens_left, wide, fixed_point=fixed_point),
            distortion_maps(rig, lens_right, wide, fixed_point=fixed_point),
        )

    @property
    def crop(self) -> tuple[int, int]:
        """Padding ``(columns, rows)`` of the wide render on each side [px]."""
        return (self.wide.width - self.rig.width) // 2, (self.wide.height - self.rig.height) // 2

    def apply(self, left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distort a pair of wide pinhole renders (``wide.height × wide.width``) into ``rig.height × rig.width``."""
        shape = (self.wide.height, self.wide.width)
        if left.shape[:2] != shape or right.shape[:2] != shape:
            raise InputError(f"LensDistortion.apply expects {shape} images, got {left.shape[:2]} and {right.shape[:2]}")
        return remap(left, self.maps_left), remap(right, self.maps_right)
