"""Feature detection and description of VISO2-S (Geiger, Ziegler & Stiller 2011, §III-A).

* Two 5×5 interest filters, blob and corner (checkerboard), on the (optionally 2×2 box-downsampled)
  image; non-maximum suppression gives four classes — blob minimum (0), blob maximum (1), corner
  minimum (2), corner maximum (3) — with |response| ≥ tau (viso2s reference §1.2).
* Descriptor: 5×5 Sobel-like responses (smoothing [1 4 6 4 1], derivative [1 2 0 −2 −1]) scaled
  by 1/128, offset by 128 and saturated to uint8; the horizontal and vertical responses sampled at
  16 sparse offsets of the 11×11 window give 32 bytes, compared by SAD (reference §1.3).

Everything is vectorised with OpenCV and numpy. The extrema are found with rectangular
``cv2.dilate``/``cv2.erode``: a pixel is an extremum when it equals the extremum of its (2n+1)²
neighbourhood. Filter responses are integers; ties are broken by a fixed sub-integer offset pattern
that is unique inside any window, so detected extrema are strict and at least n+1 px apart
(Chebyshev) — the result of Neubeck & Van Gool's block algorithm, not its exact tie behaviour. The
sparse first-pass set (radius 3n, capped) is the subset of the dense extrema that are also extrema of
the larger window, read from the dense dilation at a few offsets (a (2R+1)² window is the union of
(2r+1)² windows on a small grid). The border margin is 9 px at detection resolution (libviso2 2018).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numpy as np

from sensor.vo.config import MAX_NMS_N, VOConfig

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

# Geiger et al. 2011, §III-A; viso2s reference §1.2.
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
# The checkerboard kernel is separable: −a·aᵀ with a = [−1 −1 0 1 1].
_CORNER_A = np.array([-1, -1, 0, 1, 1], dtype=np.float32)

# Sobel 5×5 (reference §1.3): smoothing [1 4 6 4 1] ⊗ derivative [1 2 0 −2 −1] as a convolution, i.e.
# correlation with [−1 −2 0 2 1] (a positive response for intensity increasing to the right/down).
_SOBEL_SMOOTH = np.array([1, 4, 6, 4, 1], dtype=np.float32)
_SOBEL_DERIV = np.array([-1, -2, 0, 2, 1], dtype=np.float32)

#: (du, dv) sampling offsets of the 32-byte descriptor inside the 11×11 window (reference §1.3).
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

# Feature classes (reference §1.2).
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
    """

    dense: FeatureSet
    sparse: FeatureSet | None
    sobel_full: np.ndarray | None
    shape: tuple[int, int]


def half_resolution(image: np.ndarray) -> np.ndarray:
    """2×2 box-mean downsampling (reference §1.2); odd trailing rows/columns are dropped."""
    h, w = image.shape
    h2, w2 = h // 2, w // 2
    return cv2.resize(image[: 2 * h2, : 2 * w2], (w2, h2), interpolation=cv2.INTER_AREA)


def sobel_responses(image: np.ndarray) -> np.ndarray:
    """5×5 Sobel responses /128 + 128, saturated to uint8 (reference §1.3).

    Returns
    -------
    numpy.ndarray
        (2, H, W) uint8: horizontal (du) and vertical (dv) responses.
    """
    out = np.empty((2, *image.shape), dtype=np.uint8)
    # The 1/128 scale is folded into the derivative kernel; OpenCV rounds where libviso2 shifts.
    deriv = _SOBEL_DERIV / 128.0
    cv2.sepFilter2D(image, cv2.CV_8U, deriv, _SOBEL_SMOOTH, dst=out[0], delta=128.0, borderType=cv2.BORDER_REPLICATE)
    cv2.sepFilter2D(image, cv2.CV_8U, _SOBEL_SMOOTH, deriv, dst=out[1], delta=128.0, borderType=cv2.BORDER_REPLICATE)
    return out


def filter_responses(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Blob and corner (checkerboard) filter responses (reference §1.2).

    The blob kernel is −(5×5 box) + 2·(3×3 box) + 7·(centre): two unnormalised box filters (libviso2
    uses an integral image to the same end); the checkerboard kernel is separable.

    Returns
    -------
    blob, corner : numpy.ndarray
        float32 responses with integer values (the kernels are symmetric, so correlation = convolution).
    """
    box5 = cv2.boxFilter(image, cv2.CV_32F, (5, 5), normalize=False, borderType=cv2.BORDER_REPLICATE)
    box3 = cv2.boxFilter(image, cv2.CV_32F, (3, 3), normalize=False, borderType=cv2.BORDER_REPLICATE)
    blob = cv2.scaleAdd(image.astype(np.float32), 7.0, cv2.scaleAdd(box3, 2.0, -box5))
    corner = cv2.sepFilter2D(image, cv2.CV_32F, _CORNER_A, -_CORNER_A, borderType=cv2.BORDER_REPLICATE)
    return blob, corner


@lru_cache(maxsize=8)
def _tie_breaker(shape: tuple[int, int]) -> np.ndarray:
    """Offsets in [0, 0.5) that differ between any two pixels of a (2·MAX_NMS_N+1)² window.

    Added to the integer responses they make every window's extremum unique without changing the
    order of different integer values. |response| ≤ 16·255 < 4096, so float32 resolves steps of
    1/(2·21²) ≈ 1.1e-3 ≫ its 4.9e-4 ulp there.
    """
    period = 2 * MAX_NMS_N + 1
    rows = np.arange(shape[0]) % period
    cols = np.arange(shape[1]) % period
    pattern = (cols[None, :] + period * rows[:, None]).astype(np.float32) / np.float32(2 * period * period)
    pattern.setflags(write=False)
    return pattern


def _detect(
    blob: np.ndarray, corner: np.ndarray, radii: tuple[int, ...], tau: float, margin: int
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Extrema for several NMS radii (ascending) at once: (flat pixel index, class) per radius.

    An extremum for a larger radius is also one for a smaller radius, so the larger radii only test
    the candidates of the first.
    """
    h, w = blob.shape
    if h <= 2 * margin or w <= 2 * margin:
        return [(np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int8)) for _ in radii]
    inner = (slice(margin, h - margin), slice(margin, w - margin))
    inner_w = w - 2 * margin
    jitter = _tie_breaker((h, w))
    kernels = [cv2.getStructuringElement(cv2.MORPH_RECT, (2 * n + 1, 2 * n + 1)) for n in radii]
    found: list[list[tuple[np.ndarray, int]]] = [[] for _ in radii]
    # A (2R+1)² window is the union of (2r+1)² windows centred on an m×m grid of offsets within
    # ±(R − r): the larger radii only look up the first radius's extreme image around the candidates,
    # dropping a candidate as soon as one tile holds a more extreme value.
    r = radii[0]
    tiles: list[np.ndarray | None] = []
    for big in radii[1:]:
        m = -(-(2 * big + 1) // (2 * r + 1))
        grid = np.linspace(-(big - r), big - r, m).round().astype(np.int64)
        exact = m == 1 or np.diff(grid).max() <= 2 * r + 1
        offsets = (grid[:, None] * w + grid[None, :]).ravel()
        tiles.append(offsets[offsets != 0] if exact and big - r <= margin else None)
    for base, response in ((BLOB_MIN, blob), (CORNER_MIN, corner)):
        unique = cv2.add(response, jitter)
        flat = unique.ravel()
        core, raw = unique[inner], response[inner]
        for cls, morph, strong, sign in ((base, cv2.erode, raw <= -tau, -1), (base + 1, cv2.dilate, raw >= tau, 1)):
            extreme = morph(unique, kernels[0])
            hits = np.flatnonzero((core == extreme[inner]) & strong)
            candidates = (hits // inner_w + margin) * w + hits % inner_w + margin  # flat index in the image
            found[0].append((candidates, cls))
            ext = extreme.ravel()
            for level, (kernel, tile) in enumerate(zip(kernels[1:], tiles, strict=True), start=1):
                if tile is None:
                    keep = candidates[flat[candidates] == morph(unique, kernel).ravel()[candidates]]
                else:
                    keep = candidates
                    for offset in tile:
                        value = flat[keep]
                        beyond = ext[keep + offset]
                        keep = keep[value >= beyond] if sign > 0 else keep[value <= beyond]
                found[level].append((keep, cls))
    return [
        (
            np.concatenate([idx for idx, _ in level]),
            np.concatenate([np.full(idx.shape[0], cls, dtype=np.int8) for idx, cls in level]),
        )
        for level in found
    ]


def non_maximum_suppression(
    blob: np.ndarray, corner: np.ndarray, n: int, tau: float, margin: int = BORDER_MARGIN
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local extrema of both filter responses, four classes (reference §1.2, Neubeck & Van Gool 2006).

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
    flat, cls = _detect(blob, corner, (n,), tau, margin)[0]
    w = blob.shape[1]
    return (flat % w).astype(np.int32), (flat // w).astype(np.int32), cls


def compute_descriptors(sobel: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """32-byte descriptors at (u, v) [px of ``sobel``] (reference §1.3).

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
    pairs = cv2.merge([sobel[0], sobel[1]]).view(np.uint16)[..., 0]
    flat = v.astype(np.int64) * sobel.shape[2] + u
    return _feature_set(pairs, flat, np.zeros(flat.shape[0], dtype=np.int8), 1).desc


def _feature_set(pairs: np.ndarray, flat: np.ndarray, cls: np.ndarray, scale: int) -> FeatureSet:
    """Features at flat pixel indices of the (H, W) uint16 image of interleaved (du, dv) bytes."""
    w = pairs.shape[1]
    offsets = DESCRIPTOR_OFFSETS[:, 1] * w + DESCRIPTOR_OFFSETS[:, 0]
    # One uint16 gather fetches du and dv together: 32 bytes = 16 interleaved (du, dv) pairs.
    desc = np.take(pairs.reshape(-1), flat[:, None] + offsets[None, :]).view(np.uint8)
    u = (flat % w).astype(np.int32) * scale
    v = (flat // w).astype(np.int32) * scale
    return FeatureSet(u=u, v=v, cls=cls, desc=desc)


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
        responses when the matcher refines.
    """
    if image.ndim != 2 or image.dtype != np.uint8:
        raise ValueError(f"expected an (H, W) uint8 grey image, got {image.dtype} {image.shape}")
    image = np.ascontiguousarray(image)
    work = half_resolution(image) if config.half_resolution else image
    scale = config.scale
    sobel = sobel_responses(work)
    pairs = cv2.merge([sobel[0], sobel[1]]).view(np.uint16)[..., 0]
    blob, corner = filter_responses(work)
    radii = (config.nms_n, config.nms_n_sparse) if config.multi_stage else (config.nms_n,)
    detected = _detect(blob, corner, radii, config.nms_tau, BORDER_MARGIN)
    levels = [_feature_set(pairs, flat, cls, scale) for flat, cls in detected]
    dense = levels[0]
    sparse = levels[1] if config.multi_stage else None
    if config.refinement > 0:
        sobel_full = sobel if not config.half_resolution else sobel_responses(image)
    else:
        sobel_full = None
    return ImageFeatures(dense=dense, sparse=sparse, sobel_full=sobel_full, shape=image.shape)
