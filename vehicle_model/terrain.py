# vehicle_model/terrain.py
"""The ground under the combination: a height field z(x, y) (the Terrain protocol) and the level plane."""

from dataclasses import dataclass
from typing import Protocol

import numpy as np


class Terrain(Protocol):
    """Ground height z(x, y) over the horizontal plane."""

    def height(self, points: np.ndarray) -> np.ndarray: ...  # (N, 2) global x, y [m] -> (N,) z [m]
    def gradient(self, points: np.ndarray) -> np.ndarray: ...  # (N, 2) -> (N, 2) (dz/dx, dz/dy)


@dataclass(frozen=True)
class FlatTerrain:
    def height(self, points):
        return np.zeros(len(points))

    def gradient(self, points):
        return np.zeros((len(points), 2))
