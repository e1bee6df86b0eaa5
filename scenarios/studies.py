"""Studies: lists of small, picklable cases run by the sweep runner, gathered into a table and figures.

* ``paper-section3`` — de Saxe & Cebon 2018 §3: the constant-slip straight (5 m/s, 10 fps, 100 m, the
  14.05 m LST as the paper's 14 m trailer) over the baseline sweep for rear and side cameras at 14°
  slip (Fig 6), the slip sweep at baselines 0.5/1.5/2.5 m (Fig 7) and the scenery densities
  100/50/0 % (Fig 8).
* ``estimators-under-slip`` — μ ∈ {dry, wet, snow, ice} × camber ∈ {0, 2.5, 5 %} × {three-turn
  roundabout, figure-of-eight} × feedback ∈ {none, zero_slip, viso_ot, truth}.

The default run of each is a small subset that finishes in minutes; ``full`` runs all of it.

:func:`run_study` runs the cases with :func:`scenarios.sweep.run_sweep`: serially, on local worker
processes (``workers``) or on a Dask cluster (``scheduler``); every finished case is recorded in
``OUT/cases/`` as it completes, so running the study again into the same directory only runs what is
missing or failed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .config import load_scenario
from .metrics import estimator_errors, rms
from .runner import run_scenario
from .sweep import ProgressCallback, SweepProgress, run_sweep

# de Saxe & Cebon 2018 §3.2, values stated in the text (the figures themselves are not reproduced there).
PAPER_SECTION3 = {
    "rms_error_m": "0.01–0.04 for baselines < 2.5 m (rear and side); 0.02–0.04 at 2.5 m (rear, slip < 16°)",
    "mean_error_m": "≈ 0.01 (≤ 0.01 at 0.5 and 1.5 m; up to 0.035 at 2.5 m)",
    "mean_matches": "≈ 380 at 0.5 m, ≈ 325 at 1.5 m, ≈ 250 at 2.5 m (rear); fewer for side cameras",
}


@dataclass(frozen=True)
class CaseSpec:
    """One case: a catalogue scenario, dotted overrides and labels for the table."""

    study: str
    scenario: str
    overrides: tuple[tuple[str, Any], ...]
    labels: tuple[tuple[str, Any], ...] = field(default_factory=tuple)

    @property
    def name(self) -> str:
        return "_".join(f"{k}-{v}" for k, v in self.labels).replace(" ", "").replace("/", "-")


def _camera(kind: str) -> tuple[tuple[str, Any], ...]:
    # Rear: centred on the rear edge, looking back (ψ_c2v 180°). Side: on the left edge at the rear,
    # looking left (ψ_c2v 270°, as in the paper's field tests).
    if kind == "rear":
        return (("camera.psi_c2v_deg", 180.0), ("camera.lateral", 0.0))
    return (("camera.psi_c2v_deg", 270.0), ("camera.lateral", 1.275))


def paper_section3_cases(full: bool = False) -> list[CaseSpec]:
    """Cases of the paper §3 reproduction (a subset unless ``full``)."""
    baselines = np.round(np.arange(0.5, 5.01, 0.5), 2) if full else (0.5, 1.5, 2.5)
    slips = (0, 2, 4, 6, 8, 10, 12, 14, 16, 20, 25, 30, 40, 50, 60) if full else (0, 14, 30)
    slip_baselines = (0.5, 1.5, 2.5) if full else (0.5,)
    densities = (1.0, 0.5, 0.0)
    cameras = ("rear", "side")
    cases: list[CaseSpec] = []
    base = (("estimators.viso_ot", True), ("estimators.zero_slip", False))

    def add(sweep: str, camera: str, baseline: float, slip: float, density: float) -> None:
        overrides = (
            *base,
            *_camera(camera),
            ("camera.baseline", float(baseline)),
            ("path.slip_deg", float(slip)),
            ("camera.scenery_density", float(density)),
        )
        labels = (
            ("sweep", sweep),
            ("camera", camera),
            ("baseline", float(baseline)),
            ("slip", float(slip)),
            ("density", float(density)),
        )
        cases.append(CaseSpec("paper-section3", "constant-slip", overrides, labels))

    for camera in cameras:
        for b in baselines:
            add("baseline", camera, b, 14.0, 1.0)
    for b in slip_baselines:
        for slip in slips:
            add("slip", "rear", b, slip, 1.0)
    for camera in cameras if full else ("rear",):
        for d in densities:
            add("scenery", camera, 0.5, 14.0, d)
    return cases


def estimators_under_slip_cases(full: bool = False) -> list[CaseSpec]:
    """Cases of the estimators-under-slip grid (a subset unless ``full``)."""
    surfaces = ("dry", "wet", "snow", "ice") if full else ("dry", "ice")
    cambers = (0.0, 2.5, 5.0) if full else (0.0, 5.0)
    scenarios = ("roundabout-3", "figure-eight") if full else ("roundabout-3",)
    feedbacks = ("none", "zero_slip", "viso_ot", "truth")
    cases = []
    for scenario in scenarios:
        for surface in surfaces:
            for camber in cambers:
                for feedback in feedbacks:
                    overrides: tuple[tuple[str, Any], ...] = (
                        ("vehicle", "lst"),
                        ("surface.preset", surface),
                        ("camber.percent", camber),
                        ("feedback", feedback),
                        ("estimators.viso_ot", feedback == "viso_ot"),
                    )
                    if not full:
                        overrides += (("path.turns", 0.5),)
                    labels = (("scenario", scenario), ("surface", surface), ("camber", camber), ("feedback", feedback))
                    cases.append(CaseSpec("estimators-under-slip", scenario, overrides, labels))
    return cases


STUDIES: dict[str, Callable[[bool], list[CaseSpec]]] = {
    "paper-section3": paper_section3_cases,
    "estimators-under-slip": estimators_under_slip_cases,
}


def run_case(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """Run one case into ``out_dir/<case name>/`` and return its table row."""
    config = load_scenario(spec.scenario, dict(spec.overrides))
    run_dir = out_dir / spec.name
    run_dir.mkdir(parents=True, exist_ok=True)
    metrics = run_scenario(config, run_dir, plots=False)
    frame = pd.read_parquet(run_dir / "timeseries.parquet")
    columns = {c: frame[c].to_numpy() for c in frame.columns}
    row: dict[str, Any] = dict(spec.labels)
    row["status"] = metrics["status"]
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


def run_study(
    name: str,
    out_dir: Path,
    full: bool = False,
    progress: Callable[[int, int, CaseSpec], None] | None = None,
    *,
    workers: int = 1,
    scheduler: str | Any | None = None,
    resume: bool = True,
    on_progress: ProgressCallback | None = None,
) -> pd.DataFrame:
    """Run every case of a study; write ``table.parquet``, ``table.csv``, ``table.md`` and the figures.

    Parameters
    ----------
    name
        A key of :data:`STUDIES`.
    out_dir
        The study directory: a run directory and a ``cases/<name>.json`` record per case, the table and
        the figures.
    full
        Run the whole study instead of its default subset.
    progress
        ``progress(ended, total, spec)``, called at the start and whenever a case ends (finished or
        failed) with the number of ended cases and that case's spec.
    workers
        Local worker processes (1: one case after another in this process).
    scheduler
        Address of a Dask scheduler (or a ``distributed.Client``) to run the cases on instead.
    resume
        Skip cases already finished in ``out_dir`` (failed ones run again).
    on_progress
        Called with a :class:`~scenarios.sweep.SweepProgress` (finished, failed, remaining, ETA).

    Returns
    -------
    pandas.DataFrame
        One row per case in the study's order; a failed case has ``status`` ``failed`` and its ``error``.
        The figures are drawn from the cases that did not fail.
    """
    if name not in STUDIES:
        raise ValueError(f"unknown study {name!r}; choose one of {sorted(STUDIES)}")
    cases = STUDIES[name](full)
    by_name = {spec.name: spec for spec in cases}

    def report(p: SweepProgress) -> None:
        if progress is not None and cases:
            progress(p.ended, p.total, by_name[p.last.name] if p.last is not None else cases[0])
        if on_progress is not None:
            on_progress(p)

    result = run_sweep(cases, out_dir, run_case, workers=workers, scheduler=scheduler, resume=resume, progress=report)
    table = result.table
    ok = table[table["status"] != "failed"] if "status" in table.columns else table
    if not ok.empty:
        FIGURES[name](ok.reset_index(drop=True), out_dir)
    return table


def _paper_figures(table: pd.DataFrame, out_dir: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = (
        ("viso_ot_rms_error_m", "RMS error [m]"),
        ("viso_ot_mean_error_m", "mean error [m]"),
        ("mean_matches", "mean no. of matches"),
        ("mean_inliers", "mean no. of inliers"),
    )
    sweeps = (
        ("baseline", "baseline", "camera", "Fig 6: sensitivity to the stereo baseline, 14° slip", "fig6_baseline.png"),
        ("slip", "slip", "baseline", "Fig 7: rear cameras, slip angle and baseline", "fig7_slip.png"),
        ("scenery", "density", "camera", "Fig 8: sensitivity to the scenery density, 0.5 m, 14°", "fig8_scenery.png"),
    )
    for sweep, x, group, title, filename in sweeps:
        part = table[table["sweep"] == sweep]
        if part.empty:
            continue
        fig, axes = plt.subplots(1, 4, figsize=(16, 3.6))
        for ax, (column, label) in zip(axes, panels, strict=True):
            for key, grp in part.groupby(group):
                grp = grp.sort_values(x)
                ax.plot(grp[x], grp[column], marker="o", label=f"{group} {key}")
            ax.set_xlabel({"slip": "slip angle [deg]", "density": "scenery density"}.get(x, f"{x} [m]"))
            ax.set_ylabel(label)
            if column == "mean_matches":
                ax.axhline(250, color="tab:red", lw=0.6, ls=":")
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=8)
        fig.suptitle(title)
        fig.tight_layout()
        fig.savefig(out_dir / filename, dpi=110)
        plt.close(fig)


def _grid_figures(table: pd.DataFrame, out_dir: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for scenario, part in table.groupby("scenario"):
        feedbacks = list(dict.fromkeys(part["feedback"]))
        fig, axes = plt.subplots(1, len(feedbacks), figsize=(4 * len(feedbacks), 3.6), squeeze=False)
        for ax, feedback in zip(axes[0], feedbacks, strict=True):
            sub = part[part["feedback"] == feedback]
            grid = sub.pivot_table(index="surface", columns="camber", values="true_offtracking_rms_after_warmup_m")
            order = [s for s in ("dry", "wet", "snow", "ice") if s in grid.index]
            grid = grid.loc[order]
            image = ax.imshow(
                grid.to_numpy(), cmap="magma_r", vmin=0.0, vmax=max(0.3, float(np.nanmax(grid.to_numpy())))
            )
            ax.set_xticks(range(grid.shape[1]), [f"{c:g} %" for c in grid.columns])
            ax.set_yticks(range(grid.shape[0]), grid.index)
            for (i, j), value in np.ndenumerate(grid.to_numpy()):
                ax.text(
                    j,
                    i,
                    "—" if not np.isfinite(value) else f"{value:.3f}",
                    ha="center",
                    va="center",
                    color="w" if np.isfinite(value) and value > 0.15 else "k",
                    fontsize=8,
                )
            ax.set_title(f"feedback: {feedback}")
            ax.set_xlabel("adverse camber")
        fig.colorbar(image, ax=axes[0].tolist(), label="true off-tracking RMS after warm-up [m]")
        fig.suptitle(f"{scenario}: true off-tracking by feedback source, μ and camber")
        fig.savefig(out_dir / f"heatmap_{scenario}.png", dpi=110, bbox_inches="tight")
        plt.close(fig)


FIGURES: dict[str, Callable[[pd.DataFrame, Path], None]] = {
    "paper-section3": _paper_figures,
    "estimators-under-slip": _grid_figures,
}
