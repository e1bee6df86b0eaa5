"""Brown–Conrady lens: validation, the distortion round trip, the wide pinhole render and the remap maps."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from sensor.camera import Lens, StereoRig
from sensor.lens import (
    LensDistortion,
    distort_pixels,
    distortion_maps,
    remap,
    undistort_pixels,
    wide_pinhole_rig,
)
from vehicle_model.errors import InputError

WIDE_ANGLE = Lens(k1=-0.2, k2=0.05, p1=1e-3, p2=-5e-4, k3=0.0)
"""A strong wide-angle lens on the paper's 100° camera: 170 px of barrel distortion at the corners."""


@pytest.fixture(scope="module")
def rig() -> StereoRig:
    return StereoRig.from_degrees(roll_deg=-0.15, yaw_deg=0.10)


@pytest.fixture(scope="module")
def distortion(rig: StereoRig) -> LensDistortion:
    return LensDistortion.build(rig, WIDE_ANGLE, Lens(k1=-0.18, k2=0.04, p1=-5e-4, p2=8e-4), fixed_point=False)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"k1": -1.5}, r"k1\s+Input should be greater than or equal to -1"),
        ({"p2": 0.06}, r"p2\s+Input should be less than or equal to 0\.05"),
        ({"k3": math.nan}, r"k3\s+Input should be a finite number"),
        ({"k4": 0.1}, r"k4\s+Extra inputs are not permitted"),
    ],
)
def test_bad_coefficients_are_refused_by_name_and_range(changes, message) -> None:
    with pytest.raises(ValueError, match=message):
        Lens(**changes)


def test_the_schema_names_the_lens_its_range_and_the_reason() -> None:
    from scenarios.config import ConfigError, load_scenario

    assert load_scenario("roundabout-3", {"camera.lens.k1": -0.1}).camera.lens.coefficients[0] == -0.1
    with pytest.raises(ConfigError, match=r"camera\.right_lens\.k2 = 3\.0: Input should be less .* radial"):
        load_scenario("roundabout-3", {"camera.right_lens": {"k2": 3.0}})


def test_a_lens_that_folds_over_inside_the_image_is_refused(rig: StereoRig) -> None:
    with pytest.raises(InputError, match="folds over"):
        wide_pinhole_rig(rig, Lens(k1=-0.6))


def test_distortion_round_trip_within_0_05_px(rig: StereoRig) -> None:
    # A grid of ideal points over the whole distorted image (corners included), distorted by the Brown–Conrady
    # model (cv2.projectPoints) and undistorted again (cv2.undistortPoints).
    k = rig.intrinsics()
    wide = wide_pinhole_rig(rig, WIDE_ANGLE)
    pad_u, pad_v = (wide.width - rig.width) // 2, (wide.height - rig.height) // 2
    u, v = np.meshgrid(np.linspace(-pad_u, rig.width - 1 + pad_u, 120), np.linspace(-pad_v, rig.height - 1 + pad_v, 40))
    ideal = np.column_stack([u.ravel(), v.ravel()])
    distorted = distort_pixels(k, WIDE_ANGLE, ideal)
    inside = (distorted[:, 0] >= 0) & (distorted[:, 0] <= rig.width - 1) & (distorted[:, 1] >= 0)
    inside &= distorted[:, 1] <= rig.height - 1
    assert inside.sum() > 2000
    back = undistort_pixels(k, WIDE_ANGLE, distorted[inside])
    err = np.linalg.norm(back - ideal[inside], axis=1)
    assert err.max() < 0.05
    # the lens is not a no-op: the corners move by well over 100 px
    assert np.linalg.norm(distorted[inside] - ideal[inside], axis=1).max() > 100.0


def test_the_wide_render_keeps_the_focal_length_and_covers_every_pixel(
    rig: StereoRig, distortion: LensDistortion
) -> None:
    wide = distortion.wide
    assert wide.focal_length == pytest.approx(rig.focal_length, rel=1e-12)
    assert wide.hfov > rig.hfov
    assert (wide.width - rig.width) % 2 == 0 and (wide.height - rig.height) % 2 == 0
    pad_u, pad_v = distortion.crop
    assert np.allclose(np.array(wide.principal_point) - rig.principal_point, [pad_u, pad_v])
    assert wide.misalignment == rig.misalignment and wide.baseline == rig.baseline
    for map_x, map_y in (distortion.maps_left, distortion.maps_right):
        assert map_x.shape == (rig.height, rig.width) and map_x.dtype == np.float32
        # every distorted pixel has a source with its bilinear neighbour inside the wide render
        assert map_x.min() >= 0 and map_y.min() >= 0
        assert map_x.max() <= wide.width - 2 and map_y.max() <= wide.height - 2
    # the maps are tight: the padding is at most a few pixels more than the stronger lens needs
    assert min(distortion.maps_left[0].min(), distortion.maps_right[0].min()) < 5
    assert wide_pinhole_rig(rig, Lens()) is rig


def _blob_image(shape: tuple[int, int], centres: np.ndarray, sigma: float) -> np.ndarray:
    img = np.zeros(shape, dtype=np.float32)
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    for cu, cv in centres:
        u0, u1 = int(cu) - 8, int(cu) + 9
        v0, v1 = int(cv) - 8, int(cv) + 9
        du, dv = xx[v0:v1, u0:u1] - cu, yy[v0:v1, u0:u1] - cv
        img[v0:v1, u0:u1] += 200.0 * np.exp(-(du**2 + dv**2) / (2.0 * sigma**2))
    return img


def _centroids(img: np.ndarray, guesses: np.ndarray, radius: int = 6) -> np.ndarray:
    out = []
    for gu, gv in guesses:
        u0, v0 = round(gu) - radius, round(gv) - radius
        patch = img[v0 : v0 + 2 * radius + 1, u0 : u0 + 2 * radius + 1].astype(float)
        yy, xx = np.mgrid[0 : patch.shape[0], 0 : patch.shape[1]]
        w = patch.sum()
        out.append([u0 + (xx * patch).sum() / w, v0 + (yy * patch).sum() / w])
    return np.array(out)


@pytest.mark.parametrize("fixed_point", [False, True])
def test_the_remapped_image_puts_points_where_project_points_does(rig: StereoRig, fixed_point: bool) -> None:
    # Known 3-D points imaged by the wide pinhole camera as Gaussian blobs, remapped into the distorted image:
    # the blobs' centroids land where cv2.projectPoints with the lens puts the points.
    wide = wide_pinhole_rig(rig, WIDE_ANGLE)
    maps = distortion_maps(rig, WIDE_ANGLE, wide, fixed_point=fixed_point)
    u, v = np.meshgrid(np.linspace(15, rig.width - 16, 23), np.linspace(15, rig.height - 16, 7))
    rays = undistort_pixels(rig.intrinsics(), WIDE_ANGLE, np.column_stack([u.ravel(), v.ravel()]) + 0.37, p=np.eye(3))
    points = np.column_stack([rays, np.ones(len(rays))]) * np.linspace(2.0, 40.0, len(rays))[:, None]
    pinhole = points[:, :2] / points[:, 2:3] * wide.focal_length + np.array(wide.principal_point)
    img = _blob_image((wide.height, wide.width), pinhole, sigma=1.6)
    distorted = remap(img, maps)
    expected, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), rig.intrinsics(), WIDE_ANGLE.coefficients)
    expected = expected.reshape(-1, 2)
    err = np.linalg.norm(_centroids(distorted, expected) - expected, axis=1)
    assert err.max() < 0.3
    assert np.median(err) < 0.1


def test_apply_distorts_a_pair_and_checks_its_shape(distortion: LensDistortion) -> None:
    wide = distortion.wide
    pair = np.full((wide.height, wide.width), 100, np.uint8), np.full((wide.height, wide.width), 50, np.uint8)
    left, right = distortion.apply(*pair)
    assert left.shape == right.shape == (distortion.rig.height, distortion.rig.width)
    assert (left == 100).all() and (right == 50).all()  # every pixel has a source: no black border
    with pytest.raises(InputError, match="expects"):
        distortion.apply(pair[0][:-1], pair[1])
