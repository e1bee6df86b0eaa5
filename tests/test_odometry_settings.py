"""The odometry's settings in the camera section (``camera.vo_bucket_max_features``, ``camera.vo_ransac_iters``,
``camera.vo_covariance_model``, ``camera.vo_gradient_refinement``): left out, the run's odometry is the one built
from the optics with libviso2's matching, field for field; a rig's own value is its odometry's and the section's is
every other rig's; a value out of the odometry's range is refused naming the field and the range before any work."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_faults import assert_one_line_error, offtrack_in_process

from scenarios.camera.build import camera_tag, frame_odometry, odometry_config, pair_developer, rig_settings
from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from sensor.vo.config import VOConfig

CAMERA = {"estimators.viso_ot": True}


def test_left_out_the_odometry_is_the_optics_one_with_libviso2s_matching_and_sub_pixel_refinement() -> None:
    config = load_scenario("roundabout-3", CAMERA)
    optics = pair_developer(config).optics
    built = odometry_config(optics, rig_settings(config))
    # the optics' camera model and stereo search, libviso2's other fields, sub-pixel refinement: every field equal
    assert built == optics.vo_config().model_copy(update={"refinement": 2})
    assert (
        built.model_dump()
        == VOConfig(
            f=built.f,
            cu=built.cu,
            cv=built.cv,
            baseline=built.baseline,
            max_disparity=built.max_disparity,
            refinement=2,
        ).model_dump()
    )
    assert (built.bucket_max_features, built.ransac_iters) == (2, 200)  # libviso2's
    assert (built.covariance_model, built.gradient_refinement) == ("gauss_newton", "off")


def test_a_rigs_own_matching_settings_are_its_odometrys_and_the_sections_the_others() -> None:
    rigs = [
        {"unit": 1},
        {"unit": 2, "facing": "rear", "vo_bucket_max_features": 6, "vo_gradient_refinement": "lucas_kanade_affine"},
    ]
    config = load_scenario(
        "roundabout-3", {**CAMERA, "vehicle": "au-b-double", "camera.vo_ransac_iters": 50, "camera.rigs": rigs}
    )
    built = [odometry_config(pair_developer(config, i).optics, rig_settings(config, i)) for i in range(2)]
    assert [(vo.bucket_max_features, vo.ransac_iters, vo.gradient_refinement) for vo in built] == [
        (2, 50, "off"),
        (6, 50, "lucas_kanade_affine"),
    ]


def test_the_setting_reaches_the_runs_odometry() -> None:
    config = load_scenario(
        "roundabout-3",
        {
            **CAMERA,
            "camera.vo_bucket_max_features": 6,
            "camera.vo_ransac_iters": 75,
            "camera.vo_covariance_model": "sandwich",
            "camera.vo_gradient_refinement": "lucas_kanade_affine",
        },
    )
    odometry = frame_odometry(build_scenario(config), pair_developer(config).optics)
    vo = odometry.vo.config
    assert (vo.bucket_max_features, vo.ransac_iters, vo.covariance_model) == (6, 75, "sandwich")
    assert vo.gradient_refinement == "lucas_kanade_affine"


@pytest.mark.parametrize(
    ("assignment", "field", "allowed"),
    [
        ("camera.vo_bucket_max_features=0", "camera.vo_bucket_max_features", "greater than or equal to 1"),
        ("camera.vo_ransac_iters=-5", "camera.vo_ransac_iters", "greater than or equal to 1"),
        (
            "camera.rigs=[{vo_bucket_max_features: 0}]",
            "camera.rigs[0].vo_bucket_max_features",
            "greater than or equal to 1",
        ),
        ("camera.vo_covariance_model=hessian", "camera.vo_covariance_model", "'gauss_newton' or 'sandwich'"),
        (
            "camera.vo_gradient_refinement=bicubic",
            "camera.vo_gradient_refinement",
            "'off', 'lucas_kanade' or 'lucas_kanade_affine'",
        ),
    ],
)
def test_a_value_out_of_the_odometrys_range_is_refused_naming_the_field_before_any_work(
    assignment: str,
    field: str,
    allowed: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "run"
    refused = offtrack_in_process(monkeypatch, capsys, "run", "roundabout-test", "--set", assignment, "--out", str(out))
    assert_one_line_error(refused, f"{field} = ", allowed)
    assert len([line for line in refused.stderr.splitlines() if field in line]) == 1
    assert not out.exists()


@pytest.mark.parametrize(
    ("field", "odometry_field"),
    [("vo_bucket_max_features", "bucket_max_features"), ("vo_ransac_iters", "ransac_iters")],
)
def test_the_sections_range_is_the_odometrys(field: str, odometry_field: str) -> None:
    assert getattr(load_scenario("roundabout-test", {f"camera.{field}": 1}).camera, field) == 1  # the smallest taken
    with pytest.raises(ValueError, match=odometry_field):  # the odometry refuses what the section refuses
        VOConfig(f=500.0, cu=300.0, cv=200.0, baseline=0.5, **{odometry_field: 0})


def test_the_frames_are_named_without_the_odometrys_settings() -> None:
    """Runs that differ only in the odometry's matching share a frame cache (its images are the same), and the
    section's other fields still name the frames."""

    def tag(overrides: dict) -> str:
        return camera_tag(build_scenario(load_scenario("roundabout-test", {**CAMERA, **overrides})))

    default = tag({})
    assert tag({"camera.vo_bucket_max_features": 6, "camera.vo_ransac_iters": 50}) == default
    assert tag({"camera.vo_covariance_model": "sandwich", "camera.vo_gradient_refinement": "lucas_kanade"}) == default
    assert tag({"camera.width": 640}) != default
