"""Terrains with closed-form heights for the terrain tests, independent of :mod:`vehicle_model.terrain`'s own."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TiltedPlane:
    """z = a·x + b·y + c."""

    a: float
    b: float
    c: float = 0.0

    def height(self, points):
        p = np.asarray(points, float)
        return self.a * p[:, 0] + self.b * p[:, 1] + self.c

    def gradient(self, points):
        return np.tile([self.a, self.b], (len(points), 1))
