"""The whole combination in the cameras' view: units drawn where the geometry puts them, masked out of the odometry.

* A unit drawn at a known pose appears where the projection says (depth within 1 % of the box face's distance), and
  every pixel the units change lies inside their exclusion mask.
* The tractor–semi-trailer rear camera: the tractor is never in view, so drawing the units changes no pixel.
* A lead trailer's rear camera with the rear trailer in view (the au-a-double's unit 1 looking back at the rear
  semi-trailer's front wall, 2.15 m behind it): with the mask its motions are as good as with that trailer not drawn;
  without it the odometry follows the wall (it moves with the camera) and reports almost no motion.
* Two rigs on different units rendered from the one OpenGL context of the process, the world's scene built once.
"""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.setup.paths import roundabout_path
from sensor.camera import StereoRig, project
from sensor.vehicle_bodies import exclusion_masks, unit_boxes, unit_poses
from sensor.vo import StereoOdometry, VOConfig
from sensor.vo.masks import mask_features
from sensor.world import build_world
from vehicle_model.geometry import ChainPose, CombinationPose
from vehicle_model.presets import vehicle_preset
from vehicle_model.rigid import invert_rigid

rendering = pytest.mark.rendering

RADIUS = 30.0


@pytest.fixture(scope="module")
def world():
    return build_world(roundabout_path(RADIUS, 0.25, 1, 20.0, 5.0), scenery_density=1.0, seed=1)


@pytest.fixture(scope="module")
def b_double():
    return vehicle_preset("au-b-double")


@pytest.fixture(scope="module")
def a_double():
    return vehicle_preset("au-a-double")


def _renderer(world, rig, params, **kwargs):
    from sensor.renderer import StereoRenderer

    return StereoRenderer(world, rig, params, **kwargs)


@rendering
def test_a_unit_appears_where_the_projection_says(world, b_double) -> None:
    """A forward-looking camera on the rear trailer sees the lead trailer's box: the depth at the projected centre of
    the box's rear face equals that point's distance along the optical axis (within 1 %); every pixel the units
    change lies inside their exclusion mask (no margin)."""
    rig = StereoRig.from_degrees(width=320, height=96, unit=2, psi_c2v_deg=0.0, station=-10.0)
    pose = ChainPose(-8.0, 1.0, 0.05, (0.08, 0.12))
    lead_body = unit_boxes(b_double)[1][0]
    assert lead_body.kind == "body"
    frame = unit_poses(b_double, pose)[1]
    centre = np.array([lead_body.lo[0], 0.5 * (lead_body.lo[1] + lead_body.hi[1]), 2.8])  # on its rear face
    world_point = frame[:3, :3] @ centre + frame[:3, 3]
    camera = rig.camera_in_world(b_double, pose, "left")
    u, v = project(rig.intrinsics(), invert_rigid(camera), world_point[None])[0]
    expected = float((invert_rigid(camera)[:3, :3] @ world_point + invert_rigid(camera)[:3, 3])[2])
    with_units = _renderer(world, rig, b_double)
    _, depth = with_units.render_view(pose, depth=True)
    got = float(depth[round(float(v)), round(float(u))])
    assert got == pytest.approx(expected, rel=0.01)
    _, bare = _renderer(world, rig, b_double, bodies=False).render_view(pose, depth=True)
    changed = np.abs(depth - bare) > 1e-3
    assert changed.sum() > 0.05 * changed.size  # the lead trailer fills a good part of the view
    mask = exclusion_masks(
        b_double, pose, (camera,), rig.intrinsics(), (rig.width, rig.height), skip_unit=2, margin_px=1
    )
    assert mask is not None
    assert not (changed & ~mask[0]).any()


@rendering
def test_tractor_semi_rear_camera_is_unchanged_by_the_units(world) -> None:
    """The rear camera of the tractor–semi-trailer never sees the tractor: the pair is bit-identical with and without
    the units drawn (at a sharp articulation), and a ChainPose renders what its CombinationPose renders; the tractor's
    node was placed (the comparison is not vacuous)."""
    params = vehicle_preset("lst")
    rig = StereoRig(width=320, height=96)
    pose = CombinationPose(-10.0, 0.5, 0.3, 0.6)
    drawn = _renderer(world, rig, params)
    pair = drawn.render(pose, frame=0)
    chain = drawn.render(ChainPose(*pose[:3], (pose.gamma,)), frame=0)
    bare = _renderer(world, rig, params, bodies=False).render(pose, frame=0)
    np.testing.assert_array_equal(pair.left, bare.left)
    np.testing.assert_array_equal(pair.right, bare.right)
    np.testing.assert_array_equal(chain.left, pair.left)
    nodes = drawn._scene.offtrack_bodies[id(params)].nodes
    drawn.render_view(pose)
    assert nodes[0].mesh.is_visible and not nodes[1].mesh.is_visible  # the tractor drawn, the rig's own unit not
    # and the masks have nothing to exclude
    cams = (rig.camera_in_world(params, pose, "left"), rig.camera_in_world(params, pose, "right"))
    assert exclusion_masks(params, pose, cams, rig.intrinsics(), (320, 96), skip_unit=1) is None


def _motions(world, params, rig, poses, *, bodies: bool, masked: bool) -> np.ndarray:
    """Translation error [m] of each frame-to-frame motion against the truth (NaN where the odometry failed)."""
    renderer = _renderer(world, rig, params, bodies=bodies)
    config = VOConfig.from_horizontal_fov(rig.width, rig.height, rig.hfov, rig.baseline, quality_min_inliers=15)
    vo = StereoOdometry(config, seed=0)
    errors = []
    for k, pose in enumerate(poses):
        pair = renderer.render(pose, frame=k)
        cams = (rig.camera_in_world(params, pose, "left"), rig.camera_in_world(params, pose, "right"))
        masks = exclusion_masks(params, pose, cams, rig.intrinsics(), (rig.width, rig.height), skip_unit=rig.unit)
        result = vo.process(pair.left, pair.right, masks if masked else None)
        if k == 0:
            continue
        truth = invert_rigid(rig.camera_in_world(params, poses[k - 1], "left")) @ cams[0]
        motion = result.camera_motion
        errors.append(np.nan if motion is None else float(np.linalg.norm(motion[:3, 3] - truth[:3, 3])))
    return np.asarray(errors)


def _turn(frames: int) -> list[ChainPose]:
    """Frames 0.3 m apart on a left circle, every coupling's articulation growing (the units move in the view)."""
    out = []
    for k in range(frames):
        heading = -0.6 + 0.01 * k
        x, y = RADIUS * np.sin(heading), RADIUS - RADIUS * np.cos(heading)
        out.append(ChainPose(x, y, heading, (0.15 + 0.004 * k, 0.1 + 0.004 * k, 0.1 + 0.004 * k)))
    return out


def _check_mask_matters(world, params, frames: int) -> None:
    rig = StereoRig(width=672, height=196, unit=1)  # the lead trailer's rear camera, 3 m up
    poses = _turn(frames)
    step = float(np.linalg.norm(np.diff([p[:2] for p in poses], axis=0), axis=1).mean())
    unseen = _motions(world, params, rig, poses, bodies=False, masked=False)
    masked = _motions(world, params, rig, poses, bodies=True, masked=True)
    unmasked = _motions(world, params, rig, poses, bodies=True, masked=False)
    assert np.isfinite(unseen).all() and np.isfinite(masked).all()
    rms = {name: float(np.sqrt(np.mean(e**2))) for name, e in (("unseen", unseen), ("masked", masked))}
    # masked: within 0.03 m per frame (a tenth of the 0.3 m step) of the run without that trailer drawn
    assert rms["masked"] <= rms["unseen"] + 0.03, rms
    # unmasked: the wall that moves with the camera leads the odometry — more than half the step wrong
    assert np.nanmin(unmasked) > 0.5 * step, (unmasked, step)


@rendering
def test_the_mask_keeps_the_odometry_off_the_trailer_behind(world, a_double) -> None:
    """Four motions (tolerances in :func:`_check_mask_matters`)."""
    _check_mask_matters(world, a_double, 5)


@rendering
@pytest.mark.slow
def test_the_mask_keeps_the_odometry_off_the_trailer_behind_long(world, a_double) -> None:
    _check_mask_matters(world, a_double, 16)


def _yaw_ratio(world, params, rig: StereoRig, yaw: float, poses: list[ChainPose], **overrides: object) -> np.ndarray:
    """The odometry's yaw over the true yaw for a pure yaw ``yaw`` [rad] of the rig about its left camera, at each
    pose (two frames each, nothing else moving); ``overrides``: other :class:`VOConfig` fields."""
    renderer = _renderer(world, rig, params, bodies=False)
    c, s = np.cos(yaw), np.sin(yaw)
    turn = np.eye(4)
    turn[:3, :3] = [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]  # about the camera's y axis (image down)
    ratios = []
    for pose in poses:
        left, right = rig.camera_in_world(params, pose, "left"), rig.camera_in_world(params, pose, "right")
        config = VOConfig.from_horizontal_fov(
            rig.width, rig.height, rig.hfov, rig.baseline, **{"refinement": 2, **overrides}
        )
        vo = StereoOdometry(config, seed=0)
        before = renderer.render_poses(left, right, frame=0)
        vo.process(before.left, before.right)
        moved = left @ turn
        after = renderer.render_poses(moved, moved @ invert_rigid(left) @ right, frame=1)
        motion = vo.process(after.left, after.right).camera_motion
        assert motion is not None
        ratios.append(np.arctan2(motion[0, 2], motion[2, 2]) / yaw)
    return np.asarray(ratios)


@rendering
@pytest.mark.parametrize(
    "samples",
    [
        pytest.param(
            1,
            marks=pytest.mark.xfail(
                strict=True,
                reason="open: aliased silhouettes lose small motions at the image edges, and the descriptor "
                "refinement's sub-pixel fit pulls the matches towards whole pixels (docs/camera.md, a long lead "
                "trailer's side camera); the gradient refinement takes the second, not the first",
            ),
        ),
        pytest.param(
            4,
            marks=pytest.mark.xfail(
                strict=True,
                reason="open by default: with 4 × 4 samples a pixel the images keep the motion, but the descriptor "
                "refinement's sub-pixel fit pulls the matches towards whole pixels; the opt-in gradient refinement "
                "measures it in full (the test below; docs/camera.md)",
            ),
        ),
    ],
)
def test_a_side_rigs_pure_yaw_is_measured_in_full(world, a_double, samples) -> None:
    """The au-a-double lead trailer's side rig at its default station, 400×200 px, a pure yaw of 7.5 mrad (about
    1.3 px at the image centre) at six poses: the odometry's mean yaw within 3 % of the truth, with one sample a
    pixel and with 4 × 4 (``supersample``, which removes the rendering's share of the shortfall). A yaw it
    under-measures leaks, through the 8 m lever arm to the kingpin and the 12.3 m follow point, into a biased
    off-tracking."""
    rig = StereoRig.from_degrees(
        width=400, height=200, unit=1, psi_c2v_deg=270.0, station=-7.975, lateral=1.25, supersample=samples
    )
    ratios = _yaw_ratio(world, a_double, rig, 0.0075, _turn(12)[::2])
    assert abs(float(np.mean(ratios)) - 1.0) <= 0.03, ratios


@rendering
def test_the_gradient_refinement_measures_the_side_rigs_pure_yaw_in_full(world, a_double) -> None:
    """The supersampled case of :func:`test_a_side_rigs_pure_yaw_is_measured_in_full` (4 × 4 samples a pixel, the
    same rig, yaw and six poses) with ``gradient_refinement="lucas_kanade"``: the mean yaw within 3 % of the truth.
    Its refinement's pull towards the pixel grid, not the images, kept the rest of the yaw (docs/camera.md)."""
    rig = StereoRig.from_degrees(
        width=400, height=200, unit=1, psi_c2v_deg=270.0, station=-7.975, lateral=1.25, supersample=4
    )
    ratios = _yaw_ratio(world, a_double, rig, 0.0075, _turn(12)[::2], gradient_refinement="lucas_kanade")
    assert abs(float(np.mean(ratios)) - 1.0) <= 0.03, ratios


@rendering
def test_the_rendered_edges_lose_part_of_a_small_yaw(world, a_double) -> None:
    """What docs/camera.md says of the side rig's images: for a pure yaw moving the image centre 1 px (400×200 px),
    an optical flow independent of the odometry (OpenCV's Farnebäck) finds the textured content of the outer fifth
    of the image, near the horizon, moving under 0.88 of the exact homography's motion (0.81–0.83 at the test's six
    poses), while on the first frame warped by that homography it finds over 0.95 (0.975–0.98): the rendering, not
    the flow, loses the motion. Rendered with 4 × 4 samples a pixel (``supersample=4``) the images keep it: over 0.93
    (0.94–0.96 at the six poses)."""
    import cv2

    rig = StereoRig.from_degrees(width=400, height=200, unit=1, psi_c2v_deg=270.0, station=-7.975, lateral=1.25)
    f = rig.focal_length
    yaw = 1.0 / f
    c, s = np.cos(yaw), np.sin(yaw)
    turn = np.eye(4)
    turn[:3, :3] = [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
    pose = _turn(12)[0]
    left, right = rig.camera_in_world(a_double, pose, "left"), rig.camera_in_world(a_double, pose, "right")

    def frames(samples: int) -> tuple[np.ndarray, np.ndarray]:
        renderer = _renderer(world, rig.replace(supersample=samples), a_double, bodies=False)
        before = renderer.render_poses(left, right, frame=0).left
        after = renderer.render_poses(left @ turn, left @ turn @ invert_rigid(left) @ right, frame=1).left
        return before, after

    before, after = frames(1)
    k = rig.intrinsics()
    homography = k @ turn[:3, :3] @ np.linalg.inv(k)  # a current pixel → where it was in the previous frame
    warped = cv2.warpPerspective(
        before, homography, (400, 200), flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REFLECT
    )
    uu, vv = np.meshgrid(np.arange(400), np.arange(200))
    moved = np.stack([uu, vv, np.ones_like(uu)], axis=-1) @ homography.T
    true_du = moved[..., 0] / moved[..., 2] - uu
    textured = np.hypot(*np.gradient(after.astype(float))) > 4
    edges = (np.abs(uu - k[0, 2]) > 0.8 * f) & (vv > 60) & (vv < 115) & textured & (uu > 15) & (uu < 385)

    def share(image: np.ndarray, first: np.ndarray) -> float:
        flow = cv2.calcOpticalFlowFarneback(image, first, None, 0.5, 3, 15, 5, 7, 1.5, 0)
        return float(flow[..., 0][edges].sum() / true_du[edges].sum())

    assert edges.sum() > 500
    assert share(after, before) < 0.88
    assert share(warped, before) > 0.95
    assert share(*frames(4)[::-1]) > 0.93


def test_a_mask_drops_only_the_features_inside_it() -> None:
    """``mask_features``: None and an empty mask give the same feature sets (the same objects); a half mask drops
    exactly the features in that half, the sparse set staying a subset of the dense one."""
    from sensor.vo.features import extract_features

    rng = np.random.default_rng(0)
    image = (rng.random((96, 160)) * 255).astype(np.uint8)
    config = VOConfig.from_horizontal_fov(160, 96, 1.7, 0.5)
    features = extract_features(image, config)
    assert mask_features(features, None) is features
    empty = mask_features(features, np.zeros((96, 160), bool))
    assert empty.dense is features.dense and empty.sparse is features.sparse
    half = np.zeros((96, 160), bool)
    half[:, :80] = True
    kept = mask_features(features, half)
    assert (kept.dense.u >= 80).all() and len(kept.dense) == int((features.dense.u >= 80).sum())
    assert set(zip(kept.sparse.u, kept.sparse.v, strict=True)) <= set(zip(kept.dense.u, kept.dense.v, strict=True))
    with pytest.raises(ValueError, match="mask shape"):
        mask_features(features, np.zeros((10, 10), bool))


@rendering
def test_two_rigs_share_the_context_and_the_scene(world, b_double) -> None:
    """A side rig on the lead trailer and a rear rig on the rear trailer render in turn from the one context and the
    one scene of the world; each renders the same pair whether or not the other rendered in between."""
    from sensor.gl_context import GLContext

    side = _renderer(
        world, StereoRig.from_degrees(width=320, height=96, unit=1, psi_c2v_deg=270.0, lateral=1.25), b_double
    )
    rear = _renderer(world, StereoRig(width=320, height=96, unit=2), b_double)
    pose = ChainPose(-6.0, 0.0, 0.2, (0.3, 0.35))
    first = side.render(pose, frame=0)
    other = rear.render(pose, frame=0)
    again = side.render(pose, frame=0)
    assert side._scene is rear._scene
    assert GLContext._instance is not None
    np.testing.assert_array_equal(first.left, again.left)
    assert not np.array_equal(first.left, other.left)


def test_frame_cache_key_holds_every_units_pose() -> None:
    from scenarios.camera.frame_cache import _key

    one = CombinationPose(1.0, 2.0, 0.3, 0.1)
    np.testing.assert_array_equal(_key(one, None), _key(ChainPose(1.0, 2.0, 0.3, (0.1,)), None))
    a, b = _key(ChainPose(1.0, 2.0, 0.3, (0.1, 0.2)), None), _key(ChainPose(1.0, 2.0, 0.3, (0.1, 0.25)), None)
    assert not np.array_equal(a, b, equal_nan=True)


def test_a_feed_of_a_rig_the_configuration_lacks_is_refused() -> None:
    from types import SimpleNamespace

    from scenarios.camera.delivery import CameraFeed
    from scenarios.config import load_scenario
    from vehicle_model.errors import InputError

    setup = SimpleNamespace(config=load_scenario("roundabout-3"))  # a tractor–semi-trailer: one rig
    with pytest.raises(InputError, match=r"rig_index = 1: the run has 1 camera rig\(s\), 0 to 0"):
        CameraFeed(setup, rig_index=1)  # type: ignore[arg-type]
