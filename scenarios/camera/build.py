"""The scenario's camera as sensor objects: the ``camera`` section of the configuration mapped to :mod:`sensor`.

Degrees and configuration models stop here; what comes out is SI and made of sensor objects:

* :func:`rig_from_config` — the :class:`~sensor.camera.StereoRig`;
* :func:`world_for_scenario` — the procedural :class:`~sensor.world.World` around the reference path (the
  scenario's seed, ``camera.scenery_density`` and ``camera.world``);
* :func:`lenses`, :func:`calibration_for` (``camera.calibration``: ideal, estimated once per
  process by :func:`run_calibration`, or read from a file), :func:`lighting_from_config`, :func:`mount_flex`;
* :func:`stereo_camera` — the :class:`~sensor.stereo_camera.StereoCamera` of a built scenario: the one place a
  camera (and its :class:`~sensor.renderer.StereoRenderer`) is assembled, as the run has it or as an ideal pinhole
  rig (``ideal=True``), optionally through a frame cache (:mod:`.frame_cache`); :func:`pair_developer` its
  development alone (a process that does not render);
* :func:`frame_odometry` — the per-frame estimator :class:`~sensor.frame_odometry.FrameOdometry`;
* :func:`flex_schedule` — the right camera's :class:`~sensor.mount_flex.FlexSchedule`, seeded by
  ``(seed, 0xF1E8)``.
"""

from __future__ import annotations

import functools
import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from sensor.calibration import CalibrationResult, calibrate_rig
from sensor.camera import Lens, Misalignment, StereoRig
from sensor.lighting import Lighting
from sensor.mount_flex import FlexSchedule, MountFlex
from sensor.world import World, build_world
from vehicle_model.errors import InputError

from ..config import ScenarioConfig
from ..setup.build import ScenarioSetup, build_scenario

if TYPE_CHECKING:
    from sensor.field_optics import FieldOptics
    from sensor.frame_odometry import FrameOdometry
    from sensor.stereo_camera import PairDeveloper, StereoCamera

__all__ = [
    "CONFIGURED",
    "calibration_for",
    "calibration_target_rig",
    "camera_tag",
    "flex_schedule",
    "frame_odometry",
    "lenses",
    "lighting_from_config",
    "mount_flex",
    "pair_developer",
    "resolve_scenery_density",
    "rig_from_config",
    "run_calibration",
    "stereo_camera",
    "world_for_scenario",
]


def rig_from_config(config: ScenarioConfig | Any) -> StereoRig:
    """The stereo rig of a scenario's ``camera`` section (degrees at this edge, SI inside).

    Parameters
    ----------
    config : ScenarioConfig or CameraConfig
        A scenario configuration (its ``camera``) or the camera section itself; a configuration
        without one gives the default rig (de Saxe & Cebon 2018, §3.1).
    """
    camera = getattr(config, "camera", config)
    if camera is None or not hasattr(camera, "psi_c2v_deg"):
        return StereoRig()
    roll, pitch, yaw = getattr(camera, "right_misalignment_deg", (0.0, 0.0, 0.0))
    return StereoRig.from_degrees(
        hfov_deg=camera.hfov_deg,
        psi_c2v_deg=camera.psi_c2v_deg,
        roll_deg=roll,
        pitch_deg=pitch,
        yaw_deg=yaw,
        width=camera.width,
        height=camera.height,
        baseline=camera.baseline,
        station=camera.station,
        lateral=camera.lateral,
        mount_height=camera.mount_height,
        noise_std=getattr(camera, "noise_std", 0.0),
        exposure_std=getattr(camera, "brightness_jitter", 0.0),
    )


def resolve_scenery_density(config: ScenarioConfig, override: float | None = None) -> float:
    """The scenery density to render: ``override`` if given, else the scenario's ``camera.scenery_density`` (1.0)."""
    if override is not None:
        return float(override)
    return float(getattr(getattr(config, "camera", None), "scenery_density", 1.0))


def world_for_scenario(
    setup_or_config: ScenarioSetup | ScenarioConfig,
    scenery_density: float | None = None,
    seed: int | None = None,
    **world_settings: Any,
) -> World:
    """The procedural world around a scenario's reference path.

    Parameters
    ----------
    setup_or_config : ScenarioSetup or ScenarioConfig
        A built scenario (its ``path`` and ``config.seed`` are used) or a configuration (built here).
    scenery_density : float, optional
        Fraction of roadside objects, in [0, 1] (the paper's §3.2.3: 1.0, 0.5, 0.0); default: the
        scenario's ``camera.scenery_density`` (1.0 unless set).
    seed : int, optional
        Seed of the world (default: the scenario's ``seed``).
    **world_settings
        Other :class:`sensor.world.WorldConfig` fields (``road_width``, ``apron_width``,
        ``kind="airfield"`` for the Bourn-like airfield of the paper's §4, ``ground_detail``, …).
    """
    setup = setup_or_config if isinstance(setup_or_config, ScenarioSetup) else build_scenario(setup_or_config)
    seed = setup.config.seed if seed is None else seed
    density = resolve_scenery_density(setup.config, scenery_density)
    return build_world(setup.path, scenery_density=density, seed=int(seed), **world_settings)


def lenses(config: ScenarioConfig) -> tuple[Lens, Lens]:
    """The left and right lenses of the configuration (:meth:`~scenarios.camera_schema.CameraConfig.lens_pair`)."""
    return config.camera.lens_pair()


def calibration_target_rig(rig: StereoRig, config: ScenarioConfig) -> StereoRig:
    """The rig as it was when calibrated: the right camera rotated by ``camera.calibration.misalignment_deg``."""
    return rig.replace(misalignment=Misalignment.from_degrees(*config.camera.calibration.misalignment_deg))


def run_calibration(rig: StereoRig, config: ScenarioConfig) -> CalibrationResult:
    """Calibrate the rig as configured (``camera.calibration``; seeded by the run's seed)."""
    cal = config.camera.calibration
    left, right = lenses(config)
    return calibrate_rig(
        calibration_target_rig(rig, config),
        left,
        right,
        views=cal.views,
        target=(cal.target_cols, cal.target_rows),
        square_size=cal.square_size,
        corner_noise_px=cal.corner_noise_px,
        seed=config.seed,
    )


@functools.lru_cache(maxsize=4)
def _calibration_cached(config_json: str) -> CalibrationResult:
    config = ScenarioConfig.model_validate(json.loads(config_json))
    return run_calibration(rig_from_config(config), config)


def calibration_for(rig: StereoRig, config: ScenarioConfig) -> CalibrationResult | None:
    """The calibration the odometry uses (``None``: ideal). Estimated once per process and configuration."""
    cal = config.camera.calibration
    if cal.mode == "ideal":
        return None
    if cal.mode == "file":
        assert cal.file is not None
        result = CalibrationResult.read(Path(cal.file))
        if tuple(result.image_size) != (rig.width, rig.height):
            raise InputError(
                f"camera.calibration.file {cal.file} is for {result.image_size[0]}×{result.image_size[1]} px images; "
                f"the camera is {rig.width}×{rig.height} px"
            )
        return result
    # the camera and the seed decide the calibration: one per process for every run that shares them
    return _calibration_cached(json.dumps(config.model_dump(mode="json"), sort_keys=True))


def lighting_from_config(config: ScenarioConfig) -> Lighting | None:
    """The renderer's lighting (``None``: the flat lighting of the ideal study) from ``camera.lighting``."""
    light = config.camera.lighting  # the schema's section is the sensor's Lighting
    return light if light.sun else None


def mount_flex(config: ScenarioConfig) -> MountFlex:
    """The right camera's mount flex settings (``camera.flex``)."""
    return config.camera.flex  # the schema's section is the sensor's MountFlex


def flex_schedule(setup: ScenarioSetup) -> FlexSchedule:
    """The right camera's flex frame by frame: ``camera.flex`` at ``camera.station``, vibration seeded by
    ``(seed, 0xF1E8)``."""
    cfg = setup.config
    rng = np.random.default_rng([cfg.seed, 0xF1E8])
    return FlexSchedule(mount_flex(cfg), setup.params, cfg.camera.station, cfg.rates.frame_interval_s, rng)


def _camera_settings(config: ScenarioConfig) -> dict[str, Any]:
    """The keyword arguments of :class:`~sensor.stereo_camera.PairDeveloper` (and the camera) of ``config``."""
    rig = rig_from_config(config)
    return {
        "lenses": lenses(config),
        "calibration": calibration_for(rig, config),
        "lighting": lighting_from_config(config),
        "flex": mount_flex(config),
        "right_correction_deg": tuple(config.camera.right_correction_deg),
        "seed": config.seed,
        "frame_interval_s": 1.0 / config.rates.camera_hz,
    }


CONFIGURED: Final = "configured"
"""``lighting`` of :func:`stereo_camera`: the configuration's (flat for an ideal camera)."""


def _ideal_developer(config: ScenarioConfig, rig: StereoRig, lighting: Lighting | None) -> PairDeveloper:
    """An ideal pinhole rig's development: no lens, ideal calibration, no mount flex, no right-image correction."""
    from sensor.stereo_camera import PairDeveloper

    return PairDeveloper(rig, lighting=lighting, seed=config.seed, frame_interval_s=1.0 / config.rates.camera_hz)


def camera_tag(setup: ScenarioSetup, **settings: Any) -> str:
    """A name for the frames of the camera :func:`stereo_camera` builds for ``setup`` with ``settings``: a hash of the
    configuration's camera section, seed and camera rate, the reference path, the vehicle and the settings."""
    cfg = setup.config
    described = {
        "camera": cfg.camera.model_dump(mode="json"),
        "seed": cfg.seed,
        "camera_hz": cfg.rates.camera_hz,
        "vehicle": repr(setup.params),
        "settings": {k: repr(v) for k, v in sorted(settings.items())},
    }
    digest = hashlib.sha256(json.dumps(described, sort_keys=True).encode())
    digest.update(np.ascontiguousarray(setup.path.points, dtype=np.float64).tobytes())
    return digest.hexdigest()[:16]


def stereo_camera(
    setup: ScenarioSetup,
    *,
    ideal: bool = False,
    rig: StereoRig | None = None,
    lighting: Lighting | str | None = CONFIGURED,
    scenery_density: float | None = None,
    world: World | None = None,
    antialias: bool = False,
    frame_cache: Path | None = None,
) -> StereoCamera:
    """The scenario's stereo camera in its world: the one place a camera of a run is assembled.

    As the run has it (default): the world (``camera.world``: the roadside, or the airfield of de Saxe & Cebon
    2018, §4; ``camera.scenery_density``), the rig, the lenses, the calibration the odometry uses, the lighting and
    auto-exposure, the right camera's mount flex and the eq (8)–(9) correction, seeded by the run's seed. The
    odometry on its images is :func:`frame_odometry` and the flex frame by frame :func:`flex_schedule`.

    Parameters
    ----------
    setup : ScenarioSetup
        The built scenario.
    ideal : bool
        An ideal pinhole rig instead: the configured rig with no lens, ideal calibration, no mount flex and no
        correction, under flat lighting unless ``lighting`` says otherwise.
    rig : StereoRig, optional
        The rig of an ideal camera (default: the configured one, :func:`rig_from_config`); only with ``ideal``.
    lighting : Lighting or None
        The lighting of an ideal camera (``None``: flat); default: the configuration's for the run's camera, flat
        for an ideal one.
    scenery_density : float, optional
        Fraction of roadside objects (default: ``camera.scenery_density``).
    world : World, optional
        The world to render (default: built from the scenario, :func:`world_for_scenario`).
    antialias : bool
        Render with 4× multisampling.
    frame_cache : Path, optional
        Keep the developed frames in this directory and take them back on a later run
        (:class:`.frame_cache.FrameCache`, :meth:`sensor.stereo_camera.StereoCamera.pair`).

    Raises
    ------
    InputError
        ``rig`` or ``lighting`` given for the run's camera (they are the configuration's).
    """
    from sensor.stereo_camera import StereoCamera  # the renderer: OpenGL only where frames are rendered

    from .frame_cache import FrameCache

    cfg = setup.config
    if ideal:
        light = None if isinstance(lighting, str) else lighting
        developer = _ideal_developer(cfg, rig if rig is not None else rig_from_config(cfg), light)
    else:
        if rig is not None or not isinstance(lighting, str):
            raise InputError("the run's camera has the configured rig and lighting; pass ideal=True to change them")
        developer = pair_developer(cfg)
    if world is None:
        world = world_for_scenario(setup, scenery_density, kind=cfg.camera.world)
    store = None
    if frame_cache is not None:
        tag = camera_tag(
            setup,
            ideal=ideal,
            rig=developer.rig,
            lighting=developer.lighting,
            world=world.config,
            antialias=antialias,
        )
        store = FrameCache(frame_cache, tag)
    return StereoCamera(developer, world, setup.params, antialias=antialias, frame_store=store)


def pair_developer(config: ScenarioConfig) -> PairDeveloper:
    """The camera's development alone, for a process that gets the raw pairs from render workers."""
    from sensor.stereo_camera import PairDeveloper

    return PairDeveloper(rig_from_config(config), **_camera_settings(config))


def frame_odometry(setup: ScenarioSetup, optics: FieldOptics) -> FrameOdometry:
    """The per-frame estimator on the images ``optics`` gives (``camera.self_calibration``, rates, seed)."""
    from sensor.frame_odometry import FrameOdometry

    cfg = setup.config
    self_cal = cfg.camera.self_calibration
    settings = self_cal if self_cal.enabled else None  # the schema's section is the sensor's settings
    return FrameOdometry(
        setup.params,
        optics.vo_config().model_copy(update={"refinement": cfg.camera.vo_refinement}),
        optics.left_in_trailer(setup.params),
        cfg.rates.frame_interval_s,
        cfg.seed,
        settings,
    )
