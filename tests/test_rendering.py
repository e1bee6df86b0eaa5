"""Procedural world, offscreen stereo rendering and the KITTI export.

Tests that render are marked ``rendering`` (headless OpenGL through EGL). Tolerances:

* depth of flat road: relative error ≤ 1e-4 (24-bit depth buffer; measured ~2e-5);
* marker centroid within 0.1 px of its pinhole projection, disparity within 0.1 px of f·B/Z
  (measured < 0.01 px);
* right-camera misalignment vs the homography K·R·K⁻¹ (de Saxe & Cebon 2018, eq (8)): median corner error
  ≤ 0.2 px and 90 % within 0.5 px (LK-tracked), normalised correlation ≥ 0.99.
"""

from __future__ import annotations

import itertools
import math
import os
import pickle
import subprocess
import sys
import textwrap

import cv2
import numpy as np
import pytest

from scenarios.setup.paths import roundabout_path
from sensor.camera import StereoRig, project
from sensor.world import RoadPath, World, WorldConfig, build_world
from vehicle_model.errors import InputError, OfftrackError
from vehicle_model.geometry import CombinationPose

rendering = pytest.mark.rendering


# ------------------------------------------------------------------------------------------------
# Fixtures


@pytest.fixture(scope="module")
def roundabout():
    """The roundabout-3 reference path (50 m radius, three turns)."""
    return roundabout_path(50.0, 3.0, 1, 30.0, 30.0)


@pytest.fixture(scope="module")
def default_world(roundabout) -> World:
    return build_world(roundabout)


@pytest.fixture(scope="module")
def flat_world() -> World:
    """A straight road with nothing but road and ground (scenery density 0)."""
    return build_world(RoadPath.straight(400.0, start=(-200.0, 0.0)), scenery_density=0.0, seed=1)


def _ring_state(path, s: float) -> CombinationPose:
    i = int(np.searchsorted(path.s, s))
    return CombinationPose(float(path.x[i]), float(path.y[i]), float(path.heading[i]), 0.05)


# ------------------------------------------------------------------------------------------------
# World (no rendering)


def test_world_is_reproducible_and_density_selects_a_subset(roundabout, default_world: World) -> None:
    # Seeds 0 and 1 are those of the module's worlds: a process builds a seed's textures once (cached), so the
    # worlds here cost their layout only.
    a = default_world  # seed 0
    b = build_world(roundabout, seed=0)
    assert [p.name for p in a.parts] == [p.name for p in b.parts]
    for pa, pb in zip(a.parts, b.parts, strict=True):
        np.testing.assert_array_equal(pa.positions, pb.positions)
        np.testing.assert_array_equal(pa.texcoords, pb.texcoords)
        if pa.poses is not None:
            np.testing.assert_array_equal(pa.poses, pb.poses)
    c = build_world(roundabout, seed=1)
    assert any(
        pa.poses is not None and (pa.poses.shape != pc.poses.shape or not np.allclose(pa.poses, pc.poses))
        for pa, pc in zip(a.parts, c.parts, strict=False)
        if pc.poses is not None and pa.name == pc.name
    )
    half = build_world(roundabout, seed=0, scenery_density=0.5)
    none = build_world(roundabout, seed=0, scenery_density=0.0)
    full_n = sum(a.object_counts.values())
    half_n = sum(half.object_counts.values())
    assert 0.4 * full_n <= half_n <= 0.6 * full_n + 2
    assert sum(v for k, v in none.object_counts.items()) == 0
    assert {p.category for p in none.parts} <= {"road", "roundabout", "ground"}
    # Density 0.5 keeps a subset of the objects of density 1.0 (the paper's §3.2.3: objects removed).
    full_trees = {tuple(np.round(p[:3, 3], 6)) for part in a.parts if part.name == "tree_0" for p in part.poses}
    half_trees = {tuple(np.round(p[:3, 3], 6)) for part in half.parts if part.name == "tree_0" for p in part.poses}
    assert half_trees and half_trees < full_trees


def test_roundabout_geometry(roundabout, default_world: World) -> None:
    (loop,) = default_world.loops
    assert loop.centre == pytest.approx((0.0, 50.0))
    assert loop.radius == pytest.approx(50.0, abs=1e-6)
    assert loop.inner_edge == pytest.approx(50.0 - 3.5, abs=0.05)
    assert loop.island_radius == pytest.approx(loop.inner_edge - 3.0)
    names = {p.name for p in default_world.parts}
    assert {"road", "road_lines", "road_dashes", "truck_apron", "kerbs", "islands"} <= names
    # Three turns lay the circulatory carriageway once: no more road than a one-turn roundabout.
    one = build_world(roundabout_path(50.0, 1.0, 1, 30.0, 30.0))
    road = [next(p for p in w.parts if p.name == "road").triangles for w in (default_world, one)]
    assert abs(road[0] - road[1]) <= 10, road  # (the straights' sampling may differ by a sample)
    # Every instanced object keeps clear of the carriageway.
    for part in default_world.parts:
        if part.poses is None or part.category != "scenery":
            continue
        xy = part.poses[:, :2, 3]
        r = np.hypot(xy[:, 0] - loop.centre[0], xy[:, 1] - loop.centre[1])
        assert np.all((r > loop.outer_edge) | (r < loop.island_radius)), part.name


def test_world_config_validation(flat_world: World) -> None:
    with pytest.raises(InputError, match="scenery_density"):
        WorldConfig(scenery_density=1.5)
    with pytest.raises(InputError, match="road_width"):
        build_world(flat_world.road, road_width=0.5)
    with pytest.raises(InputError, match="unknown world setting"):
        build_world(flat_world.road, lanes=3)
    assert 0 < flat_world.triangle_count < 40000


# ------------------------------------------------------------------------------------------------
# Rendering


def test_rendering_unavailable_names_the_fix() -> None:
    """Runs first among the rendering tests, in a fresh interpreter (fork + exec, before this process
    holds a GL context)."""
    script = textwrap.dedent(
        """
        import numpy as np
        from sensor.camera import StereoRig
        from sensor.renderer import StereoRenderer
        from sensor.rendering_errors import RenderingUnavailableError
        from sensor.world import RoadPath, build_world
        from vehicle_model.errors import OfftrackError
        world = build_world(RoadPath.straight(50.0), scenery_density=0.0)
        try:
            StereoRenderer(world, StereoRig(station=-12.0)).render_poses(np.eye(4), np.eye(4))
        except RenderingUnavailableError as exc:
            assert isinstance(exc, OfftrackError)
            print("MESSAGE:", exc)
        """
    )
    env = {**os.environ, "PYOPENGL_PLATFORM": "no-such-platform"}
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=120)
    assert "MESSAGE:" in out.stdout, out.stderr
    assert "apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri" in out.stdout
    assert "PYOPENGL_PLATFORM=egl" in out.stdout


@rendering
def test_flat_road_depth_equals_ray_plane_depth(flat_world: World) -> None:
    from sensor.renderer import StereoRenderer

    rig = StereoRig(station=-12.0)
    pose = rig.camera_in_trailer("left")  # trailer at the world origin, heading +X
    renderer = StereoRenderer(flat_world, rig)
    grey, depth = renderer.render_view(pose, depth=True)
    assert grey.shape == depth.shape == (rig.height, rig.width) and grey.dtype == np.uint8
    k = rig.intrinsics()
    v, u = np.mgrid[0 : rig.height, 0 : rig.width]
    rays = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones(u.shape)], axis=-1) @ pose[:3, :3].T
    down = rays[..., 2] < -1e-6
    z = np.where(down, -pose[2, 3] / np.where(down, rays[..., 2], -1.0), 1e9)  # depth along the optical axis
    hit = pose[:3, 3] + z[..., None] * rays
    # Pixels whose ray meets the road (Z = 0) clear of its paint, within 150 m.
    on_road = down & (np.abs(hit[..., 1]) < 2.8) & (np.abs(hit[..., 1]) > 0.3) & (z < 150.0)
    assert on_road.sum() > 20000
    rel = np.abs(depth[on_road] - z[on_road]) / z[on_road]
    assert rel.max() < 1e-4, rel.max()
    assert np.all(depth[: int(k[1, 2]) - 40] == 0.0)  # sky above the horizon (nothing but the far band)


@rendering
@pytest.mark.parametrize(("baseline", "distance"), [(0.5, 10.0), (0.5, 20.0), (0.5, 40.0), (2.5, 30.0)])
def test_marker_disparity_is_f_b_over_z(flat_world: World, baseline: float, distance: float) -> None:
    from sensor.renderer import StereoRenderer

    rig = StereoRig(station=-12.0, baseline=baseline)
    tl, tr = rig.camera_in_trailer("left"), rig.camera_in_trailer("right")
    r = tl[:3, :3]
    mid = 0.5 * (tl[:3, 3] + tr[:3, 3])
    centre = mid + distance * r[:, 2] + 0.05 * distance * r[:, 0] - 0.02 * distance * r[:, 1]
    size = 0.1 * distance  # 56 px wide at any distance; a white disc of radius 0.3·size on black
    world = flat_world.with_marker(centre, -r[:, 2], size)
    pair = StereoRenderer(world, rig).render_poses(tl, tr)
    k = rig.intrinsics()

    def centroid(img: np.ndarray, guess: np.ndarray, half: int = 24) -> np.ndarray:
        u0, v0 = (round(g) for g in guess)
        win = img[v0 - half : v0 + half + 1, u0 - half : u0 + half + 1].astype(float)
        w = np.clip((win - 40.0) / 180.0, 0.0, 1.0)
        vv, uu = np.mgrid[-half : half + 1, -half : half + 1]
        return np.array([u0 + (w * uu).sum() / w.sum(), v0 + (w * vv).sum() / w.sum()])

    expected_l = project(k, np.linalg.inv(tl), centre[None])[0]
    expected_r = project(k, np.linalg.inv(tr), centre[None])[0]
    cl, cr = centroid(pair.left, expected_l), centroid(pair.right, expected_r)
    np.testing.assert_allclose(cl, expected_l, atol=0.1)
    np.testing.assert_allclose(cr, expected_r, atol=0.1)
    assert cl[0] - cr[0] == pytest.approx(k[0, 0] * baseline / distance, abs=0.1)
    assert cl[1] == pytest.approx(cr[1], abs=0.1)  # rectified: same row


@rendering
def test_same_seed_same_images_other_seed_different(roundabout) -> None:
    from sensor.renderer import StereoRenderer
    from vehicle_model.presets import vehicle_preset

    params = vehicle_preset("reference")
    state = _ring_state(roundabout, 140.0)
    rig = StereoRig(noise_std=2.0, exposure_std=0.03)
    images, renderers = [], []
    for seed in (0, 0, 1):  # the module's seeds (their textures are built once in a process)
        world = build_world(roundabout, seed=seed, scenery_density=0.5)
        renderers.append(StereoRenderer(world, rig, params))
        images.append(renderers[-1].render(state, frame=5))
    np.testing.assert_array_equal(images[0].left, images[1].left)
    np.testing.assert_array_equal(images[0].right, images[1].right)
    assert np.abs(images[0].left.astype(int) - images[2].left.astype(int)).mean() > 5.0
    # Noise and exposure depend on the frame index, not on the call order: the second renderer, after frame 6,
    # renders frame 5 as the first one did first.
    again = renderers[1]
    other = again.render(state, frame=6)
    np.testing.assert_array_equal(again.render(state, frame=5).left, images[0].left)
    diff = other.left.astype(float) - images[0].left.astype(float)
    assert 1.5 < np.std(diff[(images[0].left > 20) & (images[0].left < 230)]) < 8.0


@rendering
def test_right_camera_misalignment_is_the_homography(default_world: World, roundabout) -> None:
    """The paper's eq (8): a pure rotation of the right camera maps its image by K·R·K⁻¹ at every depth."""
    from sensor.renderer import StereoRenderer
    from vehicle_model.presets import vehicle_preset

    params = vehicle_preset("reference")
    state = _ring_state(roundabout, 150.0)
    ideal = StereoRig()
    rotated = StereoRig.from_degrees(roll_deg=1.0, pitch_deg=0.6, yaw_deg=-0.8)
    a = StereoRenderer(default_world, ideal, params, antialias=True).render(state).right
    b = StereoRenderer(default_world, rotated, params, antialias=True).render(state).right
    h = rotated.misalignment_homography()
    corners = cv2.goodFeaturesToTrack(a, 500, 0.01, 8)
    predicted = cv2.perspectiveTransform(corners, h)
    tracked, status, _ = cv2.calcOpticalFlowPyrLK(
        a,
        b,
        corners,
        predicted.copy(),
        winSize=(31, 31),
        maxLevel=2,
        flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
        criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 0.001),
    )
    p = predicted[:, 0]
    inside = (p[:, 0] > 20) & (p[:, 0] < ideal.width - 20) & (p[:, 1] > 20) & (p[:, 1] < ideal.height - 20)
    err = np.linalg.norm(tracked[:, 0] - p, axis=1)[(status[:, 0] == 1) & inside]
    assert len(err) > 200
    assert np.median(np.linalg.norm(p - corners[:, 0], axis=1)) > 5.0  # the rotation moves points a lot
    assert np.median(err) < 0.2 and np.percentile(err, 90) < 0.5, (np.median(err), np.percentile(err, 90))
    warped = cv2.warpPerspective(a, h, (ideal.width, ideal.height), flags=cv2.INTER_LINEAR)
    valid = cv2.warpPerspective(np.full_like(a, 255), h, (ideal.width, ideal.height), flags=cv2.INTER_NEAREST)
    valid = cv2.erode(valid, np.ones((5, 5), np.uint8)) == 255
    assert np.corrcoef(warped[valid].astype(float), b[valid].astype(float))[0, 1] > 0.99


@rendering
@pytest.mark.parametrize("density", [1.0, 0.5, 0.0])
def test_images_have_hundreds_of_features(roundabout, default_world: World, density: float) -> None:
    from sensor.renderer import StereoRenderer
    from vehicle_model.presets import vehicle_preset

    params = vehicle_preset("reference")
    world = default_world if density == 1.0 else build_world(roundabout, scenery_density=density)
    renderer = StereoRenderer(world, StereoRig(), params)
    for s in (20.0, 150.0):
        pair = renderer.render(_ring_state(roundabout, s))
        for img in (pair.left, pair.right):
            corners = cv2.goodFeaturesToTrack(img, 3000, 0.01, 5)
            assert corners is not None and len(corners) >= 300, (density, s, 0 if corners is None else len(corners))
            assert len(cv2.FastFeatureDetector_create(20).detect(img)) >= 300


@rendering
def test_side_camera_sees_the_central_island(default_world: World, roundabout) -> None:
    """ψ_c2v = 270° looks left: in a left turn that is towards the island (close, so large disparity)."""
    from sensor.renderer import StereoRenderer
    from vehicle_model.presets import vehicle_preset

    params = vehicle_preset("reference")
    rig = StereoRig.from_degrees(psi_c2v_deg=270.0)
    renderer = StereoRenderer(default_world, rig, params)
    pair = renderer.render(_ring_state(roundabout, 150.0), depth=True)
    centre_col = pair.depth_left[rig.height // 2 + 20 :, rig.width // 2 - 50 : rig.width // 2 + 50]
    assert 5.0 < np.median(centre_col[centre_col > 0]) < 60.0
    # One camera at the combination pose is the pair's (no noise, flat lighting), the right one too.
    np.testing.assert_array_equal(renderer.render_view(_ring_state(roundabout, 150.0))[0], pair.left)
    np.testing.assert_array_equal(renderer.render_view(_ring_state(roundabout, 150.0), which="right")[0], pair.right)


@rendering
def test_renderer_pickles_and_refuses_a_fork(flat_world: World, monkeypatch) -> None:
    from sensor import gl_context
    from sensor import renderer as rmod
    from sensor.rendering_errors import RenderingUnavailableError

    rig = StereoRig(station=-12.0)
    r = rmod.StereoRenderer(flat_world, rig)
    pose_l, pose_r = rig.camera_in_trailer("left"), rig.camera_in_trailer("right")
    first = r.render_poses(pose_l, pose_r)
    blob = pickle.dumps(r)
    assert len(blob) < 64e6
    clone = pickle.loads(blob)
    assert clone._scene is None  # no OpenGL state travels
    again = clone.render_poses(pose_l, pose_r)
    np.testing.assert_array_equal(first.left, again.left)
    np.testing.assert_array_equal(first.right, r.render_poses(pose_l, pose_r).right)
    # A context created in another process (a fork) is refused, not used.
    monkeypatch.setattr(gl_context.os, "getpid", lambda: -1)
    with pytest.raises(RenderingUnavailableError, match="fork"):
        r.render_poses(pose_l, pose_r)


@rendering
def test_kitti_export_loads_back(tmp_path) -> None:
    from scenarios.config import load_scenario
    from scenarios.export.kitti import export_kitti, read_calib, read_poses

    config = load_scenario("constant-slip", {"duration_s": 0.6})
    calls = []
    result = export_kitti(
        config, tmp_path / "kitti", max_frames=5, progress=lambda d, n: calls.append((d, n)), scenery_density=0.5
    )
    out = tmp_path / "kitti"
    assert result["frames"] == 5 and calls[-1] == (5, 5) and result["status"] == "completed"
    rig = StereoRig()
    for cam in ("image_0", "image_1"):
        files = sorted((out / cam).glob("*.png"))
        assert [f.name for f in files] == [f"{k:06d}.png" for k in range(5)]
        img = cv2.imread(str(files[0]), cv2.IMREAD_UNCHANGED)
        assert img.shape == (rig.height, rig.width) and img.dtype == np.uint8
    calib = read_calib(out / "calib.txt")
    f = rig.focal_length
    np.testing.assert_allclose(calib["P0"][:, :3], rig.intrinsics(), atol=1e-9)
    assert calib["P1"][0, 3] == pytest.approx(-f * rig.baseline)
    np.testing.assert_allclose(calib["Tr"], np.eye(4)[:3])
    poses = read_poses(out / "poses.txt")
    assert poses.shape == (5, 4, 4)
    np.testing.assert_allclose(poses[0], np.eye(4), atol=1e-9)
    # The paper's §3: crabbing at 14° at 5 m/s, 10 Hz: 0.5 m per frame, 14° to the trailer's left. The
    # rear-facing camera's z is the trailer's −x and its x the trailer's +y.
    step = 5.0 / config.rates.camera_hz
    beta = math.radians(14.0)
    for a, b in itertools.pairwise(poses):
        np.testing.assert_allclose(b[:3, 3] - a[:3, 3], [step * math.sin(beta), 0.0, -step * math.cos(beta)], atol=1e-6)
        np.testing.assert_allclose(b[:3, :3], np.eye(3), atol=1e-9)
    times = np.loadtxt(out / "times.txt")
    np.testing.assert_allclose(times, np.arange(5) / config.rates.camera_hz, atol=1e-9)
    with pytest.raises(InputError, match="already holds"):
        export_kitti(config, out, max_frames=1)


def test_write_video(tmp_path) -> None:
    import imageio.v2 as imageio

    from scenarios.export.video import write_video

    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 255, (391, 300), dtype=np.uint8) for _ in range(4)]
    n = write_video(tmp_path / "v.mp4", frames, frames[::-1], fps=10.0)
    assert n == 4
    reader = imageio.get_reader(tmp_path / "v.mp4")
    first = reader.get_data(0)
    assert first.shape[:2] == (392, 604)  # side by side with a 4 px gap, padded to even size
    assert reader.count_frames() == 4
    reader.close()
    with pytest.raises(OfftrackError):
        write_video(tmp_path / "w.mp4", [frames[0]], [frames[0][:, :10]], fps=10.0)


@rendering
def test_bench_render_reports() -> None:
    from scenarios.bench.render import bench_render

    result = bench_render(duration_frames=3)
    for key in ("pairs_per_s", "ms_per_pair", "width", "height", "triangles", "ms_draw", "ms_readback", "ms_grey"):
        assert key in result
    assert (result["width"], result["height"]) == (1344, 391)
    assert result["pairs_per_s"] > 0 and result["triangles"] > 10000


def test_rig_from_scenario_camera_section() -> None:
    from scenarios.camera.build import rig_from_config
    from scenarios.config import load_scenario

    assert rig_from_config(load_scenario("roundabout-3")) == StereoRig()
    overrides = {
        "camera.psi_c2v_deg": 270.0,
        "camera.baseline": 2.5,
        "camera.right_misalignment_deg": [-0.15, 0.0, 0.1],
    }
    rig = rig_from_config(load_scenario("roundabout-3", overrides))
    assert rig.psi_c2v == pytest.approx(1.5 * math.pi) and rig.baseline == 2.5
    assert (rig.misalignment.roll, rig.misalignment.yaw) == pytest.approx((math.radians(-0.15), math.radians(0.1)))
