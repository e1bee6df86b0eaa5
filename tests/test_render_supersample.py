"""Supersampled rendering (:attr:`sensor.camera.StereoRig.supersample`): each view drawn k times larger, averaged down.

* The geometry: a ``w × h`` rig supersampled ``k`` times renders exactly the ``cv2.INTER_AREA`` average of the same
  camera drawn at ``kw × kh`` (the same field of view), so the samples of each pixel are that pixel's and no other's;
  its depth is the large view's sample nearest each pixel's centre; with a sun the sky/shade alpha is averaged too.
* One sample a pixel (``supersample=1``) is the renderer's image without the setting, and more samples change it.
* Refused before rendering, in one line naming the field: outside 1 to 4, or a rendered side over
  :data:`sensor.camera.MAX_RENDER_PX` (the rig, the configuration's section and a rig of ``camera.rigs``).
* ``camera.supersample``, the section's or a rig's own, reaches that rig.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sensor.camera import MAX_RENDER_PX, StereoRig
from vehicle_model.errors import InputError
from vehicle_model.geometry import CombinationPose

rendering = pytest.mark.rendering

SIDE = {"hfov_deg": 90.0, "psi_c2v_deg": 270.0, "lateral": 1.25, "station": -4.0}


@pytest.fixture(scope="module")
def world():
    from sensor.world import RoadPath, build_world

    return build_world(RoadPath.straight(160.0, start=(-80.0, 0.0)), scenery_density=1.0, seed=3)


def _pair(world, rig: StereoRig, pose: np.ndarray):
    from sensor.renderer import StereoRenderer

    renderer = StereoRenderer(world, rig, bodies=False)
    return renderer.render_poses(pose, pose, depth=True, frame=0)


@pytest.fixture(scope="module")
def camera_pose():
    from vehicle_model.presets import vehicle_preset

    rig = StereoRig.from_degrees(width=160, height=64, **SIDE)
    return rig.camera_in_world(vehicle_preset("lst"), CombinationPose(0.0, 0.0, 0.05, 0.0), "left")


@rendering
@pytest.mark.parametrize("k", [2, 3])
def test_a_supersampled_view_is_the_large_view_averaged_down(world, camera_pose, k) -> None:
    """Bit-identical grey levels against ``INTER_AREA`` of the ``k``-times view (no tolerance: the same samples);
    the depth is the large view's at offset ``k // 2`` in each block (exact); the silhouettes of the scenery make the
    averaging show (the supersampled view differs from the one-sample view in over 1 % of the pixels)."""
    small = StereoRig.from_degrees(width=160, height=64, supersample=k, **SIDE)
    large = StereoRig.from_degrees(width=160 * k, height=64 * k, **SIDE)
    got = _pair(world, small, camera_pose)
    big = _pair(world, large, camera_pose)
    assert got.left.shape == (64, 160) and got.depth_left is not None and big.depth_left is not None
    np.testing.assert_array_equal(got.left, cv2.resize(big.left, (160, 64), interpolation=cv2.INTER_AREA))
    np.testing.assert_array_equal(got.depth_left, big.depth_left[k // 2 :: k, k // 2 :: k])
    one = _pair(world, small.replace(supersample=1), camera_pose)
    assert np.mean(one.left != got.left) > 0.01


@rendering
def test_one_sample_a_pixel_is_the_image_without_the_setting(world, camera_pose) -> None:
    """``supersample=1`` renders exactly the default rig's pair (the setting's default leaves every image as it
    was)."""
    plain = _pair(world, StereoRig.from_degrees(width=160, height=64, **SIDE), camera_pose)
    one = _pair(world, StereoRig.from_degrees(width=160, height=64, supersample=1, **SIDE), camera_pose)
    np.testing.assert_array_equal(plain.left, one.left)
    np.testing.assert_array_equal(plain.depth_left, one.depth_left)


@pytest.mark.parametrize(
    ("changes", "allowed"),
    [
        ({"supersample": 0}, "an integer, 1 to 4"),
        ({"supersample": 5}, "an integer, 1 to 4"),
        ({"supersample": 2.0}, "an integer, 1 to 4"),
        ({"supersample": 3, "width": 4000}, f"× supersample ≤ {MAX_RENDER_PX} px"),
    ],
)
def test_a_rig_refuses_a_supersampling_it_cannot_render(changes, allowed) -> None:
    with pytest.raises(InputError, match=r"^rig\.supersample = .* is out of range; allowed: .*" + allowed):
        StereoRig(**changes)


def test_the_configuration_refuses_a_supersampling_it_cannot_render() -> None:
    """The section's value out of 1..4 or too large a rendered size is a ConfigError naming ``camera.supersample``
    (or the section); a rig's own combination of width and supersampling an InputError naming that rig."""
    from scenarios.config import ConfigError, load_scenario

    with pytest.raises(ConfigError, match=r"camera\.supersample = 5"):
        load_scenario("roundabout-3", {"camera.supersample": 5})
    with pytest.raises(ConfigError, match=rf"supersample = 4: width and height × supersample ≤ {MAX_RENDER_PX} px"):
        load_scenario("roundabout-3", {"camera.supersample": 4, "camera.width": 4096})
    rigs = [{"unit": 1, "supersample": 3, "width": 3000}]
    overrides = {"vehicle": "au-b-double", "estimators.viso_ot": True, "camera.rigs": rigs}
    with pytest.raises(InputError, match=r"^camera\.rigs\[0\]\.supersample = 3: .* here 3000 px$"):
        load_scenario("roundabout-3", overrides)


def test_the_configurations_supersampling_reaches_each_rig() -> None:
    """The section's ``camera.supersample`` is every rig's; a rig of ``camera.rigs`` may set its own."""
    from scenarios.camera.build import rig_from_config, rigs_from_config
    from scenarios.config import load_scenario

    assert rig_from_config(load_scenario("roundabout-3")).supersample == 1
    assert rig_from_config(load_scenario("roundabout-3", {"camera.supersample": 3})).supersample == 3
    rigs = [{"unit": 1, "facing": "left", "supersample": 2}, {"unit": 2, "facing": "rear"}]
    config = load_scenario("roundabout-3", {"vehicle": "au-b-double", "camera.rigs": rigs})
    assert [rig.supersample for rig in rigs_from_config(config)] == [2, 1]
