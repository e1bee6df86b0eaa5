"""The field optics in the loop (``sensor/field_optics.py``, ``sensor/stereo_camera.py``): lens, calibration, mount
flex and the in-order exposure between the renderer and the odometry.

The library parts are tested on their own (``test_lens``, ``test_calibration``, ``test_mount_flex``,
``test_lighting``); here: the ideal case is untouched, the chain undoes what it should, the flex warp rotates
the right camera the way re-posing it in the renderer does, a calibration written by ``offtrack calibrate``
is what a run loads, only the auto-exposure must develop the frames in order, and pipelined runs with every field
condition on record the same series as serial ones.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from scenarios.camera.build import pair_developer, rig_from_config
from scenarios.config import load_scenario
from vehicle_model.errors import InputError

SMALL = {"camera.width": 672, "camera.height": 196}
LENS = {"camera.lens.k1": -0.2, "camera.lens.k2": 0.05}


def texture(height: int, width: int, seed: int = 0) -> np.ndarray:
    """A smooth random grey texture (so interpolation errors stay small)."""
    noise = np.random.default_rng(seed).uniform(0, 255, (height, width)).astype(np.float32)
    return np.clip(cv2.GaussianBlur(noise, (0, 0), 3.0) * 4.0 - 382.0, 0, 255).astype(np.uint8)


def test_the_ideal_camera_has_no_field_optics() -> None:
    config = load_scenario("roundabout-3", {"estimators.viso_ot": True})
    optics = pair_developer(config).optics
    assert optics.rig == rig_from_config(config)
    assert not optics.active and optics.render_rig is optics.rig  # the renderer draws exactly the ideal images


def test_lens_with_ideal_calibration_gives_back_the_pinhole_image() -> None:
    # The wide pinhole render, distorted by the lens, then undistorted with the true lens: the centre of the wide
    # render (same focal length, centred) within interpolation error.
    config = load_scenario("roundabout-3", {"estimators.viso_ot": True, **SMALL, **LENS})
    rig = rig_from_config(config)
    optics = pair_developer(config).optics
    wide = optics.render_rig
    assert (wide.width, wide.height) > (rig.width, rig.height)
    assert np.allclose(wide.intrinsics()[0, 0], rig.intrinsics()[0, 0])
    image = texture(wide.height, wide.width)
    left, _ = optics.prepare(image, image, right_rotation=None, seed=0, frame=0)
    dx, dy = (wide.width - rig.width) // 2, (wide.height - rig.height) // 2
    centre = image[dy : dy + rig.height, dx : dx + rig.width].astype(float)
    inner = (slice(10, -10), slice(10, -10))
    error = np.abs(left.astype(float) - centre)[inner]
    assert np.median(error) < 2.0 and np.percentile(error, 95) < 8.0  # grey levels


def test_only_the_auto_exposure_develops_the_frames_in_order() -> None:
    base = {"estimators.viso_ot": True, **SMALL}
    ideal = pair_developer(load_scenario("roundabout-3", base))
    assert not ideal.develops_in_order and ideal.correction is None
    lit = pair_developer(load_scenario("roundabout-3", {**base, "camera.lighting.sun": True}))
    assert lit.develops_in_order and lit.optics.sensor_effects_after  # the noise comes after the exposure
    fixed = pair_developer(
        load_scenario("roundabout-3", {**base, "camera.lighting.sun": True, "camera.lighting.auto_exposure": False})
    )
    assert not fixed.develops_in_order and not fixed.optics.active
    # An unexposed pair (radiance at gain 1) comes out as grey levels exposed to the target level.
    from sensor.stereo_camera import RawStereoPair

    rig = lit.rig
    radiance = np.full((rig.height, rig.width), 55.0, np.float32)
    left, right = lit.develop(RawStereoPair(radiance, radiance, exposed=False), 0)
    assert left.dtype == right.dtype == np.uint8
    assert abs(float(left.mean()) - 110.0) < 1.0  # the default target level, gain 2
    with pytest.raises(ValueError, match="auto-exposure"):
        ideal.develop(RawStereoPair(radiance, radiance, exposed=False), 0)


@pytest.mark.rendering
def test_the_flex_warp_rotates_the_right_camera_like_re_posing_it() -> None:
    # de Saxe & Cebon 2018, eq (8): a rotation about the optical centre is the homography K·Rᵀ·K⁻¹. Rendering
    # the right camera re-posed by R and warping the aligned render must give the same image (inside the border
    # strip).
    from scenarios.camera.build import world_for_scenario
    from scenarios.setup.build import build_scenario
    from sensor.camera import Misalignment
    from sensor.renderer import StereoRenderer

    over = {"estimators.viso_ot": True, **SMALL, "camera.flex.vibration_rms_deg": [0.5, 0.5, 0.5]}
    setup = build_scenario(load_scenario("roundabout-3", over))
    rig = rig_from_config(setup.config)
    optics = pair_developer(setup.config).optics
    rotation = Misalignment.from_degrees(0.4, -0.3, 0.5)
    renderer = StereoRenderer(world_for_scenario(setup), rig, setup.params)
    pose = setup.initial_state.pose
    aligned = renderer.render(pose, frame=0).right
    _, warped = optics.prepare(aligned, aligned, right_rotation=rotation, seed=0, frame=0)
    renderer.rig = rig.replace(misalignment=rotation)
    posed = renderer.render(pose, frame=0).right
    inner = (slice(12, -12), slice(12, -12))
    same = float(np.median(np.abs(warped.astype(float) - posed.astype(float))[inner]))
    back = Misalignment.from_degrees(-0.4, 0.3, -0.5)
    opposite = optics.prepare(aligned, aligned, right_rotation=back, seed=0, frame=0)[1]
    other = float(np.median(np.abs(opposite.astype(float) - posed.astype(float))[inner]))
    assert same < 3.0  # grey levels: interpolation only
    assert other > 2.0 * same  # and the sign matters


def test_a_calibration_from_offtrack_calibrate_is_what_a_run_loads(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from scenarios.cli import app
    from sensor.calibration import CalibrationResult

    out = tmp_path / "cal"
    sets = [f"--set={k}={v}" for k, v in {**SMALL, **LENS, "camera.calibration.views": 20}.items()]
    done = CliRunner().invoke(app, ["calibrate", "roundabout-3", "--out", str(out), *sets])  # in this process
    assert done.exit_code == 0, done.output
    residuals = json.loads((out / "residuals.json").read_text())
    assert residuals["rms_px"]["stereo"] < 0.3
    assert abs(residuals["baseline_m"]["error"]) < 2e-3
    config = load_scenario(
        "roundabout-3",
        {
            "estimators.viso_ot": True,
            **SMALL,
            **LENS,
            "camera.calibration.mode": "file",
            "camera.calibration.file": str(out / "calibration.yaml"),
        },
    )
    optics = pair_developer(config).optics
    written = CalibrationResult.read(out / "calibration.yaml")
    assert optics.calibration is not None
    np.testing.assert_array_equal(optics.calibration.p1, written.p1)
    assert optics.vo_config().baseline == pytest.approx(written.rectified_rig_parameters().baseline)
    wrong = load_scenario(
        "roundabout-3",
        {
            "estimators.viso_ot": True,
            "camera.calibration.mode": "file",
            "camera.calibration.file": str(out / "calibration.yaml"),
        },
    )
    with pytest.raises(InputError, match=r"camera\.calibration\.file"):
        pair_developer(wrong)  # made for 672×196 images, the camera is 1344×391


@pytest.mark.slow  # pipelined = serial runs by default in test_loop_pipelining; this adds the field optics
@pytest.mark.rendering
def test_pipelined_and_serial_field_runs_are_identical() -> None:
    # Flex (twist and seeded vibration), lens, estimated calibration and a low sun: the flex is drawn in frame order
    # in the co-simulation's process and handed to whichever worker renders the frame.
    from scenarios.run.drive import simulate
    from scenarios.setup.build import build_scenario

    field = {
        "vehicle": "lst",
        "estimators.viso_ot": True,
        "feedback": "viso_ot",
        "duration_s": 3.0,
        "speed.cornering_kmh": 25.0,
        **SMALL,
        **LENS,
        "camera.calibration.mode": "estimated",
        "camera.calibration.views": 15,
        "camera.flex.twist_deg_per_mps2": [0.05, 0.0, 0.03],
        "camera.flex.vibration_rms_deg": [0.01, 0.01, 0.01],
        "camera.lighting.sun": True,
    }
    runs = []
    for workers in (0, 2):
        setup = build_scenario(load_scenario("roundabout-3", field))
        runs.append(simulate(setup, camera_workers=workers))
    (a_outcome, a), (b_outcome, b) = runs
    assert a_outcome.status == b_outcome.status == "completed"
    differ = [k for k in a if k not in {"render_ms", "vo_ms"} and not np.array_equal(a[k], b[k], equal_nan=True)]
    assert differ == []
    assert np.isfinite(a["offtracking_viso_ot"]).sum() > 10
