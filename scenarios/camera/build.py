"""The scenario's cameras as sensor objects: the ``camera`` section of the configuration mapped to :mod:`sensor`.

Degrees and configuration models stop here; what comes out is SI and made of sensor objects. A run has one rig per
camera-carrying towed unit (:func:`rig_settings`, ``camera.rigs``); every function of a rig takes its ``rig_index``
(0: the first rig, the one camera of a tractor–semi-trailer). Each rig's random draws — its calibration, image
noise and exposure, mount flex and odometry — are seeded by :func:`rig_seed`, which is the run's seed for rig 0:

* :func:`rig_from_config` — the :class:`~sensor.camera.StereoRig` (:func:`rigs_from_config`: every one);
* :func:`world_for_scenario` — the procedural :class:`~sensor.world.World` around the reference path (the
  scenario's seed, ``camera.scenery_density`` and ``camera.world``), built once per process for a road and settings;
* :func:`lenses`, :func:`calibration_for` (``camera.calibration``: ideal, estimated by :func:`run_calibration` once
  per machine through a disk cache (:mod:`.calibration_cache`), or read from a file), :func:`lighting_from_config`,
  :func:`mount_flex`;
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
from vehicle_model.terrain import Terrain

from ..camera_schema import ODOMETRY_ONLY, RigConfig, StereoRigConfig, rig_configs
from ..config import ScenarioConfig
from ..setup.build import ScenarioSetup, build_scenario
from .calibration_cache import cached_calibrate_rig

if TYPE_CHECKING:
    from sensor.field_optics import FieldOptics
    from sensor.frame_odometry import FrameOdometry
    from sensor.stereo_camera import PairDeveloper, StereoCamera
    from sensor.vo.config import VOConfig

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
    "odometry_config",
    "pair_developer",
    "resolve_scenery_density",
    "rig_from_config",
    "rig_seed",
    "rig_settings",
    "rigs_from_config",
    "run_calibration",
    "stereo_camera",
    "world_for_scenario",
]


RIG_SEED_STREAM: Final = 0x5219
"""Mixed with the run's seed and a rig's index (≥ 1) into that rig's seed (:func:`rig_seed`)."""


def rig_seed(seed: int, rig_index: int) -> int:
    """The seed of rig ``rig_index``'s random draws: the run's ``seed`` for rig 0 (the one camera draws exactly what
    it always did), else drawn from ``(seed, RIG_SEED_STREAM, rig_index)``."""
    if rig_index == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), RIG_SEED_STREAM, int(rig_index)]).generate_state(1)[0])


def rig_settings(config: ScenarioConfig, rig_index: int = 0) -> RigConfig:
    """The resolved settings of rig ``rig_index`` (:func:`scenarios.camera_schema.rig_configs`).

    Raises
    ------
    InputError
        The run has no such rig.
    """
    rigs = rig_configs(config.camera, config.vehicle_params())
    if not 0 <= rig_index < len(rigs):
        raise InputError(f"rig_index = {rig_index}: the run has {len(rigs)} camera rig(s), 0 to {len(rigs) - 1}")
    return rigs[rig_index]


def rig_from_config(config: ScenarioConfig | Any, rig_index: int = 0) -> StereoRig:
    """The stereo rig of a scenario's camera rig ``rig_index`` (degrees at this edge, SI inside).

    Parameters
    ----------
    config : ScenarioConfig or CameraConfig
        A scenario configuration (its rig ``rig_index``) or a camera section or rig itself; a configuration
        without one gives the default rig (de Saxe & Cebon 2018, §3.1).
    rig_index : int
        The rig of a scenario configuration (:func:`rig_settings`).
    """
    scenario = isinstance(config, ScenarioConfig)
    camera = rig_settings(config, rig_index) if scenario else getattr(config, "camera", config)
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
        unit=getattr(camera, "unit", 1),
        supersample=getattr(camera, "supersample", 1),
    )


def rigs_from_config(config: ScenarioConfig) -> tuple[StereoRig, ...]:
    """Every stereo rig of the run, in the order of its rigs (:func:`rig_from_config`)."""
    count = len(rig_configs(config.camera, config.vehicle_params()))
    return tuple(rig_from_config(config, index) for index in range(count))


def resolve_scenery_density(config: ScenarioConfig, override: float | None = None) -> float:
    """The scenery density to render: ``override`` if given, else the scenario's ``camera.scenery_density`` (1.0)."""
    if override is not None:
        return float(override)
    return float(getattr(getattr(config, "camera", None), "scenery_density", 1.0))


def world_for_scenario(
    setup_or_config: ScenarioSetup | ScenarioConfig,
    scenery_density: float | None = None,
    seed: int | None = None,
    terrain: Terrain | None = None,
    **world_settings: Any,
) -> World:
    """The procedural world around a scenario's reference path, built once per process for a road and settings (the
    last :data:`WORLDS_KEPT` kept, :func:`_world_key`; a world on a terrain is built every time).

    Parameters
    ----------
    setup_or_config : ScenarioSetup or ScenarioConfig
        A built scenario (its ``path`` and ``config.seed`` are used) or a configuration (built here).
    scenery_density : float, optional
        Fraction of roadside objects, in [0, 1] (the paper's §3.2.3: 1.0, 0.5, 0.0); default: the
        scenario's ``camera.scenery_density`` (1.0 unless set).
    seed : int, optional
        Seed of the world (default: the scenario's ``seed``).
    terrain : Terrain, optional
        The ground to drape the world on (:func:`sensor.world.build_world`); ``None``: the level road.
    **world_settings
        Other :class:`sensor.world.WorldConfig` fields (``road_width``, ``apron_width``,
        ``kind="airfield"`` for the Bourn-like airfield of the paper's §4, ``ground_detail``, …).
    """
    setup = setup_or_config if isinstance(setup_or_config, ScenarioSetup) else build_scenario(setup_or_config)
    seed = setup.config.seed if seed is None else seed
    density = resolve_scenery_density(setup.config, scenery_density)
    settings = {"scenery_density": density, "seed": int(seed), **world_settings}
    key = _world_key(setup.path, settings) if terrain is None else None
    if key is None:  # a world on a terrain, or a setting without an exact text: built every time
        return build_world(setup.path, terrain=terrain, **settings)
    world = _WORLDS.pop(key, None)
    if world is None:
        world = build_world(setup.path, terrain=None, **settings)
    _WORLDS[key] = world  # the most recently used last
    while len(_WORLDS) > WORLDS_KEPT:
        _WORLDS.pop(next(iter(_WORLDS)))
    return world


WORLDS_KEPT: Final = 4
"""Worlds :func:`world_for_scenario` keeps per process (the most recently used), by road and settings."""

_WORLDS: dict[tuple, World] = {}


def _world_key(path: Any, settings: dict[str, Any]) -> tuple | None:
    """The key of a level world: a digest of the road path's geometry (its centre line, loop centres and curvature)
    and the exact settings; ``None`` when a setting is not a plain number, string, flag or tuple of them.

    A world is a function of its road and settings (:func:`sensor.world.build_world`: same inputs, identical world)
    and no caller modifies one once built (a lit world or a world with a marker is a new world), so one build serves
    every camera of the process that asks for the same road and settings.
    """
    plain = (bool, int, float, str, type(None))
    for value in settings.values():
        if not (isinstance(value, plain) or (isinstance(value, tuple) and all(isinstance(v, plain) for v in value))):
            return None
    digest = hashlib.sha256()
    for name in ("x", "y", "heading", "centres", "curvature"):
        value = getattr(path, name, None)
        digest.update(name.encode() + (b"-" if value is None else np.ascontiguousarray(value, float).tobytes()))
    return (digest.hexdigest(), tuple(sorted((k, type(v).__name__, repr(v)) for k, v in settings.items())))


def lenses(config: ScenarioConfig, rig_index: int = 0) -> tuple[Lens, Lens]:
    """The left and right lenses of a rig (:meth:`~scenarios.camera_schema.StereoRigConfig.lens_pair`)."""
    return rig_settings(config, rig_index).lens_pair()


def calibration_target_rig(rig: StereoRig, config: ScenarioConfig, rig_index: int = 0) -> StereoRig:
    """The rig as it was when calibrated: the right camera rotated by its ``calibration.misalignment_deg``."""
    misalignment = rig_settings(config, rig_index).calibration.misalignment_deg
    return rig.replace(misalignment=Misalignment.from_degrees(*misalignment))


def run_calibration(
    rig: StereoRig, config: ScenarioConfig, rig_index: int = 0, *, disk_cache: bool = False
) -> CalibrationResult:
    """Calibrate the rig as configured (its ``calibration``; seeded by the rig's seed, :func:`rig_seed`);
    ``disk_cache``: read from or kept in the disk cache of calibrations (:mod:`.calibration_cache`, the same result
    to the bit)."""
    cal = rig_settings(config, rig_index).calibration
    left, right = lenses(config, rig_index)
    return (cached_calibrate_rig if disk_cache else calibrate_rig)(
        calibration_target_rig(rig, config, rig_index),
        left,
        right,
        views=cal.views,
        target=(cal.target_cols, cal.target_rows),
        square_size=cal.square_size,
        corner_noise_px=cal.corner_noise_px,
        seed=rig_seed(config.seed, rig_index),
        stereo_refinement=cal.stereo_refinement,
    )


@functools.lru_cache(maxsize=4)
def _calibration_cached(config_json: str, rig_index: int) -> CalibrationResult:
    config = ScenarioConfig.model_validate(json.loads(config_json))
    return run_calibration(rig_from_config(config, rig_index), config, rig_index, disk_cache=True)


def calibration_for(rig: StereoRig, config: ScenarioConfig, rig_index: int = 0) -> CalibrationResult | None:
    """The calibration the odometry of rig ``rig_index`` uses (``None``: ideal). Estimated once per machine for the
    same rig, settings and code (the disk cache of :mod:`.calibration_cache`) and kept once per process, configuration
    and rig."""
    cal = rig_settings(config, rig_index).calibration
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
    return _calibration_cached(json.dumps(config.model_dump(mode="json"), sort_keys=True), rig_index)


def lighting_from_config(config: ScenarioConfig, rig_index: int = 0) -> Lighting | None:
    """The renderer's lighting (``None``: the flat lighting of the ideal study) from a rig's ``lighting``."""
    light = rig_settings(config, rig_index).lighting  # the schema's section is the sensor's Lighting
    return light if light.sun else None


def mount_flex(config: ScenarioConfig, rig_index: int = 0) -> MountFlex:
    """The right camera's mount flex settings of a rig (its ``flex``)."""
    return rig_settings(config, rig_index).flex  # the schema's section is the sensor's MountFlex


def flex_schedule(setup: ScenarioSetup, rig_index: int = 0) -> FlexSchedule:
    """The right camera's flex frame by frame: the rig's ``flex``, twisted by its own unit's lateral acceleration at
    the rig's ``station``, vibration seeded by ``(rig seed, 0xF1E8)``."""
    cfg = setup.config
    rng = np.random.default_rng([rig_seed(cfg.seed, rig_index), 0xF1E8])
    rig = rig_settings(cfg, rig_index)
    return FlexSchedule(
        mount_flex(cfg, rig_index), setup.params, rig.station, cfg.rates.frame_interval_s, rng, unit=rig.unit
    )


def _camera_settings(config: ScenarioConfig, rig_index: int = 0) -> dict[str, Any]:
    """The keyword arguments of :class:`~sensor.stereo_camera.PairDeveloper` (and the camera) of a rig."""
    rig = rig_from_config(config, rig_index)
    return {
        "lenses": lenses(config, rig_index),
        "calibration": calibration_for(rig, config, rig_index),
        "lighting": lighting_from_config(config, rig_index),
        "flex": mount_flex(config, rig_index),
        "right_correction_deg": tuple(rig_settings(config, rig_index).right_correction_deg),
        "seed": rig_seed(config.seed, rig_index),
        "frame_interval_s": 1.0 / config.rates.camera_hz,
    }


CONFIGURED: Final = "configured"
"""``lighting`` of :func:`stereo_camera`: the configuration's (flat for an ideal camera)."""


def _ideal_developer(
    config: ScenarioConfig, rig: StereoRig, lighting: Lighting | None, rig_index: int = 0
) -> PairDeveloper:
    """An ideal pinhole rig's development: no lens, ideal calibration, no mount flex, no right-image correction."""
    from sensor.stereo_camera import PairDeveloper

    seed = rig_seed(config.seed, rig_index)
    return PairDeveloper(rig, lighting=lighting, seed=seed, frame_interval_s=1.0 / config.rates.camera_hz)


def camera_tag(setup: ScenarioSetup, **settings: Any) -> str:
    """A name for the frames of the camera :func:`stereo_camera` builds for ``setup`` with ``settings``: a hash of the
    configuration's camera section (without its odometry's :data:`~scenarios.camera_schema.ODOMETRY_ONLY` fields, which
    do not change the images), seed and camera rate, the reference path, the vehicle, the settings and the
    renderer's :data:`~.frame_cache.FRAME_REVISION`."""
    from .frame_cache import FRAME_REVISION

    cfg = setup.config
    described = {
        "frame_revision": FRAME_REVISION,
        "camera": cfg.camera.model_dump(mode="json", exclude=set(ODOMETRY_ONLY)),
        "seed": cfg.seed,
        "camera_hz": cfg.rates.camera_hz,
        "vehicle": repr(setup.params),
        "settings": {k: repr(v) for k, v in sorted(settings.items())},
    }
    terrain = settings.get("terrain")
    described["settings"].pop("terrain", None)  # named below by its section and its heights
    if settings.get("rig_index", 0) == 0:
        described["settings"].pop("rig_index", None)  # the first rig's frames are named as the one camera's were
    if terrain is not None:  # the section, and the heights themselves (a file's content, seeded potholes)
        described["terrain"] = cfg.terrain.model_dump(mode="json", exclude={"look"})  # the world names it
    digest = hashlib.sha256(json.dumps(described, sort_keys=True).encode())
    digest.update(np.ascontiguousarray(setup.path.points, dtype=np.float64).tobytes())
    if terrain is not None:
        points = np.asarray(setup.path.points, dtype=float)
        for offset in (-6.0, -2.0, 0.0, 2.0, 6.0):
            digest.update(np.ascontiguousarray(terrain.height(points + offset), dtype=np.float64).tobytes())
    return digest.hexdigest()[:16]


def stereo_camera(
    setup: ScenarioSetup,
    *,
    ideal: bool = False,
    rig: StereoRig | None = None,
    lighting: Lighting | str | None = CONFIGURED,
    scenery_density: float | None = None,
    world: World | None = None,
    antialias: bool | None = None,
    frame_cache: Path | None = None,
    rig_index: int = 0,
    terrain: Terrain | None = None,
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
    antialias : bool, optional
        Render with 4× multisampling (default: ``camera.antialias``).
    frame_cache : Path, optional
        Keep the developed frames in this directory and take them back on a later run
        (:class:`.frame_cache.FrameCache`, :meth:`sensor.stereo_camera.StereoCamera.pair`).
    rig_index : int
        The rig (:func:`rig_settings`; 0: the first).
    terrain : Terrain, optional
        The ground the world is draped on and the combination stands on (docs/terrain_camera.md); ``None``: the
        level road. Only when the world is built here (``world`` not given: a given world carries its own).

    Raises
    ------
    InputError
        ``rig`` or ``lighting`` given for the run's camera (they are the configuration's).
    """
    from sensor.stereo_camera import StereoCamera  # the renderer: OpenGL only where frames are rendered

    from .frame_cache import FrameCache

    cfg = setup.config
    if antialias is None:
        antialias = cfg.camera.antialias
    if ideal:
        light = None if isinstance(lighting, str) else lighting
        chosen = rig if rig is not None else rig_from_config(cfg, rig_index)
        developer = _ideal_developer(cfg, chosen, light, rig_index)
    else:
        if rig is not None or not isinstance(lighting, str):
            raise InputError("the run's camera has the configured rig and lighting; pass ideal=True to change them")
        developer = pair_developer(cfg, rig_index)
    if world is None:
        world = world_for_scenario(
            setup, scenery_density, kind=cfg.camera.world, surface=cfg.terrain.look, terrain=terrain
        )
    elif terrain is not None:
        raise InputError("terrain: a given world carries its own terrain (build_world(..., terrain=...))")
    store = None
    if frame_cache is not None:
        tag = camera_tag(
            setup,
            ideal=ideal,
            rig=developer.rig,
            lighting=developer.lighting,
            world=world.config,
            antialias=antialias,
            rig_index=rig_index,
            **({} if world.terrain is None else {"terrain": world.terrain}),
        )
        store = FrameCache(frame_cache, tag)
    return StereoCamera(developer, world, setup.params, antialias=antialias, frame_store=store)


def pair_developer(config: ScenarioConfig, rig_index: int = 0) -> PairDeveloper:
    """A rig's development alone, for a process that gets the raw pairs from render workers."""
    from sensor.stereo_camera import PairDeveloper

    return PairDeveloper(rig_from_config(config, rig_index), **_camera_settings(config, rig_index))


def odometry_config(optics: FieldOptics, rig: StereoRigConfig) -> VOConfig:
    """The odometry's settings of a rig: the camera model and stereo search of the images ``optics`` gives
    (:meth:`~sensor.field_optics.FieldOptics.vo_config`) with the rig's ``vo_refinement``,
    ``vo_bucket_max_features``, ``vo_ransac_iters``, ``vo_covariance_model`` and ``vo_gradient_refinement``
    (validated by the schema with the odometry's own ranges and values)."""
    return optics.vo_config().model_copy(
        update={
            "refinement": rig.vo_refinement,
            "bucket_max_features": rig.vo_bucket_max_features,
            "ransac_iters": rig.vo_ransac_iters,
            "covariance_model": rig.vo_covariance_model,
            "gradient_refinement": rig.vo_gradient_refinement,
        }
    )


def frame_odometry(
    setup: ScenarioSetup, optics: FieldOptics, rig_index: int = 0, level_reference: str = "planar"
) -> FrameOdometry:
    """The per-frame estimator of rig ``rig_index`` on the images ``optics`` gives (the rig's ``self_calibration``
    and :func:`odometry_config`, rates, the rig's seed), estimating the off-tracking of the towed unit the rig is on;
    ``level_reference`` how VISO-OT finds the level on terrain (:mod:`sensor.level_reference`, default the level
    road)."""
    from sensor.frame_odometry import FrameOdometry

    cfg = setup.config
    rig = rig_settings(cfg, rig_index)
    self_cal = rig.self_calibration
    settings = self_cal if self_cal.enabled else None  # the schema's section is the sensor's settings
    offset = {"disparity_offset_settings": rig.disparity_offset} if rig.disparity_offset.enabled else {}
    unit = {"unit": rig.unit} if rig.unit != 1 else {}  # the first towed unit is the odometry's default
    return FrameOdometry(
        setup.params,
        odometry_config(optics, rig),
        optics.left_in_trailer(setup.params),
        cfg.rates.frame_interval_s,
        rig_seed(cfg.seed, rig_index),
        settings,
        **unit,
        **({} if level_reference == "planar" else {"level_reference": level_reference}),
        **offset,
    )
