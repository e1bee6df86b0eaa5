"""Terrain: the ground's height ``z(x, y)`` over the horizontal plane, and its gradient.

A terrain is any object with :meth:`Terrain.height` and :meth:`Terrain.gradient` over global horizontal points
``(x, y)`` [m] (docs/terrain.md). The vehicle model's ``x, y`` are horizontal coordinates, so a terrain adds the
third dimension without changing them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


class Terrain(Protocol):
    """A height field over the horizontal plane."""

    def height(self, points: np.ndarray) -> np.ndarray:
        """Ground height ``z`` [m] at global horizontal points ``(N, 2)`` → ``(N,)``."""
        ...

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """Ground gradient ``(∂z/∂x, ∂z/∂y)`` at global horizontal points ``(N, 2)`` → ``(N, 2)``."""
        ...


@dataclass(frozen=True)
class FlatTerrain:
    """The horizontal plane ``z = 0``."""

    def height(self, points: np.ndarray) -> np.ndarray:
        """Zero at every point."""
        return np.zeros(len(points))

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """Zero at every point."""
        return np.zeros((len(points), 2))
