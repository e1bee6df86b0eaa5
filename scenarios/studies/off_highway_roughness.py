"""The ``off-highway-roughness`` study: VISO-OT's error against the road's roughness, in the level frame and with
the paper's planar eqs — de Saxe & Cebon 2018's "does not assume a planar road" quantified.

Each case drives ``forest-road`` (:data:`SCENARIO`) model only, unsteered (open loop), with the terrain's
undulations, or its potholes, set by the case; the other terrain features stay the scenario's (its grade, crossfall
and ruts). From the run's time series an **ideal camera** is taken: the left camera's pose on the terrain at every
camera frame (``rates.camera_hz``) from the planar model's pose, each unit's kinematic pitch and roll and the rig's
mount (``StereoRig.camera_in_world``, docs/terrain_camera.md §1–2), and its exact motion between frames. VISO-OT
(:class:`sensor.viso_ot.VisoOtEstimator`) is fed those motions four ways (:data:`ESTIMATES`):

* ``level`` — on the level road: the same horizontal poses with no terrain, the reference the others are held to;
* ``true_tilt`` — on the terrain, in the level frame with the unit's true tilt;
* ``accelerometer`` — on the terrain, in the level frame of the run's assumed trailer accelerometer
  (:func:`sensor.level_reference.trailer_accelerometer`, the loop's default on a terrain);
* ``planar`` — on the terrain, the paper's planar eqs (3)–(7) on the 3-D motion.

The row gives each estimate's RMS and largest error against the true off-tracking and, for the three on the terrain,
against ``level`` (what the terrain alone costs). No image is rendered: the odometry's own error on such ground is
the field and rendered runs' (``off-highway``; docs/terrain_camera.md §4).

The default subset: undulation amplitudes :data:`DEFAULT_AMPLITUDES_M` at :data:`WAVELENGTH_M`, without potholes,
:data:`SHORT_DURATION_S` long. ``full``: :data:`DEFAULT_AMPLITUDES_M` at each of :data:`FULL_WAVELENGTHS_M`, and
:data:`FULL_POTHOLES_PER_100M` without undulations, the complete scenario.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sensor.level_reference import trailer_accelerometer
from sensor.viso_ot import VisoOtEstimator
from vehicle_model.geometry import CombinationPose
from vehicle_model.terrain_pose import unit_attitude

from ..camera.build import rig_from_config
from ..config import load_scenario
from ..loop.ends import RunStatus
from ..run.metrics import estimator_errors
from ..setup.build import build_scenario
from .cases import run_case
from .records import CaseSpec
from .workers import worker_models

STUDY = "off-highway-roughness"

SCENARIO = "forest-road"
"""The scenario of every case: a bend between straights, grade and crossfall (docs/terrain.md, "Catalogue")."""

WAVELENGTH_M = 12.0
"""Undulation wavelength of the default subset [m]: a few trailer axle spreads, where the tilt changes most."""

DEFAULT_AMPLITUDES_M = (0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3)
"""Undulation amplitudes of the default subset and of the full grid [m]."""

FULL_WAVELENGTHS_M = (6.0, 12.0, 25.0)
"""Undulation wavelengths of the full grid [m]."""

FULL_POTHOLES_PER_100M = (5.0, 10.0, 20.0)
"""Pothole densities of the full grid without undulations [per 100 m] (10 cm deep, seeded)."""

POTHOLE_DEPTH_M = 0.10
"""Depth of the full grid's potholes [m]."""

SHORT_DURATION_S = 30.0
"""Simulated time of the default subset's cases [s]: the approach and most of the bend."""

ESTIMATES = ("level", "true_tilt", "accelerometer", "planar")
"""The ways VISO-OT is fed the ideal camera's motions (module notes)."""

ROUGHNESS_COLUMNS = (
    "amplitude_m",
    "wavelength_m",
    "potholes_per_100m",
    "level_rms_error_m",
    "accelerometer_rms_error_m",
    "planar_rms_error_m",
    "accelerometer_vs_level_max_m",
    "planar_vs_level_max_m",
    "true_tilt_valid_fraction",
    "frames",
)
"""The study's terminal columns."""


def roughness_case(amplitude_m: float, wavelength_m: float, potholes_per_100m: float, full: bool) -> CaseSpec:
    """One case: the scenario unsteered with the given undulations and potholes (module notes)."""
    overrides: tuple[tuple[str, Any], ...] = (
        ("feedback", "none"),
        ("seed", 0),
        ("terrain.undulation_amplitude_m", float(amplitude_m)),
        ("terrain.undulation_wavelength_m", float(wavelength_m)),
        ("terrain.potholes_per_100m", float(potholes_per_100m)),
        ("terrain.pothole_depth_m", POTHOLE_DEPTH_M),
    )
    if not full:
        overrides += (("duration_s", SHORT_DURATION_S),)
    labels = (
        ("amplitude_m", float(amplitude_m)),
        ("wavelength_m", float(wavelength_m)),
        ("potholes_per_100m", float(potholes_per_100m)),
    )
    return CaseSpec(STUDY, SCENARIO, overrides, labels)


def roughness_cases(full: bool = False) -> list[CaseSpec]:
    """The cases: :data:`DEFAULT_AMPLITUDES_M` (7), or with ``full`` the amplitudes at every wavelength and the
    pothole densities (24)."""
    if not full:
        return [roughness_case(a, WAVELENGTH_M, 0.0, False) for a in DEFAULT_AMPLITUDES_M]
    waves = [roughness_case(a, w, 0.0, True) for w in FULL_WAVELENGTHS_M for a in DEFAULT_AMPLITUDES_M]
    return waves + [roughness_case(0.0, WAVELENGTH_M, n, True) for n in FULL_POTHOLES_PER_100M]


def frame_indices(time_s: np.ndarray, camera_hz: float) -> np.ndarray:
    """The ticks at which a camera running at ``camera_hz`` takes a frame: the first tick of every frame period."""
    period = np.floor(np.asarray(time_s, dtype=float) * camera_hz + 1e-9)
    return np.flatnonzero(np.r_[True, np.diff(period) > 0])


def ideal_camera_estimates(
    params: Any, rig: Any, poses: list[CombinationPose], terrain: Any, frame_interval: float, seed: int = 0
) -> dict[str, np.ndarray]:
    """VISO-OT's off-tracking at every frame after the first, fed the ideal camera's exact motions each way of
    :data:`ESTIMATES` (NaN where it has none).

    Parameters
    ----------
    params : VehicleParams
        The combination.
    rig : StereoRig
        The rig; its left camera on the first towed unit.
    poses : list of CombinationPose
        The combination's horizontal pose at every frame.
    terrain : Terrain
        The ground.
    frame_interval : float
        Time between frames [s].
    seed : int
        Seed of the accelerometer's noise.
    """
    mount = rig.camera_in_trailer("left", params)

    def motions(ground: Any) -> list[np.ndarray]:
        cams = [rig.camera_in_world(params, pose, "left", ground) for pose in poses]
        return [np.linalg.inv(a) @ b for a, b in itertools.pairwise(cams)]

    def run(estimator: VisoOtEstimator, steps: list[np.ndarray], tilts: list[Any] | None) -> np.ndarray:
        out = [estimator.update(m, None if tilts is None else tilts[k + 1]) for k, m in enumerate(steps)]
        return np.array([np.nan if e is None else float(e) for e in out])

    on_terrain = motions(terrain)
    truth = [(float(a.pitch), float(a.roll)) for a in (unit_attitude(params, p, terrain) for p in poses)]
    imu = trailer_accelerometer(seed)
    read = [imu.read(*t) for t in truth]

    def level_frame(tilts: list[Any]) -> VisoOtEstimator:
        return VisoOtEstimator(
            params, mount, frame_interval=frame_interval, level_reference="accelerometer", initial_tilt=tilts[0]
        )

    return {
        "level": run(VisoOtEstimator(params, mount, frame_interval=frame_interval), motions(None), None),
        "true_tilt": run(level_frame(truth), on_terrain, truth),
        "accelerometer": run(level_frame(read), on_terrain, read),
        "planar": run(VisoOtEstimator(params, mount, frame_interval=frame_interval), on_terrain, None),
    }


def estimate_columns(truth: np.ndarray, estimates: dict[str, np.ndarray]) -> dict[str, float]:
    """Each estimate's ``<name>_rms_error_m`` and ``<name>_max_abs_error_m`` against ``truth`` and the share of the
    truth's frames it gave a value on (``<name>_valid_fraction``: VISO-OT bridges a frame whose motion is beyond
    :class:`sensor.viso_ot.MotionBounds`), and for the terrain's
    ``<name>_vs_level_rms_m`` and ``<name>_vs_level_max_m`` against the level road's estimate [m] (NaN without a
    common value)."""
    row: dict[str, float] = {}
    level = estimates["level"]
    for name, values in estimates.items():
        errors = estimator_errors(truth, values)
        row[f"{name}_rms_error_m"] = errors["rms_error"]
        row[f"{name}_max_abs_error_m"] = errors["max_abs_error"]
        row[f"{name}_valid_fraction"] = errors["valid_fraction"]
        if name != "level":
            both = np.isfinite(values) & np.isfinite(level)
            diff = values[both] - level[both]
            row[f"{name}_vs_level_rms_m"] = float(np.sqrt(np.mean(diff**2))) if diff.size else float("nan")
            row[f"{name}_vs_level_max_m"] = float(np.max(np.abs(diff))) if diff.size else float("nan")
    return row


def run_roughness_case(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """:func:`~scenarios.studies.cases.run_case` (the unsteered run), plus the ideal camera's VISO-OT errors
    (:func:`ideal_camera_estimates`, :func:`estimate_columns`) and ``frames``, the number of camera frames."""
    row = run_case(spec, out_dir)
    if row.get("status") in (RunStatus.INTERRUPTED, RunStatus.FAILED):
        return row
    config = load_scenario(spec.scenario, dict(spec.overrides))
    params = config.vehicle_params()
    setup = build_scenario(config, model=worker_models().model(params))
    frame = pd.read_parquet(out_dir / spec.name / "timeseries.parquet")
    hz = float(config.rates.camera_hz)
    ticks = frame_indices(frame["time"].to_numpy(), hz)
    columns = {c: frame[c].to_numpy()[ticks] for c in ("X", "Y", "psi1", "gamma", "offtracking_truth")}
    poses = [
        CombinationPose(float(x), float(y), float(p), float(g))
        for x, y, p, g in zip(columns["X"], columns["Y"], columns["psi1"], columns["gamma"], strict=True)
    ]
    estimates = ideal_camera_estimates(params, rig_from_config(config), poses, setup.terrain, 1.0 / hz, config.seed)
    row.update(estimate_columns(columns["offtracking_truth"][1:], estimates))
    row["frames"] = len(poses)
    return row
