"""Feature detection and description of VISO2-S (Geiger, Ziegler & Stiller 2011, §III-A).

* Two 5×5 interest filters, blob and corner (checkerboard), on the (optionally 2×2 box-downsampled)
  image; non-maximum suppression gives four classes — blob minimum (0), blob maximum (1), corner
  minimum (2), corner maximum (3) — with |response| ≥ tau (docs/visual_odometry.md §3).
* Descriptor: 5×5 Sobel-like responses (smoothing [1 4 6 4 1], derivative [1 2 0 −2 −1]) scaled
  by 1/128, offset by 128 and saturated to uint8; the horizontal and vertical responses sampled at
  16 sparse offsets of the 11×11 window give 32 bytes, compared by SAD (docs/visual_odometry.md §4).

The interest filters and the Sobel filters (exact integer sums; the Sobel bytes those of OpenCV's
``sepFilter2D``), the extrema and the descriptors are compiled (:mod:`sensor.vo.kernels_features`);
the downsampling and the erosion/dilation of the tie-broken responses are OpenCV's. A pixel is an
extremum when no pixel of its (2n+1)² neighbourhood is more extreme. Filter responses are integers;
ties are broken by a fixed rank pattern that is unique inside any window, so detected extrema are
strict and at least n+1 px apart (Chebyshev) — the result of Neubeck & Van Gool's block algorithm,
not its exact tie behaviour. The sparse first-pass set (radius 3n, capped) is the subset of the
dense extrema that are also extrema of the larger window (clipped to the image). The border margin
is 9 px at detection resolution (libviso2 2018).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numpy as np

from sensor.vo.config import MAX_NMS_N, VOConfig
from sensor.vo.kernels_features import describe, detect, features_at, responses, sobel, tie_keys

__all__ = [
    "BLOB_KERNEL",
    "BORDER_MARGIN",
    "CORNER_KERNEL",
    "DESCRIPTOR_OFFSETS",
    "FeatureSet",
    "ImageFeatures",
    "compute_descriptors",
    "extract_features",
    "filter_responses",
    "half_resolution",
    "non_maximum_suppression",
    "sobel_responses",
]

# Geiger et al. 2011, §III-A; docs/visual_odometry.md §3.
BLOB_KERNEL = np.array(
    [
        [-1, -1, -1, -1, -1],
        [-1, 1, 1, 1, -1],
        [-1, 1, 8, 1, -1],
        [-1, 1, 1, 1, -1],
        [-1, -1, -1, -1, -1],
    ],
    dtype=np.float32,
)
CORNER_KERNEL = np.array(
    [
        [-1, -1, 0, 1, 1],
        [-1, -1, 0, 1, 1],
        [0, 0, 0, 0, 0],
        [1, 1, 0, -1, -1],
        [1, 1, 0, -1, -1],
    ],
    dtype=np.float32,
)

# Sobel 5×5 (docs/visual_odometry.md §4): smoothing [1 4 6 4 1] ⊗ derivative [1 2 0 −2 −1] as a convolution, i.e.
# correlation with [−1 −2 0 2 1] (a positive response for intensity increasing to the right/down):
# :func:`sensor.vo.kernels_features.sobel`.

#: (du, dv) sampling offsets of the 32-byte descriptor inside the 11×11 window (docs/visual_odometry.md §4).
DESCRIPTOR_OFFSETS = np.array(
    [
        (-1, -1), (1, -1), (-1, 1), (1, 1),
        (-3, -1), (3, -1), (-3, 1), (3, 1),
        (-1, -5), (1, -5), (-1, 5), (1, 5),
        (-5, -3), (5, -3), (-5, 3), (5, 3),
    ],
    dtype=np.int64,
)  # fmt: skip

#: Border [detection px] without features: descriptor (±5) + Sobel (±2) + refinement slack (libviso2 2018: 9).
BORDER_MARGIN = 9

#: Period of the tie-breaking rank pattern: unique inside any window of the largest NMS radius.
_TIE_PERIOD = 2 * MAX_NMS_N + 1

# Feature classes (docs/visual_odometry.md §3).
BLOB_MIN, BLOB_MAX, CORNER_MIN, CORNER_MAX = 0, 1, 2, 3


@dataclass(frozen=True, eq=False)
class FeatureSet:
    """Features of one image at one NMS scale.

    Attributes
    ----------
    u, v : numpy.ndarray
        int32 positions [full-resolution px] (even numbers when detected at half resolution).
    cls : numpy.ndarray
        int8 class: 0 blob-min, 1 blob-max, 2 corner-min, 3 corner-max.
    desc : numpy.ndarray
        (N, 32) uint8 descriptors.
    """

    u: np.ndarray
    v: np.ndarray
    cls: np.ndarray
    desc: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False)

    def __len__(self) -> int:
        return int(self.u.shape[0])


@dataclass(frozen=True, eq=False)
class ImageFeatures:
    """Everything the matcher needs from one image.

    Attributes
    ----------
    dense : FeatureSet
        Features with NMS radius ``nms_n``.
    sparse : FeatureSet | None
        Features with the sparse radius (``multi_stage`` only).
    sobel_full : numpy.ndarray | None
        (2, H, W) uint8 full-resolution Sobel responses (du, dv) for the refinement, or None.
    shape : tuple[int, int]
        Full-resolution image shape (H, W).
    grey : numpy.ndarray | None
        A copy of the (H, W) uint8 image for the gradient refinement (``gradient_refinement``), or None.
    """

    dense: FeatureSet
    sparse: FeatureSet | None
    sobel_full: np.ndarray | None
    shape: tuple[int, int]
    grey: np.ndarray | None = None


def half_resolution(image: np.ndarray) -> np.ndarray:
    """2×2 box-mean downsampling (docs/visual_odometry.md §3); odd trailing rows/columns are dropped."""
    h, w = image.shape
    h2, w2 = h // 2, w // 2
    return cv2.resize(image[: 2 * h2, : 2 * w2], (w2, h2), interpolation=cv2.INTER_AREA)


def sobel_responses(image: np.ndarray) -> np.ndarray:
    """5×5 Sobel responses /128 + 128, rounded to uint8 (docs/visual_odometry.md §4).

    Exact integer sums, rounded half to even (:func:`sensor.vo.kernels_features.sobel`): the same
    bytes as OpenCV's ``sepFilter2D`` with the float kernels (derivative/128), delta 128 and
    replicated borders; OpenCV rounds where libviso2 shifts.

    Parameters
    ----------
    image : numpy.ndarray
        (H, W) uint8.

    Returns
    -------
    numpy.ndarray
        (2, H, W) uint8: horizontal (du) and vertical (dv) responses.
    """
    image = np.ascontiguousarray(image, dtype=np.uint8)
    h, w = image.shape
    out = np.empty((2, h, w), dtype=np.uint8)
    padded_row = _WORKSPACE.get("sobel_row", (w + 4,), np.int16)
    sobel(image, padded_row, _WORKSPACE.get("sobel_ring", (2, 5, w), np.int16), out)
    return out


def filter_responses(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Blob and corner (checkerboard) filter responses (docs/visual_odometry.md §3), borders replicated.

    The blob kernel is −(5×5 box) + 2·(3×3 box) + 7·(centre) (libviso2 uses an integral image to the
    same end); the checkerboard kernel is separable. Exact integer sums
    (:func:`sensor.vo.kernels_features.responses`).

    Returns
    -------
    blob, corner : numpy.ndarray
        float32 responses with integer values (the kernels are symmetric, so correlation = convolution).
    """
    image = np.ascontiguousarray(image, dtype=np.uint8)
    h, w = image.shape
    values = np.empty((2, h, w), dtype=np.int32)
    responses(image, 0, _WORKSPACE.get("ring", (4, 5, w + 4)), values, _NO_KEYS)
    return values[0].astype(np.float32), values[1].astype(np.float32)


class _Workspace(threading.local):
    """Work arrays of the compiled detection, per thread and image shape (fresh arrays cost page faults)."""

    def __init__(self) -> None:
        self.arrays: dict[tuple[str, int, int], np.ndarray] = {}

    def get(self, name: str, shape: tuple[int, ...], dtype: type = np.int32) -> np.ndarray:
        """An array of ``shape``, reused between calls (its content is overwritten by the kernels)."""
        key = (name, *shape)
        array = self.arrays.get(key)
        if array is None:
            if len(self.arrays) > 16:  # many image sizes: start afresh
                self.arrays.clear()
            array = self.arrays[key] = np.empty(shape, dtype=dtype)
        return array


_WORKSPACE = _Workspace()
_NO_VALUES = np.empty((0, 0, 0), dtype=np.int32)
_NO_KEYS = np.empty((0, 0, 0), dtype=np.float32)


def _keys(image: np.ndarray) -> np.ndarray:
    """(2, H, W) float32 tie-broken keys of the blob and corner responses, in this thread's work array."""
    h, w = image.shape
    keys = _WORKSPACE.get("keys", (2, h, w), np.float32)
    responses(image, _TIE_PERIOD, _WORKSPACE.get("ring", (4, 5, w + 4), np.int16), _NO_VALUES, keys)
    return keys


@lru_cache(maxsize=MAX_NMS_N)
def _window(radius: int) -> np.ndarray:
    """The (2·radius + 1)² rectangle of OpenCV's erosion and dilation."""
    return cv2.getStructuringElement(cv2.MORPH_RECT, (2 * radius + 1, 2 * radius + 1))


def _detect(
    keys: np.ndarray, radii: tuple[int, ...], tau: float, margin: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Extrema of the (2, H, W) keys for the dense and optionally a larger (sparse) NMS radius.

    OpenCV dilates and erodes the keys with the dense window; an extremum for the larger radius is
    also one for the smaller, so the larger radius only tests the extrema of the first
    (:func:`sensor.vo.kernels_features.detect`).

    Returns
    -------
    u, v, cls, sparse_index : numpy.ndarray
        The dense extrema (int32 column, row; int8 class) and the indices of the sparse ones among
        them (empty for one radius).
    """
    if not 1 <= len(radii) <= 2:
        raise ValueError(f"one or two NMS radii, got {radii}")
    big = radii[1] if len(radii) == 2 else 0
    highest, lowest = (_WORKSPACE.get(name, keys.shape, np.float32) for name in ("highest", "lowest"))
    window = _window(radii[0])
    for i in range(2):
        cv2.dilate(keys[i], window, dst=highest[i])
        cv2.erode(keys[i], window, dst=lowest[i])
    return detect(keys, highest, lowest, float(tau), margin, radii[0], big, _TIE_PERIOD)


def non_maximum_suppression(
    blob: np.ndarray, corner: np.ndarray, n: int, tau: float, margin: int = BORDER_MARGIN
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local extrema of both filter responses, four classes (docs/visual_odometry.md §3, Neubeck & Van Gool 2006).

    Parameters
    ----------
    blob, corner : numpy.ndarray
        Filter responses (float32, integer-valued) from :func:`filter_responses`.
    n : int
        Suppression radius: an extremum is strict within its (2n+1)² window (ties broken by a fixed
        pattern), so two features of one class are more than n px apart.
    tau : float
        Threshold: maxima need response ≥ tau, minima ≤ −tau.
    margin : int
        Border [px] without features.

    Returns
    -------
    u, v, cls : numpy.ndarray
        Column, row (int32) and class (int8) of every feature, grouped by class 0…3.
    """
    if not 1 <= n <= MAX_NMS_N:
        raise ValueError(f"n must be in [1, {MAX_NMS_N}], got {n}")
    keys = np.empty((2, *blob.shape), dtype=np.float32)
    tie_keys(*(np.ascontiguousarray(x, dtype=np.int32) for x in (blob, corner)), _TIE_PERIOD, keys)
    u, v, cls, _ = _detect(keys, (n,), tau, margin)
    return u, v, cls


def compute_descriptors(sobel: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """32-byte descriptors at (u, v) [px of ``sobel``] (docs/visual_odometry.md §4).

    Parameters
    ----------
    sobel : numpy.ndarray
        (2, H, W) uint8 from :func:`sobel_responses`.
    u, v : numpy.ndarray
        Integer positions at least 5 px from the border.

    Returns
    -------
    numpy.ndarray
        (N, 32) uint8: (du, dv) pairs at the 16 offsets of :data:`DESCRIPTOR_OFFSETS`.
    """
    return describe(np.ascontiguousarray(sobel), np.asarray(u, np.int64), np.asarray(v, np.int64), DESCRIPTOR_OFFSETS)


def _feature_sets(
    sobel: np.ndarray, detected: tuple[np.ndarray, ...], scale: int, sparse: bool
) -> tuple[FeatureSet, FeatureSet | None]:
    """Dense (and sparse) features at the detected positions of the (2, H, W) Sobel responses, positions
    scaled to full resolution; the sparse set is a subset of the dense one, so its rows are taken from it."""
    u, v, cls, sparse_index = detected
    u, v, desc = features_at(sobel, u, v, scale, DESCRIPTOR_OFFSETS)
    dense = FeatureSet(u=u, v=v, cls=cls, desc=desc)
    if not sparse:
        return dense, None
    i = sparse_index
    return dense, FeatureSet(u=u[i], v=v[i], cls=cls[i], desc=desc[i])


def extract_features(image: np.ndarray, config: VOConfig) -> ImageFeatures:
    """Detect and describe the features of one rectified 8-bit grey image.

    Parameters
    ----------
    image : numpy.ndarray
        (H, W) uint8.
    config : VOConfig
        Detector parameters (``nms_n``, ``nms_tau``, ``half_resolution``, ``multi_stage``, ``refinement``).

    Returns
    -------
    ImageFeatures
        Dense (and sparse) features in full-resolution coordinates, plus the full-resolution Sobel
        responses when the matcher refines and a copy of the image for the gradient refinement.
    """
    if image.ndim != 2 or image.dtype != np.uint8:
        raise ValueError(f"expected an (H, W) uint8 grey image, got {image.dtype} {image.shape}")
    image = np.ascontiguousarray(image)
    # The full-resolution responses first, while the image is in the cache (cheaper than last).
    sobel_full = sobel_responses(image) if config.refinement > 0 else None
    work = half_resolution(image) if config.half_resolution else image
    scale = config.scale
    sobel = sobel_full if scale == 1 and sobel_full is not None else sobel_responses(work)
    radii = (config.nms_n, config.nms_n_sparse) if config.multi_stage else (config.nms_n,)
    detected = _detect(_keys(work), radii, config.nms_tau, BORDER_MARGIN)
    dense, sparse = _feature_sets(sobel, detected, scale, config.multi_stage)
    grey = image.copy() if config.gradient_refinement != "off" else None
    return ImageFeatures(dense=dense, sparse=sparse, sobel_full=sobel_full, shape=image.shape, grey=grey)
