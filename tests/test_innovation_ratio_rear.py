"""``innovation_ratio_from: rear_lateral``: ``ρ`` of eq (5) from the lateral innovation on a rear rig only.

* On the same synthetic feed a rear-facing camera's filter with ``rear_lateral`` is the ``lateral`` one to the bit
  (estimate, std, ``ρ``) and a side-facing camera's the default's to the bit, while ``lateral`` would move the side
  camera's ``ρ`` (so the scoping is what keeps it).
* In a run's rigs (the LST, the B-double, the A-double, the scenario's ``fusion`` settings) every rear rig's filter
  takes ``lateral`` and every side rig's (the leads', the A-double's dolly's) ``all``; every other setting each filter
  takes is the default's.
* Unset, no rig's filter takes anything but ``all``: the default is unchanged.
* A value outside the three is refused on one line that names the field and the three values.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

import tests.test_fusion as synthetic
from scenarios.camera.build import rig_from_config
from scenarios.camera_schema import rig_configs
from scenarios.config import ConfigError, load_scenario
from sensor.fusion import FusedVisoOt, FusionNoise
from tests.test_fusion import CAMERA, EVERY, PARAMS, drive_with_truth, run

# A side camera 3 m up at x = −7 m, 1.275 m left, looking left: OpenCV x (right) = trailer +x, y (down) = −z,
# z (forward) = +y.
SIDE_CAMERA = np.eye(4)
SIDE_CAMERA[:3, :3] = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]
SIDE_CAMERA[:3, 3] = (-7.0, 1.275, 3.0)


@pytest.fixture(scope="module")
def runs() -> dict[tuple[str, str], tuple[FusedVisoOt, np.ndarray, np.ndarray]]:
    """Each camera's filter with each value on the same drive and odometry error (as
    tests/test_innovation_ratio_lateral.py's: every motion taken, the two ratios apart and above the floor)."""
    r_m, w_m, incs, _ = drive_with_truth(n=600, slip=0.0)
    errors = np.random.default_rng(11).normal(size=(len(incs) // EVERY + 1, 3)) * (4e-3, 4e-3, 1e-4)
    covariance = np.diag([1e-8, 1e-8, 1e-8, 4e-6, 4e-6, 4e-6])
    out = {}
    feed = synthetic.CAMERA, synthetic.CAMERA_INVERSE
    try:
        for camera_name, camera in (("rear", CAMERA), ("side", SIDE_CAMERA)):
            synthetic.CAMERA, synthetic.CAMERA_INVERSE = camera, np.linalg.inv(camera)  # the feed's camera motions
            for value in ("default", "lateral", "rear_lateral"):
                noise = FusionNoise() if value == "default" else FusionNoise(innovation_ratio_from=value)
                fused = FusedVisoOt(PARAMS, camera, noise)
                est, std, _ = run(fused, r_m, w_m, incs, frame_error=errors, covariance=covariance)
                out[camera_name, value] = (fused, np.asarray(est, dtype=float), np.asarray(std, dtype=float))
    finally:
        synthetic.CAMERA, synthetic.CAMERA_INVERSE = feed
    return out


def _same(a: tuple[FusedVisoOt, np.ndarray, np.ndarray], b: tuple[FusedVisoOt, np.ndarray, np.ndarray]) -> bool:
    return (
        np.array_equal(a[1], b[1], equal_nan=True)
        and np.array_equal(a[2], b[2], equal_nan=True)
        and a[0].innovation_ratio == b[0].innovation_ratio
    )


def test_the_rear_camera_takes_the_lateral_ratio_and_the_side_camera_the_3d_one(runs) -> None:
    for camera in ("rear", "side"):
        fused, est, _ = runs[camera, "default"]
        assert np.isfinite(est).sum() > 50 and fused.rejected == 0, camera  # estimates made, every motion taken
    assert runs["rear", "rear_lateral"][0].noise.innovation_ratio_from == "lateral"
    assert runs["side", "rear_lateral"][0].noise.innovation_ratio_from == "all"
    assert _same(runs["rear", "rear_lateral"], runs["rear", "lateral"])
    assert _same(runs["side", "rear_lateral"], runs["side", "default"])
    # the lateral ratio would move each camera's ρ by more than 5 %: the scoping, not the feed, keeps the side's
    for camera in ("rear", "side"):
        moved, kept = runs[camera, "lateral"][0].innovation_ratio, runs[camera, "default"][0].innovation_ratio
        assert not math.isclose(moved, kept, rel_tol=0.05), camera
        assert not np.array_equal(runs[camera, "lateral"][2], runs[camera, "default"][2], equal_nan=True), camera


@pytest.mark.parametrize(
    ("vehicle", "expected"),
    [
        (None, ("lateral",)),  # the LST: its one camera looks back
        ("au-b-double-steered", ("all", "lateral")),  # the lead's side rig, the rear trailer's rear rig
        ("au-a-double-steered", ("all", "all", "lateral")),  # the lead's and the dolly's side rigs, the rear's
    ],
)
def test_a_runs_rigs_take_the_ratio_by_their_facing(vehicle: str | None, expected: tuple[str, ...]) -> None:
    overrides = {} if vehicle is None else {"vehicle": vehicle}
    default = load_scenario("roundabout-3", overrides)
    chosen = load_scenario("roundabout-3", {**overrides, "fusion.innovation_ratio_from": "rear_lateral"})
    params = default.vehicle_params()
    facings = []
    for index, rig in enumerate(rig_configs(default.camera, params)):
        stereo = rig_from_config(default, index)
        camera = stereo.camera_in_trailer("left", params)
        by_default = FusedVisoOt(params, camera, default.fusion, unit=stereo.unit)
        with_rear = FusedVisoOt(params, camera, chosen.fusion, unit=stereo.unit)
        assert by_default.noise.innovation_ratio_from == "all", (vehicle, rig.unit)  # the default unchanged
        facings.append(with_rear.noise.innovation_ratio_from)
        # every other setting of the rig's filter (its side rig's or linked rig's) is the default's
        assert with_rear.noise.replace(innovation_ratio_from="all") == by_default.noise, (vehicle, rig.unit)
    assert tuple(facings) == expected


def test_for_camera_decides_on_the_optical_axis() -> None:
    noise = FusionNoise(innovation_ratio_from="rear_lateral")
    for unit in (1, 2, 3):
        assert noise.for_camera((-1.0, 0.0), unit).innovation_ratio_from == "lateral"
        assert noise.for_camera((-0.8, 0.6), unit).innovation_ratio_from == "lateral"  # back and to one side
        for axis in ((0.0, 1.0), (0.0, -1.0), (-0.6, 0.8), (1.0, 0.0), (0.8, -0.6)):  # across or forward
            assert noise.for_camera(axis, unit).innovation_ratio_from == "all", (axis, unit)
    default = FusionNoise()
    assert default.for_camera((-1.0, 0.0)) is default  # unset: the settings themselves, as before
    for value in ("all", "lateral"):  # the other values are taken as they are on every rig
        for axis in ((-1.0, 0.0), (0.0, 1.0)):
            assert FusionNoise(innovation_ratio_from=value).for_camera(axis, 2).innovation_ratio_from == value


def test_a_bad_value_is_refused_on_one_line() -> None:
    field = "fusion.innovation_ratio_from"
    for value in ("all", "lateral", "rear_lateral"):
        assert load_scenario("roundabout-3", {field: value}).fusion.innovation_ratio_from == value
    for bad in ("rear", "rear-lateral", "lat", "", 2):
        with pytest.raises(ConfigError, match=re.escape(field)) as caught:
            load_scenario("roundabout-3", {field: bad})
        lines = [line for line in str(caught.value).splitlines() if field in line]
        assert len(lines) == 1, str(caught.value)
        assert all(f"'{value}'" in lines[0] for value in ("all", "lateral", "rear_lateral")), lines[0]
