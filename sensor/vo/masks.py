"""Image masks of the odometry: features inside a masked region (a moving body in view) are not taken.

A mask is a ``(height, width)`` bool array, True where no feature may be taken (the other units of the combination,
:func:`sensor.vehicle_bodies.exclusion_masks`). Features are dropped after detection, before matching: the
descriptors of the remaining features are those of the whole image, and the sparse set stays a subset of the dense
one. Without a mask the features are untouched (the same objects).
"""

from __future__ import annotations

import numpy as np

from sensor.vo.features import FeatureSet, ImageFeatures

__all__ = ["mask_features"]


def _keep(features: FeatureSet, excluded: np.ndarray) -> FeatureSet:
    h, w = excluded.shape
    u = np.clip(features.u, 0, w - 1)
    v = np.clip(features.v, 0, h - 1)
    keep = ~excluded[v, u]
    if keep.all():
        return features
    return FeatureSet(u=features.u[keep], v=features.v[keep], cls=features.cls[keep], desc=features.desc[keep])


def mask_features(features: ImageFeatures, excluded: np.ndarray | None) -> ImageFeatures:
    """The features of one image outside the mask ``excluded`` (``None``: all of them, unchanged).

    Raises
    ------
    ValueError
        The mask's shape is not the image's.
    """
    if excluded is None:
        return features
    excluded = np.asarray(excluded, dtype=bool)
    if excluded.shape != tuple(features.shape):
        raise ValueError(f"mask shape {excluded.shape} differs from the image shape {tuple(features.shape)}")
    sparse = None if features.sparse is None else _keep(features.sparse, excluded)
    return ImageFeatures(
        dense=_keep(features.dense, excluded),
        sparse=sparse,
        sobel_full=features.sobel_full,
        shape=features.shape,
        grey=features.grey,
    )
