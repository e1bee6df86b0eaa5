"""One camera of a run (:func:`scenarios.camera.build.stereo_camera`): assembled in one place, ideal on request,
with a frame cache; the animation draws the run's own camera and the KITTI export renders the run's lighting.

Rendering is slow on llvmpipe: every rendering test here uses a small camera (336 × 98 or 672 × 196) and a
few frames.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from field_camera_run import FIELD, field_camera_run

from scenarios.camera.build import stereo_camera
from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from vehicle_model.errors import InputError
from vehicle_model.geometry import CombinationPose

REPO = Path(__file__).resolve().parents[1]
TINY = {"camera.width": 336, "camera.height": 98}


def test_stereo_renderer_is_built_in_one_source_module() -> None:
    built = re.compile(r"^[^\"'#]*\bStereoRenderer\(", re.MULTILINE)  # a call in code, not in a message
    modules = [
        path.relative_to(REPO).as_posix()
        for top in ("scenarios", "sensor", "benchmarks", "controller", "vehicle_model")
        for path in (REPO / top).rglob("*.py")
        if built.search(path.read_text(encoding="utf-8"))
    ]
    assert modules == ["sensor/stereo_camera.py"]


def test_ideal_switch_drops_lens_flex_lighting_and_correction() -> None:
    config = load_scenario(
        "constant-slip",
        {**TINY, **FIELD, "duration_s": 0.3, "camera.right_correction_deg": [0.0, 0.1, 0.0]},
    )
    setup = build_scenario(config)
    run = stereo_camera(setup)
    assert run.developer.lighting is not None and run.optics.distortion is not None
    assert run.developer.correction is not None and run.develops_in_order
    ideal = stereo_camera(setup, ideal=True, world=run.world)
    assert ideal.developer.lighting is None and ideal.optics.distortion is None and ideal.optics.calibration is None
    assert ideal.developer.correction is None and not ideal.develops_in_order
    assert ideal.rig == run.rig and ideal.developer.seed == run.developer.seed == config.seed
    lit = stereo_camera(setup, ideal=True, world=run.world, lighting=run.developer.lighting)
    assert lit.developer.lighting == run.developer.lighting and lit.optics.distortion is None
    with pytest.raises(InputError, match="ideal=True"):
        stereo_camera(setup, rig=run.rig, world=run.world)


def test_the_configurations_antialias_reaches_the_renderer_and_is_the_runs() -> None:
    """``camera.antialias`` is the renderer's multisampling unless a caller says otherwise; a rig cannot set it (one
    GL context renders every rig of a run)."""
    from scenarios.config import ConfigError

    plain = build_scenario(load_scenario("constant-slip", {**TINY, "duration_s": 0.3}))
    smooth = build_scenario(load_scenario("constant-slip", {**TINY, "duration_s": 0.3, "camera.antialias": True}))
    world = stereo_camera(plain).world
    assert not stereo_camera(plain, world=world).renderer.antialias
    assert stereo_camera(smooth, world=world).renderer.antialias
    assert not stereo_camera(smooth, world=world, antialias=False).renderer.antialias
    with pytest.raises(ConfigError, match="antialias"):
        load_scenario("constant-slip", {"camera.rigs": [{"unit": 1, "antialias": True}]})


@pytest.mark.rendering
def test_frame_cache_gives_back_the_frames_and_the_exposure(tmp_path: Path) -> None:
    config = load_scenario("constant-slip", {**TINY, "camera.lighting.sun": True, "duration_s": 0.3})
    setup = build_scenario(config)
    poses = [CombinationPose(x, 0.0, 0.0, 0.0) for x in (0.0, 0.5, 1.0)]
    first = stereo_camera(setup, frame_cache=tmp_path)
    assert first.develops_in_order  # the auto-exposure: a stored frame must still move the gain
    rendered, gains = [], []
    for k, pose in enumerate(poses):
        rendered.append(first.pair(pose, k))
        gains.append(first.developer.last_gain)
    assert gains[0] != gains[2]  # the exposure moved over the frames
    store = first.frame_store
    assert store is not None and store.saved == 3 and len(store) == 3

    again = stereo_camera(setup, frame_cache=tmp_path, world=first.world)
    for k, pose in enumerate(poses[:2]):
        left, right = again.pair(pose, k)
        assert np.array_equal(left, rendered[k][0]) and np.array_equal(right, rendered[k][1])
        assert again.developer.last_gain == gains[k]  # the stored frames moved the exposure as rendered ones did
    assert again.frame_store is not None and again.frame_store.loaded == 2 and again.frame_store.saved == 0
    moved = CombinationPose(1.2, 0.0, 0.0, 0.0)  # another pose for frame 2: rendered, not taken from the cache
    left, _ = again.pair(moved, 2)
    assert again.frame_store.loaded == 2 and again.frame_store.saved == 1
    assert not np.array_equal(left, rendered[2][0])
    other = stereo_camera(setup, ideal=True, frame_cache=tmp_path, world=first.world)  # another camera, another tag
    assert other.frame_store is not None and other.frame_store.load(0, poses[0], None) is None


@pytest.mark.rendering
def test_kitti_export_renders_the_runs_lighting_as_the_runs_camera(tmp_path: Path) -> None:
    from scenarios.export.kitti import export_kitti
    from scenarios.loop.trailer_steer import UnsteeredTrailer, trailer_axles
    from scenarios.run.drive import simulate

    flat = load_scenario("constant-slip", {**TINY, "duration_s": 0.3})
    lit = load_scenario("constant-slip", {**TINY, "duration_s": 0.3, "camera.lighting.sun": True})
    export_kitti(flat, tmp_path / "flat", max_frames=2)
    export_kitti(lit, tmp_path / "lit", max_frames=2)

    def image(name: str, side: str, k: int) -> np.ndarray:
        return cv2.imread(str(tmp_path / name / side / f"{k:06d}.png"), cv2.IMREAD_UNCHANGED)

    assert np.abs(image("flat", "image_0", 1).astype(int) - image("lit", "image_0", 1)).mean() > 5.0
    meta = {name: json.loads((tmp_path / name / "offtrack.json").read_text()) for name in ("flat", "lit")}
    assert "lighting" not in meta["flat"] and meta["lit"]["lighting"]["sun"] is True
    # the export is what the run's camera gives for those frames (the lit scenario has no lens, flex or correction)
    setup = build_scenario(lit.model_copy(update={"duration_s": 0.1 + 2.0 / lit.rates.control_hz}))
    _, cols = simulate(setup, UnsteeredTrailer(trailer_axles(setup)))
    ticks = np.flatnonzero(np.asarray(cols["camera_frame"]) > 0.5)[:2]
    camera = stereo_camera(setup)
    for k, r in enumerate(ticks):
        pose = CombinationPose(*(float(cols[c][r]) for c in ("X", "Y", "psi1", "gamma")))
        left, right = camera.pair(pose, k)
        assert np.array_equal(left, image("lit", "image_0", k)) and np.array_equal(right, image("lit", "image_1", k))


@pytest.mark.rendering
def test_animation_draws_the_matches_the_runs_odometry_recorded(tmp_path_factory: pytest.TempPathFactory) -> None:
    """A field-conditions run (lens, low sun with auto-exposure, mount vibration) of five camera frames, made in a
    child process (which owns its renderer; ``field_camera_run.py``, shared with test_figures.py); its animation's
    camera panel draws, frame by frame, as many matches and inliers as the run's odometry recorded."""
    from scenarios.export.animation import CameraPanel
    from scenarios.run.plots import load_run

    run = load_run(field_camera_run(tmp_path_factory))
    cols = run.columns
    panel = CameraPanel(run)
    assert len(panel.rows) >= 4
    try:
        for r in panel.rows:
            panel.image(int(r))
            assert panel.drawn == (int(cols["vo_matches"][r]), int(cols["vo_inliers"][r])), f"row {r}: {panel.info}"
            assert panel.frame.valid == bool(cols["vo_valid"][r])
    finally:
        panel.close()
    assert sum(int(cols["vo_matches"][r]) for r in panel.rows) > 100  # the frames after the first did match


@pytest.mark.rendering
def test_a_run_through_the_frame_cache_records_the_same_series(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``OFFTRACK_FRAME_CACHE``: the first run keeps its frames, the second takes them all back; both record what a
    run without the cache records (the timing columns aside)."""
    from scenarios.camera.frame_cache import FRAME_CACHE_ENV
    from scenarios.run.drive import simulate

    small = {"camera.width": 672, "camera.height": 196}
    config = load_scenario(
        "roundabout-3", {**small, "estimators.viso_ot": True, "duration_s": 0.35, "camera.lighting.sun": True}
    )

    def series(asked: int, workers: int) -> dict[str, np.ndarray]:
        outcome, cols = simulate(build_scenario(config), camera_workers=asked)
        assert outcome.status == "completed" and outcome.camera["workers"] == workers
        return {k: v for k, v in cols.items() if k not in ("render_ms", "vo_ms")}

    # the run without the cache renders in-process too (a pipelined run records the same series:
    # test_loop_pipelining.py), so the comparison isolates the cache
    plain = series(0, 0)
    monkeypatch.setenv(FRAME_CACHE_ENV, str(tmp_path))
    first = series(2, 0)  # with a frame cache: rendered here, whatever the workers asked for
    frames = sorted(tmp_path.glob("*/*.npz"))
    assert len(frames) == int(np.sum(plain["camera_frame"] > 0.5)) >= 3
    stamps = [f.stat().st_mtime_ns for f in frames]
    second = series(2, 0)
    assert [f.stat().st_mtime_ns for f in frames] == stamps  # read back, not written again
    for run in (first, second):
        assert run.keys() == plain.keys()
        assert [k for k in plain if not np.array_equal(plain[k], run[k], equal_nan=True)] == []
