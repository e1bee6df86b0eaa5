"""Friction and slope fields."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vehicle_model.surface import (
    FlatRoad,
    FrictionPatch,
    PatchyFriction,
    RadialCamber,
    Surface,
    UniformCrossfall,
    grade_to_sin,
)


def test_patches_override_base_and_later_patches_win():
    field = PatchyFriction(0.8, (FrictionPatch(0, 10, -5, 5, 0.1), FrictionPatch(5, 10, -5, 5, 0.3)))
    pts = np.array([[-1.0, 0.0], [2.0, 0.0], [7.0, 0.0], [7.0, 6.0]])
    assert field(pts) == pytest.approx([0.8, 0.1, 0.3, 0.8])


def test_crossfall_vector():
    s = grade_to_sin(2.5)
    assert s == pytest.approx(math.sin(math.atan(0.025)))
    v = UniformCrossfall(2.5, -math.pi / 2)(np.zeros((3, 2)))
    assert v == pytest.approx(np.tile([0.0, -s], (3, 1)))


@pytest.mark.parametrize(("direction", "sign"), [("outward", 1.0), ("inward", -1.0)])
def test_radial_camber_points_along_the_radius(direction, sign):
    camber = RadialCamber((10.0, -3.0), 5.0, direction)
    pts = np.array([[20.0, -3.0], [10.0, 7.0], [10.0 - 6.0, -3.0 - 8.0]])
    v = camber(pts)
    radial = (pts - [10.0, -3.0]) / np.linalg.norm(pts - [10.0, -3.0], axis=1)[:, None]
    assert v == pytest.approx(sign * grade_to_sin(5.0) * radial)
    assert np.isfinite(camber(np.array([[10.0, -3.0]]))).all()  # finite at the centre


def test_uniform_surfaces_are_recognised():
    assert Surface().is_uniform
    assert Surface.preset("ice", UniformCrossfall(2.0, 0.0)).is_uniform
    assert not Surface(slope=RadialCamber((0, 0), 2.0)).is_uniform
    assert isinstance(Surface().slope, FlatRoad)
