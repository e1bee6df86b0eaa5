"""The airfield world after the Bourn test site (de Saxe & Cebon 2018, §4.1, Fig 12) and ground detail."""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.setup.paths import roundabout_path
from sensor.camera import StereoRig
from sensor.world import WorldConfig, build_world
from sensor.world.detail import detail_mipmaps
from vehicle_model.errors import InputError
from vehicle_model.geometry import CombinationPose

rendering = pytest.mark.rendering


@pytest.fixture(scope="module")
def ring():
    return roundabout_path(50.0, 3.0, 1, 30.0, 30.0)


def test_airfield_world_has_apron_grain_fields_and_distant_objects(ring) -> None:
    world = build_world(ring, kind="airfield", seed=3)
    textures = {p.texture for p in world.parts}
    assert "tarmac" in textures and textures & {"crop", "stubble"}
    assert not textures & {"paint_line", "paint_dash", "setts", "grass", "plough", "verge"}
    assert world.object_counts["buildings"] >= 3 and world.object_counts["hedges"] > 0
    assert "tarmac" in world.mipmaps and "crop" in world.mipmaps  # detail to the horizon
    loop = world.loops[0]
    assert loop.outer_edge - loop.inner_edge == pytest.approx(40.0)
    # The distant hedges, buildings and horizon woods are landscape: the same at every scenery density.
    assert {"hedge_0", "hangar_0", "horizon"} <= {p.name for p in world.parts}
    assert not any(p.category == "scenery" for p in world.parts)
    bare = build_world(ring, kind="airfield", seed=3, scenery_density=0.0)
    assert bare.object_counts == world.object_counts
    assert [p.name for p in bare.parts] == [p.name for p in world.parts]
    # Both kinds give the ground detail at every distance by default; it can be switched off.
    roadside = build_world(ring, seed=3).mipmaps
    assert set(roadside) >= {"grass", "crop", "asphalt", "horizon", "landscape_foliage"}
    assert "foliage" not in roadside  # the roadside trees and hedges keep the box-filtered chain
    assert WorldConfig().detailed_ground and not WorldConfig(ground_detail=False).detailed_ground
    with pytest.raises(InputError, match="kind"):
        WorldConfig(kind="moon")


def test_detail_mipmaps_keep_contrast_and_mean() -> None:
    rng = np.random.default_rng(0)
    img = np.clip(128 + 40 * rng.standard_normal((64, 64, 3)), 0, 255).astype(np.uint8)
    levels = detail_mipmaps(img)
    assert [lv.shape[0] for lv in levels] == [32, 16, 8, 4, 2, 1]
    box = detail_mipmaps(img, max_gain=1.0)
    assert levels[2].std() > 2.0 * box[2].std()
    assert abs(float(levels[2].mean()) - float(img.mean())) < 2.0


@rendering
def test_airfield_renders_with_features_to_the_horizon(ring) -> None:
    import cv2

    from sensor.renderer import StereoRenderer
    from vehicle_model.presets import vehicle_preset

    world = build_world(ring, kind="airfield", scenery_density=0.0)
    rig = StereoRig()
    i = int(np.searchsorted(ring.s, 150.0))
    pose = CombinationPose(ring.x[i], ring.y[i], ring.heading[i], 0.0)
    pair = StereoRenderer(world, rig, vehicle_preset("reference")).render(pose)
    corners = cv2.goodFeaturesToTrack(pair.left, 3000, 0.01, 5)
    assert corners is not None and len(corners) >= 300
    far = corners[:, 0, 1] < rig.principal_point[1] + 40  # beyond ~40 m on the ground
    assert far.sum() >= 15  # measured 26 (seed 0)
