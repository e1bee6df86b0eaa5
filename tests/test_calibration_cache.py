"""The disk cache of estimated calibrations (:mod:`scenarios.camera.calibration_cache`) and the per-process memo of
scenario worlds (:func:`scenarios.camera.build.world_for_scenario`).

A cached calibration reads back bit-identical to a computed one; every input that decides the result changes the
key; a truncated, corrupt or foreign entry and a folder that cannot be written fall back to computing. The worlds:
one build per road and settings, a world on a terrain built every time.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest

import scenarios.camera.build as camera_build
import sensor.calibration
from scenarios.camera import calibration_cache
from scenarios.camera.calibration_cache import cache_dir, cached_calibrate_rig, calibration_key
from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from sensor.calibration import CalibrationResult, calibrate_rig
from sensor.camera import Lens, Misalignment, StereoRig
from vehicle_model.terrain import FlatTerrain

RIG = StereoRig.from_degrees(width=480, height=160, roll_deg=-0.15, yaw_deg=0.10, noise_std=1.0)
LEFT = Lens(k1=-0.1, k2=0.02, p1=2e-4)
RIGHT = Lens(k1=-0.09, k2=0.01, p2=-1e-4)
SETTINGS = {"views": 5, "target": (9, 6), "square_size": 0.05, "corner_noise_px": 0.1, "seed": 3}


def _fields(result: CalibrationResult) -> dict[str, object]:
    return {f.name: getattr(result, f.name) for f in dataclasses.fields(result) if f.name != "_maps"}


def assert_bit_identical(a: CalibrationResult, b: CalibrationResult) -> None:
    """Every array of the two results equal to the bit (dtype, shape, bytes), every other field equal."""
    fa, fb = _fields(a), _fields(b)
    for name, value in fa.items():
        if isinstance(value, np.ndarray):
            other = fb[name]
            assert (value.dtype, value.shape) == (other.dtype, other.shape), name
            assert value.tobytes() == other.tobytes(), name
        elif isinstance(value, float):
            assert float(value).hex() == float(fb[name]).hex(), name
        else:
            assert value == fb[name], name


@pytest.fixture(scope="module")
def computed() -> CalibrationResult:
    return calibrate_rig(RIG, LEFT, RIGHT, **SETTINGS)


@pytest.fixture
def counted(monkeypatch: pytest.MonkeyPatch, computed: CalibrationResult) -> list[int]:
    """``calibrate_rig`` replaced by the module's computed result; the list counts the calls."""
    calls: list[int] = []

    def fake(*args: object, **kwargs: object) -> CalibrationResult:
        calls.append(1)
        return computed

    monkeypatch.setattr(sensor.calibration, "calibrate_rig", fake)
    return calls


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("OFFTRACK_CACHE_DIR", str(tmp_path / "cache"))
    return cache_dir()


def test_a_cached_calibration_reads_back_bit_identical(
    cache: Path, counted: list[int], computed: CalibrationResult, monkeypatch: pytest.MonkeyPatch
) -> None:
    first = cached_calibrate_rig(RIG, LEFT, RIGHT, **SETTINGS)  # computed (a real calibration) and written
    assert first is computed and counted == [1]
    assert len(list(cache.glob("*.npz"))) == 1 and not list(cache.glob(".tmp-*"))

    def refuse(*args: object, **kwargs: object) -> CalibrationResult:
        raise AssertionError("computed although cached")

    monkeypatch.setattr(sensor.calibration, "calibrate_rig", refuse)
    again = cached_calibrate_rig(RIG, LEFT, RIGHT, **SETTINGS)
    assert again is not computed
    assert_bit_identical(again, computed)
    image = np.random.default_rng(0).integers(0, 256, (RIG.height, RIG.width), dtype=np.uint8)
    for a, b in zip(again.rectify(image, image), computed.rectify(image, image), strict=True):
        assert a.tobytes() == b.tobytes()


def test_every_input_and_the_code_change_the_key(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    base = calibration_key(RIG, LEFT, RIGHT, **SETTINGS)
    assert calibration_key(RIG, LEFT, RIGHT, **SETTINGS) == base
    tiny = float(np.nextafter(1.0, 2.0)) - 1.0  # one ulp at 1
    changed = [
        calibration_key(
            dataclasses.replace(RIG, misalignment=Misalignment(yaw=RIG.misalignment.yaw + 1e-9)),
            LEFT,
            RIGHT,
            **SETTINGS,
        ),
        calibration_key(dataclasses.replace(RIG, baseline=RIG.baseline + tiny), LEFT, RIGHT, **SETTINGS),
        calibration_key(dataclasses.replace(RIG, noise_std=2.0), LEFT, RIGHT, **SETTINGS),
        calibration_key(dataclasses.replace(RIG, width=482), LEFT, RIGHT, **SETTINGS),
        calibration_key(RIG, RIGHT, LEFT, **SETTINGS),
        calibration_key(RIG, LEFT, Lens(k1=-0.09, k2=0.01, p2=-1e-4, k3=1e-12), **SETTINGS),
        *(
            calibration_key(RIG, LEFT, RIGHT, **{**SETTINGS, name: value})
            for name, value in (("views", 6), ("target", (9, 7)), ("square_size", 0.06), ("corner_noise_px", 0.2))
        ),
        calibration_key(RIG, LEFT, RIGHT, **{**SETTINGS, "seed": 4}),
        calibration_key(RIG, LEFT, RIGHT, **SETTINGS, alpha=0.5),
        calibration_key(RIG, LEFT, RIGHT, **SETTINGS, stereo_refinement="joint"),
    ]
    monkeypatch.setattr(cv2, "__version__", cv2.__version__ + "-other")
    changed.append(calibration_key(RIG, LEFT, RIGHT, **SETTINGS))
    monkeypatch.undo()
    supported = cv2.checkHardwareSupport
    monkeypatch.setattr(cv2, "checkHardwareSupport", lambda feature: feature == 1 and supported(feature))
    changed.append(calibration_key(RIG, LEFT, RIGHT, **SETTINGS))  # another CPU (or OPENCV_CPU_DISABLE)
    monkeypatch.undo()
    edited = tmp_path / "calibration.py"
    edited.write_bytes(calibration_cache.SOURCES[0].read_bytes() + b"\n# edited\n")
    monkeypatch.setattr(calibration_cache, "SOURCES", (edited, *calibration_cache.SOURCES[1:]))
    changed.append(calibration_key(RIG, LEFT, RIGHT, **SETTINGS))
    assert base not in changed and len(set(changed)) == len(changed)


def _entry(cache: Path) -> Path:
    (entry,) = cache.glob("*.npz")
    return entry


@pytest.mark.parametrize("fault", ["truncated", "corrupt", "empty", "another key's", "a field missing"])
def test_a_bad_entry_is_computed_afresh_and_replaced(
    cache: Path, counted: list[int], computed: CalibrationResult, fault: str
) -> None:
    cached_calibrate_rig(RIG, LEFT, RIGHT, **SETTINGS)
    entry = _entry(cache)
    good = entry.read_bytes()
    if fault == "truncated":
        entry.write_bytes(good[: len(good) // 2])
    elif fault == "corrupt":
        entry.write_bytes(good[:200] + bytes(255 - b for b in good[200:400]) + good[400:])
    elif fault == "empty":
        entry.write_bytes(b"")
    else:
        with np.load(entry) as data:
            arrays = dict(data)
        if fault == "another key's":
            arrays["key"] = np.str_("0" * 64)
        else:
            del arrays["q"]
        with entry.open("wb") as handle:
            np.savez(handle, **arrays)
    result = cached_calibrate_rig(RIG, LEFT, RIGHT, **SETTINGS)
    assert len(counted) == 2  # computed again
    assert_bit_identical(result, computed)
    assert_bit_identical(cached_calibrate_rig(RIG, LEFT, RIGHT, **SETTINGS), computed)
    assert len(counted) == 2  # the entry was replaced by a good one


def test_a_folder_that_cannot_be_written_leaves_the_result_uncached(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, counted: list[int], computed: CalibrationResult
) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("OFFTRACK_CACHE_DIR", str(blocker))  # its calibration/ folder cannot be made
    for n in (1, 2):
        assert_bit_identical(cached_calibrate_rig(RIG, LEFT, RIGHT, **SETTINGS), computed)
        assert len(counted) == n
    assert blocker.read_text() == "not a folder"


def test_no_home_folder_leaves_the_result_uncached(
    monkeypatch: pytest.MonkeyPatch, counted: list[int], computed: CalibrationResult
) -> None:
    def no_home() -> Path:
        raise RuntimeError("Could not determine home directory.")

    monkeypatch.setattr(calibration_cache, "cache_dir", no_home)
    assert cached_calibrate_rig(RIG, LEFT, RIGHT, **SETTINGS) is computed and counted == [1]


def test_the_scenarios_estimated_calibration_goes_through_the_cache(
    cache: Path, counted: list[int], computed: CalibrationResult
) -> None:
    config = load_scenario(
        "roundabout-3", {"camera.calibration.mode": "estimated", "camera.calibration.views": 7, "seed": 98765}
    )
    rig = camera_build.rig_from_config(config)
    camera_build._calibration_cached.cache_clear()
    assert camera_build.calibration_for(rig, config) is computed
    camera_build._calibration_cached.cache_clear()
    assert_bit_identical(camera_build.calibration_for(rig, config), computed)  # read back from the disk
    camera_build._calibration_cached.cache_clear()
    assert len(counted) == 1 and len(list(cache.glob("*.npz"))) == 1


def test_a_scenarios_world_is_built_once_per_road_and_settings(monkeypatch: pytest.MonkeyPatch) -> None:
    built: list[dict] = []

    def fake_build(path: object, terrain: object = None, **settings: object) -> object:
        built.append(settings)
        return object()

    monkeypatch.setattr(camera_build, "build_world", fake_build)
    monkeypatch.setattr(camera_build, "_WORLDS", {})
    setup = build_scenario(load_scenario("roundabout-test"))
    first = camera_build.world_for_scenario(setup)
    assert camera_build.world_for_scenario(setup) is first
    assert camera_build.world_for_scenario(setup.config) is first  # the same road rebuilt from the configuration
    assert camera_build.world_for_scenario(setup, seed=setup.config.seed + 1) is not first
    assert camera_build.world_for_scenario(setup, kind="airfield") is not first
    assert camera_build.world_for_scenario(setup, scenery_density=0.5) is not first
    assert len(built) == 4
    flat = FlatTerrain()
    assert camera_build.world_for_scenario(setup, terrain=flat) is not camera_build.world_for_scenario(
        setup, terrain=flat
    )  # on a terrain: built every time
    assert len(built) == 6
    for seed in range(camera_build.WORLDS_KEPT):  # the least recently used is dropped
        camera_build.world_for_scenario(setup, seed=1000 + seed)
    assert camera_build.world_for_scenario(setup) is not first
