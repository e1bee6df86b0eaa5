"""Running one case of a sweep into its run directory and turning it into a table row; the model-only cases."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from ..config import load_scenario
from ..loop.ends import RunStatus
from ..run.metrics import estimator_errors, rms
from ..run.runner import run_scenario
from .records import CaseSpec
from .workers import worker_models


def run_case(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """Run one case into ``out_dir/<case name>/`` and return its table row.

    The vehicle model comes from this process's :func:`~scenarios.studies.workers.worker_models`, so the
    cases a process runs share each vehicle's casadi functions. A run stopped by Ctrl-C or SIGTERM returns
    only its labels, ``status`` ``interrupted`` and ``stop_signal``, which
    :func:`~scenarios.studies.workers.execute` turns back into the stop. A run that failed (a file it could not
    write, a render worker lost; perhaps before its first row) returns its labels, ``status`` ``failed``, its
    ``message`` and ``stop_time``, which :func:`~scenarios.studies.workers.execute` records as a failed case, run
    again on resume.
    """
    config = load_scenario(spec.scenario, dict(spec.overrides))
    run_dir = out_dir / spec.name
    run_dir.mkdir(parents=True, exist_ok=True)
    metrics = run_scenario(config, run_dir, plots=False, model=worker_models().model(config.vehicle_params()))
    row: dict[str, Any] = dict(spec.labels)
    row["status"] = metrics["status"]
    if metrics["status"] == RunStatus.INTERRUPTED:  # stopped (perhaps before its first row): run again on resume
        row["stop_signal"] = metrics.get("stop_signal")
        return row
    if metrics["status"] == RunStatus.FAILED:  # did not do its work (perhaps not one row): failed, run again on resume
        row["message"] = metrics.get("message")
        row["stop_time"] = metrics.get("stop_time")
        return row
    frame = pd.read_parquet(run_dir / "timeseries.parquet")
    columns = {c: frame[c].to_numpy() for c in frame.columns}
    truth = columns["offtracking_truth"]
    row["truth_rms_m"] = rms(truth)
    if "offtracking_viso_ot" in columns:
        err = estimator_errors(truth, columns["offtracking_viso_ot"])
        cam = frame[frame["camera_frame"] > 0.5]
        row.update(
            {
                "viso_ot_rms_error_m": err["rms_error"],
                "viso_ot_mean_error_m": err["mean_error"],
                "viso_ot_max_abs_error_m": err["max_abs_error"],
                "viso_ot_valid_fraction": err["valid_fraction"],
                "mean_matches": float(cam["vo_matches"].mean()),
                "mean_inliers": float(cam["vo_inliers"].mean()),
                "inlier_percent": float(100.0 * cam["vo_inliers"].sum() / max(cam["vo_matches"].sum(), 1.0)),
                "failed_frames": int((cam["vo_valid"] < 0.5).sum() - 1),  # the first frame has no previous pair
            }
        )
    if "offtracking_zero_slip" in columns:
        err = estimator_errors(truth, columns["offtracking_zero_slip"])
        row["zero_slip_rms_error_m"] = err["rms_error"]
    settled = metrics["offtracking"]["truth_after_warmup"]
    row["true_offtracking_rms_after_warmup_m"] = settled["rms"]
    row["true_offtracking_max_after_warmup_m"] = settled["max_abs"]
    steering = metrics.get("trailer_steering") or {}
    row["saturated_fraction"] = max((v["saturated_fraction"] for v in steering.values()), default=0.0)
    row["wall_time_s"] = metrics["wall_time_s"]
    return row


def model_only_cases(
    n: int = 4, duration_s: float = 3.0, scenario: str = "roundabout-3", study: str = "model-only"
) -> list[CaseSpec]:
    """``n`` short model-only cases (zero-slip estimator, no rendering) for tests and the benchmark.

    The cases cycle through the surfaces dry, ice, wet and snow with adverse camber on every other
    one and a seed per case; each simulates ``duration_s`` seconds of ``scenario``.
    """
    surfaces = ("dry", "ice", "wet", "snow")
    cases = []
    for i in range(n):
        surface, camber = surfaces[i % len(surfaces)], 5.0 if i % 2 else 0.0
        overrides = (
            ("duration_s", float(duration_s)),
            ("surface.preset", surface),
            ("camber.percent", camber),
            ("seed", i),
            ("estimators.zero_slip", True),
            ("estimators.viso_ot", False),
        )
        labels = (("case", i), ("surface", surface), ("camber", camber))
        cases.append(CaseSpec(study, scenario, overrides, labels))
    return cases
