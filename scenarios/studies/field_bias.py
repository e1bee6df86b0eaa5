"""The ``field-bias`` study: which part of the field conditions biases VISO-OT and by how much, under two builds of
the estimators.

The field-conditions set (:data:`~scenarios.studies.section4.FIELD_CONDITIONS`) is switched on one part at a time
and in pairs, on the three-turn roundabout (one turn in the default subset), dry, with the LST steered on the true
off-tracking so that every case drives the same path and the camera estimators run open loop beside it. Every case
runs under both builds of the estimators it compares:

* ``before`` — the odometry's matches refined to the pixel (``camera.vo_refinement`` 1, libviso2's default) and the
  fused filter without its bias states and kinematics: no state for the odometry's yaw error
  (``fusion.vo_yaw_bias`` 0, ``fusion.vo_yaw_bias_walk`` 0), the gyro bias unknown at the start
  (``fusion.initial_gyro_bias`` 0.01 rad/s, ``fusion.gyro_bias_walk`` 1e-4 rad/s/√s) and no zero-slip kinematics
  (``fusion.kinematics`` false);
* ``after`` — the defaults: sub-pixel refinement and the fused filter as built (:mod:`sensor.fusion`).

The online self-calibration of the right camera runs in both. Each row has the per-frame odometry error by axis
against the true kingpin motion (:func:`odometry_errors`: yaw per metre, lateral per metre, scale, yaw noise per
frame) and the raw and fused VISO-OT off-tracking errors (mean: the bias; RMS; the fused estimate's coverage).
docs/field_bias.md holds the measured table and what it says.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..loop.ends import RunStatus
from ..run.results import read_timeseries
from .cases import run_case
from .records import CaseSpec
from .section4 import FIELD_CONDITIONS, PAPER_SECTION4_MISALIGNMENT_DEG

STUDY = "field-bias"

SCENARIO = "roundabout-3"
"""The manoeuvre of every case: three left turns of the 50 m roundabout at 15 km/h."""

_FIELD = dict(FIELD_CONDITIONS)
_LENS = ("camera.lens", _FIELD["camera.lens"])
_ESTIMATED = ("camera.calibration", _FIELD["camera.calibration"])
_FLEX = _FIELD["camera.flex"]
_TWIST = ("camera.flex", {"twist_deg_per_mps2": _FLEX["twist_deg_per_mps2"]})
_VIBRATION = (
    "camera.flex",
    {"vibration_rms_deg": _FLEX["vibration_rms_deg"], "vibration_bandwidth_hz": _FLEX["vibration_bandwidth_hz"]},
)
_SUN = ("camera.lighting", _FIELD["camera.lighting"])
_AIRFIELD = ("camera.world", _FIELD["camera.world"])
_ROTATED = ("camera.right_misalignment_deg", list(PAPER_SECTION4_MISALIGNMENT_DEG))

PARTS: dict[str, tuple[tuple[str, Any], ...]] = {
    "ideal": (),
    "lens, true calibration": (_LENS,),
    "estimated calibration, pinhole": (_ESTIMATED,),
    "lens, estimated calibration": (_LENS, _ESTIMATED),
    "paper's rotation": (_ROTATED,),
    "twist": (_TWIST,),
    "vibration": (_VIBRATION,),
    "sun and exposure": (_SUN,),
    "airfield": (_AIRFIELD,),
    "lens, estimated calibration + airfield": (_LENS, _ESTIMATED, _AIRFIELD),
    "airfield + sun and exposure": (_AIRFIELD, _SUN),
    "twist + vibration": (("camera.flex", _FLEX),),
    "lens, estimated calibration + twist": (_LENS, _ESTIMATED, _TWIST),
    "all": FIELD_CONDITIONS,
    "all + paper's rotation": (*FIELD_CONDITIONS, _ROTATED),
}
"""The parts of the field conditions, alone and in pairs, as overrides (the settings of
:data:`~scenarios.studies.section4.FIELD_CONDITIONS`; the right camera's rotation after calibration is that of
:data:`~scenarios.studies.section4.PAPER_SECTION4_MISALIGNMENT_DEG`)."""

DEFAULT_PARTS = ("ideal", "lens, estimated calibration", "airfield", "all")
"""The parts of the default subset."""

VARIANTS: dict[str, tuple[tuple[str, Any], ...]] = {
    "before": (
        ("camera.vo_refinement", 1),
        ("fusion.vo_yaw_bias", 0.0),
        ("fusion.vo_yaw_bias_walk", 0.0),
        ("fusion.initial_gyro_bias", 0.01),
        ("fusion.gyro_bias_walk", 1e-4),
        ("fusion.kinematics", False),
    ),
    "after": (),
}
"""The two builds of the estimators compared: pixel-refined odometry and the fused filter without its bias states and
kinematics (``before``), and the defaults (``after``) (module notes)."""

COMMON: tuple[tuple[str, Any], ...] = (
    ("vehicle", "lst"),
    ("surface.preset", "dry"),
    ("feedback", "truth"),
    ("estimators.zero_slip", True),
    ("estimators.viso_ot", True),
    ("estimators.viso_ot_fused", True),
    ("camera.self_calibration.enabled", True),
)
"""Every case: the LST on a dry road, steered on the truth, with every estimator running."""

SHORT: tuple[tuple[str, Any], ...] = (("path.turns", 1.0), ("path.exit_length", 10.0))
"""The default subset's shortening: one turn and a 10 m exit."""

ROW_KEYS = (
    "vo_yaw_error_mrad_per_m",
    "vo_lateral_error_mm_per_m",
    "vo_scale_error_percent",
    "vo_yaw_noise_mrad",
    "viso_ot_mean_error_m",
    "viso_ot_rms_error_m",
    "fused_mean_error_m",
    "fused_rms_error_m",
    "fused_within_2sigma",
    "fused_mean_std_m",
)
"""The columns :func:`run_field_bias_case` adds to :func:`~scenarios.studies.cases.run_case`'s row."""


def field_bias_cases(full: bool = False) -> list[CaseSpec]:
    """Cases of the field-bias study: every part of :data:`PARTS` (:data:`DEFAULT_PARTS` unless ``full``) ×
    :data:`VARIANTS`, labelled ``part`` and ``variant``; the default subset drives one turn (:data:`SHORT`)."""
    parts = PARTS if full else {name: PARTS[name] for name in DEFAULT_PARTS}
    cases = []
    for part, overrides in parts.items():
        for variant, build in VARIANTS.items():
            all_overrides = (*COMMON, *overrides, *build, *(() if full else SHORT))
            cases.append(CaseSpec(STUDY, SCENARIO, all_overrides, (("part", part), ("variant", variant))))
    return cases


def odometry_errors(series: dict[str, np.ndarray]) -> dict[str, float]:
    """The odometry's error per camera frame against the true motion of the kingpin, by axis.

    For each pair of consecutive frames whose motion was accepted (``vo_valid``), the true trailer yaw change and
    the kingpin's displacement in the trailer's axes at the first frame (from ``psi2``, ``kingpin_x``,
    ``kingpin_y``) against the odometry's (``vo_step_yaw_rate_rad_s``, ``vo_step_lateral_m_s``,
    ``vo_step_speed_m_s`` times the frame interval; :meth:`sensor.viso_ot.VisoOtEstimator.step_measures`).

    Parameters
    ----------
    series
        A run's time series by column (:func:`~scenarios.run.results.read_timeseries`).

    Returns
    -------
    dict
        ``vo_yaw_error_mrad_per_m`` (the summed yaw error over the distance [mrad/m], left positive),
        ``vo_lateral_error_mm_per_m`` (the summed lateral error over the distance [mm/m]),
        ``vo_scale_error_percent`` (distance measured over distance travelled, less one [%]),
        ``vo_yaw_noise_mrad`` (the per-frame yaw error's standard deviation [mrad]); NaN without two valid frames.
    """
    nan = dict.fromkeys(("vo_yaw_error_mrad_per_m", "vo_lateral_error_mm_per_m", "vo_scale_error_percent"), math.nan)
    nan["vo_yaw_noise_mrad"] = math.nan
    needed = ("camera_frame", "vo_valid", "psi2", "kingpin_x", "kingpin_y", "time", "vo_step_yaw_rate_rad_s")
    if any(series.get(name) is None for name in needed):
        return nan
    frames = np.flatnonzero(np.asarray(series["camera_frame"], dtype=float) > 0.5)
    if len(frames) < 3:
        return nan
    k0, k1 = frames[:-1], frames[1:]
    t, psi = np.asarray(series["time"]), np.asarray(series["psi2"])
    kx, ky = np.asarray(series["kingpin_x"]), np.asarray(series["kingpin_y"])
    dt = t[k1] - t[k0]
    true_yaw = np.remainder(psi[k1] - psi[k0] + math.pi, 2.0 * math.pi) - math.pi
    c, s = np.cos(psi[k0]), np.sin(psi[k0])
    ex, ey = kx[k1] - kx[k0], ky[k1] - ky[k0]
    true_forward, true_lateral = c * ex + s * ey, -s * ex + c * ey
    distance = np.hypot(true_forward, true_lateral)

    def measured(name: str) -> np.ndarray:
        column = series.get(name)
        return np.full(len(k1), math.nan) if column is None else np.asarray(column, dtype=float)[k1] * dt

    yaw, lateral, travelled = (
        measured("vo_step_yaw_rate_rad_s"),
        measured("vo_step_lateral_m_s"),
        measured("vo_step_speed_m_s"),
    )
    ok = (np.asarray(series["vo_valid"], dtype=float)[k1] > 0.5) & np.isfinite(yaw) & (distance > 0.0)
    if ok.sum() < 2:
        return nan
    total = float(distance[ok].sum())
    yaw_error = yaw[ok] - true_yaw[ok]
    lateral_ok = ok & np.isfinite(lateral)
    return {
        "vo_yaw_error_mrad_per_m": 1e3 * float(yaw_error.sum()) / total,
        "vo_lateral_error_mm_per_m": (
            1e3 * float((lateral - true_lateral)[lateral_ok].sum()) / float(distance[lateral_ok].sum())
            if lateral_ok.any()
            else math.nan
        ),
        "vo_scale_error_percent": 100.0 * (float(np.nansum(travelled[ok])) / total - 1.0),
        "vo_yaw_noise_mrad": 1e3 * float(np.std(yaw_error)),
    }


def run_field_bias_case(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """:func:`~scenarios.studies.cases.run_case` plus :data:`ROW_KEYS`: the odometry's errors by axis
    (:func:`odometry_errors`) and the raw and fused VISO-OT errors from ``metrics.json`` (NaN where absent)."""
    row = run_case(spec, out_dir)
    row.update(dict.fromkeys(ROW_KEYS, math.nan))
    if row.get("status") == RunStatus.INTERRUPTED:
        return row
    run_dir = out_dir / spec.name
    row.update(odometry_errors(read_timeseries(run_dir)))
    metrics_file = run_dir / "metrics.json"
    metrics = json.loads(metrics_file.read_text()) if metrics_file.is_file() else {}
    estimators = (metrics.get("offtracking") or {}).get("estimators") or {}
    for name, prefix in (("viso_ot", "viso_ot"), ("viso_ot_fused", "fused")):
        errors = estimators.get(name) or {}
        row[f"{prefix}_mean_error_m"] = errors.get("mean_error", math.nan)
        row[f"{prefix}_rms_error_m"] = errors.get("rms_error", math.nan)
    fused = estimators.get("viso_ot_fused") or {}
    row["fused_within_2sigma"] = fused.get("within_2sigma", math.nan)
    row["fused_mean_std_m"] = fused.get("mean_std", math.nan)
    return row


def decomposition_table(table: pd.DataFrame) -> pd.DataFrame:
    """One row per part with its ``before`` and ``after`` figures side by side (``{column}_{variant}``).

    Parameters
    ----------
    table
        The study's case rows (``part``, ``variant`` and :data:`ROW_KEYS`).

    Returns
    -------
    pandas.DataFrame
        ``part``, then each of :data:`ROW_KEYS` for ``before`` and ``after``, in the table's order of parts.
    """
    rows = []
    for part, group in table.groupby("part", sort=False):
        row: dict[str, Any] = {"part": part}
        for variant in VARIANTS:
            case = group[group["variant"] == variant]
            for key in ROW_KEYS:
                value = case.iloc[0].get(key, math.nan) if len(case) else math.nan
                row[f"{key}_{variant}"] = float(value) if value is not None else math.nan
        rows.append(row)
    return pd.DataFrame(rows)
