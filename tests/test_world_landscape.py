"""The landscape beyond the roadside: present at every scenery density, in its band, low on
the horizon and inside the camera's far plane."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensor.camera import StereoRig
from sensor.world import RoadPath, build_world
from sensor.world.ground import ground_parts
from sensor.world.landscape import LANDSCAPE_REACH, MAX_ELEVATION, TREE_CLEARANCE, landscape_parts
from sensor.world.layout import build_layout


@pytest.fixture(scope="module")
def road() -> RoadPath:
    return RoadPath.straight(400.0, start=(-200.0, 0.0))


def _world_vertices(part) -> np.ndarray:
    pos = part.positions.astype(np.float64)
    if part.poses is None:
        return pos
    return np.concatenate([pos @ p[:3, :3].T + p[:3, 3] for p in part.poses])


def _landscape(world) -> dict[str, object]:
    return {p.name: p for p in world.parts if p.name.startswith("landscape_") or p.name == "horizon"}


def test_landscape_is_present_and_identical_at_every_density(road: RoadPath) -> None:
    worlds = {d: build_world(road, seed=2, scenery_density=d) for d in (0.0, 0.5, 1.0)}
    names = set(_landscape(worlds[1.0]))
    assert {"landscape_hedgerows", "landscape_trees", "landscape_barn_walls", "horizon"} <= names
    for d in (0.0, 0.5):
        land = _landscape(worlds[d])
        assert set(land) == names, d
        for name, part in _landscape(worlds[1.0]).items():
            np.testing.assert_array_equal(land[name].positions, part.positions)
            if part.poses is not None:
                np.testing.assert_array_equal(land[name].poses, part.poses)
    # Its foliage keeps its texture far away (a contrast-preserving mipmap chain of its own).
    assert _landscape(worlds[0.0])["landscape_hedgerows"].texture == "landscape_foliage" in worlds[0.0].mipmaps
    # The landscape is part of the ground, not roadside scenery: density 0 has no scenery objects.
    assert all(p.category == "ground" for p in _landscape(worlds[0.0]).values())
    assert sum(worlds[0.0].object_counts.values()) == 0
    bare = build_world(road, seed=2, scenery_density=0.0, landscape=False, horizon=False)
    assert not _landscape(bare)
    assert worlds[0.0].triangle_count - bare.triangle_count > 5000


def test_landscape_stands_in_its_band_low_on_the_horizon_and_inside_the_far_plane(road: RoadPath) -> None:
    world = build_world(road, seed=2, scenery_density=0.0)
    lay = build_layout(world.road, world.config)
    land = _landscape(world)
    hedges = _world_vertices(land["landscape_hedgerows"])
    clear = lay.clearance(hedges[:, :2])
    # Pieces are placed by their midpoints in (scenery_reach, LANDSCAPE_REACH); vertices reach half a piece further.
    assert clear.min() > world.config.scenery_reach - 4.0 and clear.max() < LANDSCAPE_REACH + 4.0
    trees = land["landscape_trees"].poses[:, :2, 3]
    assert len(trees) >= 50 and lay.clearance(trees).min() > TREE_CLEARANCE
    # Every landscape object's top, seen from 3 m above the nearest road point, within MAX_ELEVATION
    # (+ the jitter of the tree crowns) of the horizon; everything but the horizon band within the
    # landscape's reach.
    for name, part in land.items():
        v = _world_vertices(part)
        c = lay.clearance(v[:, :2])
        if name != "horizon":
            elevation = (v[:, 2] - 3.0) / np.maximum(c, 1.0)
            assert elevation.max() < MAX_ELEVATION * 1.2, name
        # The camera's far plane covers the whole landscape from anywhere on the road.
        d = np.hypot(v[:, 0, None] - lay.samples[None, ::40, 0], v[:, 1, None] - lay.samples[None, ::40, 1])
        assert d.max() < StereoRig().zfar, name
    assert math.isfinite(world.triangle_count) and world.triangle_count < 40000


def test_landscape_is_deterministic(road: RoadPath) -> None:
    world = build_world(road, seed=2, scenery_density=0.0)
    lay = build_layout(world.road, world.config)
    _, xs, ys = ground_parts(lay, np.random.default_rng(0))
    a, b, c = (landscape_parts(lay, np.random.default_rng(s), xs, ys) for s in (5, 5, 6))
    assert [p.name for p in a] == [p.name for p in b]
    for pa, pb in zip(a, b, strict=True):
        np.testing.assert_array_equal(pa.positions, pb.positions)
        np.testing.assert_array_equal(pa.colors, pb.colors)
    assert not np.array_equal(a[0].positions, c[0].positions)
