"""The report of a recorded run: ``recording.yaml``, ``metrics.json`` and the plots, written and rebuilt.

A recorded run's directory (:mod:`.estimate`) has ``recording.yaml`` — what ``offtrack estimate`` was given, with the
rig file's fields — where a simulated run has ``config.yaml``; :func:`is_recorded_run` tells them apart, so that
``offtrack report`` and ``offtrack animate`` take either. :func:`write_recorded_report` computes ``metrics.json``
with the simulated runs' own :func:`scenarios.run.metrics.compute_metrics` (the same errors against the truth, the
same camera frame statistics and verdict), adds what only a recording has (``recording``: frames missing, refused
and why, gaps; ``vo_rpe``: the odometry's relative pose error against reference poses; ``motion``: the kingpin's
travel forwards and backwards and its distance against the wheel speed's, whose implausible values are flags of the
verdict, :func:`.plausibility.motion_flags`) and draws
``offtracking.png`` (:func:`scenarios.run.plots.plot_offtracking`) and ``plan_view.png`` (:mod:`.plots`).
:func:`rebuild_recorded_report` does it again from the directory alone.
"""

from __future__ import annotations

import datetime as dt
import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams

from ..config import vehicle_name
from ..loop.ends import RunStatus
from ..run.files import jsonable, write_atomic
from ..run.metrics import after_warmup, compute_metrics, estimator_names
from ..run.report import INCOMPLETE_MESSAGE
from ..run.results import plot_files, read_metrics, read_timeseries, write_metrics
from ..yaml_input import load_yaml
from .plausibility import motion_flags
from .rig import rig_from_fields

__all__ = [
    "RECORDING_FILE",
    "is_recorded_run",
    "read_recording_file",
    "rebuild_recorded_report",
    "recorded_run_title",
    "write_recorded_report",
    "write_recording_file",
]

RECORDING_FILE = "recording.yaml"
"""What ``offtrack estimate`` was given (a recorded run's ``config.yaml``)."""


def is_recorded_run(run_dir: Path) -> bool:
    """Whether ``run_dir`` is the directory of ``offtrack estimate`` (it holds ``recording.yaml``)."""
    return (Path(run_dir) / RECORDING_FILE).is_file()


def write_recording_file(run_dir: Path, record: dict[str, Any]) -> None:
    """``recording.yaml``: the inputs' record (:attr:`.inputs.EstimateInputs.record`)."""
    write_atomic(Path(run_dir) / RECORDING_FILE, yaml.safe_dump(jsonable(record), sort_keys=False, allow_unicode=True))


def read_recording_file(run_dir: Path) -> dict[str, Any]:
    """The inputs' record of a recorded run (InputError if there is none or it is not a mapping)."""
    path = Path(run_dir) / RECORDING_FILE
    if not path.is_file():
        raise InputError(f"{run_dir} is not a recorded run: it has no {RECORDING_FILE}")
    data = load_yaml(path.read_bytes(), str(path))
    if not isinstance(data, dict) or not isinstance(data.get("rig_file"), dict):
        raise InputError(f"{path} does not hold a recording's inputs (no rig_file)")
    return data


def recorded_run_title(record: dict[str, Any]) -> str:
    """The one-line description heading a recorded run's figures."""
    rig = record.get("rig_file", {})
    name = Path(str(record.get("recording", "recording"))).name
    return (
        f"recording {name}, {vehicle_name(rig.get('vehicle', 'reference'))}, camera ψ_c2v {rig.get('psi_c2v_deg')}°, "
        f"lever arm {rig.get('lever_arm_m')} m"
    )


def _params(record: dict[str, Any]) -> VehicleParams:
    return rig_from_fields(record["rig_file"], RECORDING_FILE).params


def _vo_rpe(columns: dict[str, np.ndarray]) -> dict[str, Any] | None:
    """Mean, RMS and largest relative pose error per frame against reference poses (None without them)."""
    t = columns.get("vo_rpe_translation_m")
    r = columns.get("vo_rpe_rotation_rad")
    if t is None or r is None:
        return None
    ok = np.isfinite(t) & np.isfinite(r)
    if not ok.any():
        return {"frames": 0}
    return {
        "frames": int(ok.sum()),
        "translation_mean_m": float(np.mean(t[ok])),
        "translation_rms_m": float(np.sqrt(np.mean(t[ok] ** 2))),
        "translation_max_m": float(np.max(t[ok])),
        "rotation_mean_deg": math.degrees(float(np.mean(r[ok]))),
        "rotation_rms_deg": math.degrees(float(np.sqrt(np.mean(r[ok] ** 2)))),
        "rotation_max_deg": math.degrees(float(np.max(r[ok]))),
    }


def write_recorded_report(
    run_dir: Path, record: dict[str, Any], run: dict[str, Any], *, plots: bool = True, plot_format: str = "png"
) -> dict[str, Any]:
    """Compute a recorded run's metrics from its time series, write ``metrics.json`` and (``plots``) the plots.

    Parameters
    ----------
    run_dir : Path
        The run directory (with its ``timeseries.parquet``).
    record : dict
        The inputs' record (``recording.yaml``).
    run : dict
        How the run went: ``status``, ``message``, ``wall_time_s``, ``recording`` (and anything else to record).
    plots : bool
        Draw ``offtracking.png`` and ``plan_view.png`` (with two rows or more).
    plot_format : str
        Their image format: ``png`` (default), ``svg`` or ``pdf``.

    Returns
    -------
    dict
        The content of ``metrics.json``.
    """
    params = _params(record)
    columns = read_timeseries(run_dir)
    time = columns.get("time", np.zeros(0))
    names = estimator_names(columns)
    name = f"recording {Path(str(record.get('recording', ''))).name}"
    metrics = compute_metrics(name, "none", params, columns, names, None, (0.0, 0.0))
    metrics.update({"stop_time": None, "stop_signal": None})
    metrics.update({"rows": len(time), "simulated_s": float(time[-1]) if len(time) else 0.0, **run})
    metrics.update(
        {"vehicle": vehicle_name(record["rig_file"].get("vehicle", "reference")), "seed": record.get("seed")}
    )
    rpe = _vo_rpe(columns)
    if rpe is not None:
        metrics["vo_rpe"] = rpe
    motion, flags = motion_flags(columns)
    if motion:
        metrics["motion"] = motion
    if flags:  # the odometry's scale or direction is implausible: the run did not hold what it was asked
        verdict = metrics.setdefault("verdict", {"held": True, "flags": []})
        verdict["flags"] = [*verdict.get("flags", []), *flags]
        verdict["held"] = False
    write_metrics(run_dir, metrics)
    if plots and len(time) > 1:
        from ..run.plots import plot_offtracking
        from .plots import plot_recorded_plan_view

        title = recorded_run_title(record)
        plan_file, offtracking_file = plot_files(plot_format)
        plot_recorded_plan_view(run_dir / plan_file, params, columns, title)
        follow_point = rig_from_fields(record["rig_file"], RECORDING_FILE).follow_point_offset
        settled = after_warmup(columns, follow_point) if "kingpin_x" in columns else None
        plot_offtracking(run_dir / offtracking_file, columns, names, title, settled=settled)
    return metrics


def rebuild_recorded_report(run_dir: Path, plots: bool = True, *, plot_format: str = "png") -> dict[str, Any]:
    """``offtrack report`` on a recorded run: ``metrics.json`` and the plots (in ``plot_format``) again from the
    directory alone.

    The status, message, wall time and the recording's summary the run wrote are kept; a run killed before it wrote
    them is ``incomplete``.
    """
    run_dir = Path(run_dir)
    record = read_recording_file(run_dir)
    recorded = read_metrics(run_dir) or {}
    if recorded.get("status") in (None, RunStatus.RUNNING):
        run: dict[str, Any] = {"status": RunStatus.INCOMPLETE, "message": INCOMPLETE_MESSAGE}
    else:
        run = {key: recorded.get(key) for key in ("status", "message", "wall_time_s", "recording")}
    run["rebuilt_at"] = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    return write_recorded_report(run_dir, record, run, plots=plots, plot_format=plot_format)


def recording_lines(metrics: dict[str, Any], limit: int = 10) -> list[str]:
    """What ``offtrack estimate`` prints after the run's summary: the frames, those missing and refused with their
    reasons (at most ``limit`` of each listed), the gaps in the times, and the odometry's error per frame."""
    rec = metrics.get("recording") or {}
    if not rec:
        return []
    lines = [
        f"frames: {rec.get('frames')} in the recording over {rec.get('time_span_s', 0.0):.2f} s "
        f"(median interval {1e3 * (rec.get('median_interval_s') or math.nan):.1f} ms), {rec.get('processed')} "
        f"with images, {rec['missing']['count']} missing, {rec['refused']['count']} refused"
    ]
    for kind in ("missing", "refused"):
        frames = rec[kind]["frames"]
        if frames:
            shown = "; ".join(f"{k} at {t:.3f} s: {reason}" for k, t, reason in frames[:limit])
            more = f"; … {len(frames) - limit} more in metrics.json" if len(frames) > limit else ""
            lines.append(f"{kind}: {shown}{more}")
    gaps = rec.get("gaps") or []
    if gaps:
        shown = "; ".join(f"before frame {g['frame']}: {1e3 * g['interval_s']:.0f} ms" for g in gaps[:limit])
        lines.append(f"gaps in the times (frames dropped before): {shown}")
    rpe = metrics.get("vo_rpe")
    if rpe and rpe.get("frames"):
        lines.append(
            f"odometry against the reference, per frame: {1e3 * rpe['translation_mean_m']:.2f} mm, "
            f"{1e3 * rpe['rotation_mean_deg']:.2f} mdeg mean over {rpe['frames']} frames"
        )
    return lines
