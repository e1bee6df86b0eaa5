"""The figures and the paper comparison of the ``paper-section4`` study (de Saxe & Cebon 2018 Figs 14–16).

* ``fig14_timeseries.png`` — for every (camera, manoeuvre) at the smallest baseline, misaligned as in the
  field tests: off-tracking of the truth and of VISO-OT, the error, and the matched features against time;
* ``fig15_left_roundabout.png`` — left roundabout: RMS error, max error and mean matches per baseline, per
  camera and alignment, with the paper's ranges;
* ``fig16_correction.png`` — misaligned against corrected (and aligned) per manoeuvre: the error against
  time and against the true off-tracking (the sign asymmetry), and the mean error for each sign of e_tr;
* ``table.md`` — rewritten as the paper's numbers beside ours, the sign asymmetry and the correction's
  effect, then every case.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..registry import source_colour
from ..run.files import write_atomic
from .section4 import PAPER_SECTION4, PAPER_SECTION4_TEXT, SIGN_THRESHOLD_M

COLOURS = {"aligned": "tab:green", "misaligned": "tab:red", "corrected": "tab:blue"}
SHORT_NAMES = {
    "field-figure-eight": "figure-of-eight",
    "field-roundabout-left": "left roundabout",
    "field-roundabout-right": "right roundabout",
}


def _series(out_dir: Path, row: pd.Series) -> pd.DataFrame | None:
    path = out_dir / str(row.get("case", "")) / "timeseries.parquet"
    if not path.exists():
        return None
    columns = ["time", "camera_frame", "offtracking_truth", "offtracking_viso_ot", "vo_matches", "vo_inliers"]
    return pd.read_parquet(path, columns=columns)


def _rows(table: pd.DataFrame, **labels: Any) -> pd.DataFrame:
    mask = np.ones(len(table), dtype=bool)
    for key, value in labels.items():
        mask &= (table[key] == value).to_numpy()
    return table[mask]


def fig14(table: pd.DataFrame, out_dir: Path, plt: Any) -> None:
    """Fig 14: off-tracking, error and matches against time (smallest baseline, misaligned)."""
    baseline = float(table["baseline"].min())
    panels = [
        (camera, scenario)
        for scenario in SHORT_NAMES
        for camera in ("rear", "side")
        if not _rows(table, camera=camera, scenario=scenario, baseline=baseline, alignment="misaligned").empty
    ]
    if not panels:
        return
    fig, axes = plt.subplots(
        3, len(panels), figsize=(4.6 * len(panels), 7.5), squeeze=False, sharex="col", height_ratios=(2, 1, 1)
    )
    for j, (camera, scenario) in enumerate(panels):
        row = _rows(table, camera=camera, scenario=scenario, baseline=baseline, alignment="misaligned").iloc[0]
        s = _series(out_dir, row)
        if s is None:
            continue
        t = s["time"].to_numpy()
        axes[0, j].plot(t, s["offtracking_truth"], "k", lw=1.2, label="truth")
        axes[0, j].plot(t, s["offtracking_viso_ot"], color=source_colour("viso_ot"), lw=1.0, label="VISO-OT")
        axes[0, j].set_title(f"{camera} cameras, {SHORT_NAMES[scenario]}", fontsize=10)
        axes[1, j].plot(t, s["offtracking_viso_ot"] - s["offtracking_truth"], color=source_colour("viso_ot"), lw=0.9)
        axes[1, j].axhline(0.0, color="k", lw=0.5)
        cam = s[s["camera_frame"] > 0.5]
        axes[2, j].plot(cam["time"], cam["vo_matches"], "tab:gray", lw=0.8, label="matches")
        axes[2, j].plot(cam["time"], cam["vo_inliers"], "tab:purple", lw=0.8, label="inliers")
        axes[2, j].set_xlabel("time [s]")
        for ax in axes[:, j]:
            ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("off-tracking e_tr [m]")
    axes[1, 0].set_ylabel("error [m]")
    axes[2, 0].set_ylabel("features per pair")
    axes[0, 0].legend(fontsize=8)
    axes[2, 0].legend(fontsize=8)
    fig.suptitle(f"Fig 14: off-tracking with features and errors, {baseline:g} m baseline, misaligned right camera")
    fig.tight_layout()
    from ..run.plots import save_figure  # matplotlib only when the figures are drawn

    save_figure(fig, out_dir / "fig14_timeseries.png", dpi=110)


def fig15(table: pd.DataFrame, out_dir: Path, plt: Any) -> None:
    """Fig 15: left roundabout, RMS, max and mean matches per baseline (per camera and alignment)."""
    part = _rows(table, scenario="field-roundabout-left")
    if part.empty:
        return
    panels = (
        ("viso_ot_rms_error_m", "RMS error [m]", "rms_error_m"),
        ("viso_ot_max_abs_error_m", "max error [m]", "max_error_m"),
        ("mean_matches", "mean no. of matches", None),
    )
    fig, axes = plt.subplots(1, 3, figsize=(14, 3.8))
    for ax, (column, label, paper) in zip(axes, panels, strict=True):
        for (camera, alignment), grp in part.groupby(["camera", "alignment"], sort=False):
            grp = grp.sort_values("baseline")
            ax.plot(
                grp["baseline"], grp[column], marker="o" if camera == "rear" else "s",
                ls="-" if camera == "rear" else "--", color=COLOURS.get(alignment), label=f"{camera}, {alignment}",
            )  # fmt: skip
        for camera, colour, alpha in (("rear", "tab:orange", 0.3), ("side", "0.5", 0.15)):
            if paper is None and camera == "side":
                continue
            lo, hi = PAPER_SECTION4["matches"] if paper is None else PAPER_SECTION4[f"{camera}_{paper}"]
            name = f"paper, {camera}" if paper else "paper"
            ax.axhspan(lo, hi, color=colour, alpha=alpha, lw=0, label=name)
        ax.set_xlim(0.4, 1.0)
        ax.set_xlabel("baseline [m]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle("Fig 15: left roundabout summary (bands: the paper's ranges over 0.5–0.9 m)")
    fig.tight_layout()
    from ..run.plots import save_figure  # matplotlib only when the figures are drawn

    save_figure(fig, out_dir / "fig15_left_roundabout.png", dpi=110)


def fig16(table: pd.DataFrame, out_dir: Path, plt: Any) -> None:
    """Fig 16: misaligned vs corrected (and aligned): error against time and against e_tr, means by sign."""
    camera = "rear" if (table["camera"] == "rear").any() else str(table["camera"].iloc[0])
    baseline = float(table["baseline"].min())
    scenarios = [s for s in SHORT_NAMES if not _rows(table, scenario=s, camera=camera, baseline=baseline).empty]
    if not scenarios:
        return
    fig, axes = plt.subplots(len(scenarios), 3, figsize=(15, 3.3 * len(scenarios)), squeeze=False)
    for i, scenario in enumerate(scenarios):
        rows = _rows(table, scenario=scenario, camera=camera, baseline=baseline)
        bars: dict[str, tuple[float, float]] = {}
        for _, row in rows.iterrows():
            s = _series(out_dir, row)
            alignment = str(row["alignment"])
            if s is None:
                continue
            err = s["offtracking_viso_ot"] - s["offtracking_truth"]
            style = {"color": COLOURS.get(alignment), "lw": 0.9, "label": alignment}
            axes[i, 0].plot(s["time"], err, **style)
            axes[i, 1].plot(s["offtracking_truth"], err, ".", ms=1.5, color=COLOURS.get(alignment))
            bars[alignment] = (float(row.get("neg_mean_error_m", np.nan)), float(row.get("pos_mean_error_m", np.nan)))
        x = np.arange(2)
        for k, (alignment, (neg, pos)) in enumerate(bars.items()):
            axes[i, 2].bar(x + 0.27 * (k - 1), [neg, pos], 0.25, color=COLOURS.get(alignment), label=alignment)
        axes[i, 2].set_xticks(x, [f"e_tr < −{SIGN_THRESHOLD_M:g} m", f"e_tr > +{SIGN_THRESHOLD_M:g} m"])
        axes[i, 0].set_ylabel(f"{SHORT_NAMES[scenario]}\nerror [m]")
        axes[i, 1].set_xlabel("true off-tracking e_tr [m]")
        axes[i, 2].set_ylabel("mean error [m]")
        for ax in axes[i]:
            ax.axhline(0.0, color="k", lw=0.5)
            ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=8)
    axes[0, 2].legend(fontsize=8)
    fig.suptitle(
        f"Fig 16: {camera} cameras, {baseline:g} m: right camera misaligned (φ −0.15°, ψ +0.10°) "
        "and corrected by eqs (8)–(9)"
    )
    fig.tight_layout()
    from ..run.plots import save_figure  # matplotlib only when the figures are drawn

    save_figure(fig, out_dir / "fig16_correction.png", dpi=110)


def _range(key: str, unit: str = "") -> str:
    lo, hi = PAPER_SECTION4[key]
    return f"{lo:g}–{hi:g}{unit}"


def _fmt(value: Any, digits: int = 3, signed: bool = False) -> str:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return "—"
    if not np.isfinite(v):
        return "—"
    return f"{v:+.{digits}f}" if signed else f"{v:.{digits}f}"


def _pct(share: Any) -> str:
    text = _fmt(100 * float(share), 0)
    return text if text == "—" else f"{text} %"


def correction_effect(table: pd.DataFrame) -> pd.DataFrame:
    """Per (scenario, camera, baseline): the RMS error of each alignment and the share the correction removes.

    ``removed`` = 1 − RMS(corrected) / RMS(misaligned); ``removed_excess`` = the same for the RMS above the
    aligned case's, (misaligned − corrected) / (misaligned − aligned).
    """
    keys = ["scenario", "camera", "baseline"]
    wide = table.pivot_table(index=keys, columns="alignment", values="viso_ot_rms_error_m", sort=False)
    for name in ("aligned", "misaligned", "corrected"):
        if name not in wide.columns:
            wide[name] = np.nan
    wide["removed"] = 1.0 - wide["corrected"] / wide["misaligned"]
    wide["removed_excess"] = (wide["misaligned"] - wide["corrected"]) / (wide["misaligned"] - wide["aligned"])
    return wide.reset_index()


def _md(*groups: list[Any]) -> str:
    return "| " + " | ".join(str(c) for group in groups for c in group) + " |"


def _header(*groups: list[str]) -> list[str]:
    n = sum(len(g) for g in groups)
    return [_md(*groups), _md(["---"] * n)]


def comparison_markdown(table: pd.DataFrame) -> str:
    """The paper's §4 numbers beside ours, the sign asymmetry and the correction, as Markdown."""
    lines = ["# paper-section4: de Saxe & Cebon 2018 §4 (field tests) beside this simulation", ""]
    lines += ["## Left roundabout (paper Fig 15)", ""]
    lines += _header(
        ["camera", "baseline [m]", "alignment", "RMS [m]", "paper RMS [m]", "max [m]", "paper max [m]"],
        ["mean matches", "paper matches"],
    )
    for _, r in _rows(table, scenario="field-roundabout-left").iterrows():
        cam = str(r["camera"])
        lines.append(
            _md(
                [cam, f"{r['baseline']:g}", r["alignment"], _fmt(r.get("viso_ot_rms_error_m"))],
                [_range(f"{cam}_rms_error_m"), _fmt(r.get("viso_ot_max_abs_error_m")), _range(f"{cam}_max_error_m")],
                [_fmt(r.get("mean_matches"), 0), _range("matches")],
            )
        )
    threshold = f"{SIGN_THRESHOLD_M:g} m"
    lines += ["", f"## Sign asymmetry: mean error where e_tr < −{threshold} and > +{threshold}", ""]
    lines += _header(
        ["manoeuvre", "camera", "baseline [m]", "alignment", "mean error, −e_tr [m]", "mean error, +e_tr [m]"],
        ["RMS, −e_tr [m]", "RMS, +e_tr [m]", "RMS [m]", "mean error [m]"],
    )
    for _, r in table.iterrows():
        lines.append(
            _md(
                [SHORT_NAMES.get(str(r["scenario"]), r["scenario"]), r["camera"], f"{r['baseline']:g}", r["alignment"]],
                [_fmt(r.get("neg_mean_error_m"), signed=True), _fmt(r.get("pos_mean_error_m"), signed=True)],
                [_fmt(r.get("neg_rms_error_m")), _fmt(r.get("pos_rms_error_m"))],
                [_fmt(r.get("viso_ot_rms_error_m")), _fmt(r.get("viso_ot_mean_error_m"), signed=True)],
            )
        )
    lines += ["", "## The eqs (8)–(9) correction (paper Fig 16: it removes the bias of its −e_tr, the right turn)", ""]
    lines += _header(
        ["manoeuvre", "camera", "baseline [m]", "RMS aligned [m]", "RMS misaligned [m]", "RMS corrected [m]"],
        ["RMS removed", "excess over aligned removed"],
    )
    for _, r in correction_effect(table).iterrows():
        lines.append(
            _md(
                [SHORT_NAMES.get(str(r["scenario"]), r["scenario"]), r["camera"], f"{r['baseline']:g}"],
                [_fmt(r["aligned"]), _fmt(r["misaligned"]), _fmt(r["corrected"])],
                [_pct(r["removed"]), _pct(r["removed_excess"])],
            )
        )
    rms = table.pivot_table(index=["camera", "baseline"], columns="alignment", values="viso_ot_rms_error_m")
    rms2 = table.assign(ms=table["viso_ot_rms_error_m"] ** 2)
    pooled = np.sqrt(rms2.pivot_table(index=["camera", "baseline"], columns="alignment", values="ms"))
    for (camera, baseline), r in pooled.iterrows():
        several = table[(table["camera"] == camera) & (table["baseline"] == baseline)]["scenario"].nunique() > 1
        if several and {"misaligned", "corrected"} <= set(r.index) and rms.loc[(camera, baseline)].notna().all():
            removed = 1.0 - r["corrected"] / r["misaligned"]
            lines.append(
                _md(
                    ["all manoeuvres (pooled RMS)", camera, f"{baseline:g}"],
                    [_fmt(r.get("aligned")), _fmt(r["misaligned"]), _fmt(r["corrected"])],
                    [_pct(removed), "—"],
                )
            )
    lines += [
        "",
        "Sign convention: here e_tr < 0 in a left turn and > 0 in a right one. The paper's left roundabout was",
        '"the least affected by bias" and its bias was for −e_tr, so its e_tr has the opposite sign: compare',
        "turn directions, not signs.",
    ]
    lines += ["", "## The paper's findings in words (§4.2–4.4)", ""]
    lines += [f"* {key}: {text}" for key, text in PAPER_SECTION4_TEXT.items()]
    return "\n".join(lines) + "\n"


def section4_figures(table: pd.DataFrame, out_dir: Path) -> None:
    """Draw Figs 14–16 of the study into ``out_dir`` and rewrite ``table.md`` beside the paper's numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    for figure in (fig14, fig15, fig16):
        figure(table, out_dir, plt)
    full = table.to_markdown(index=False, floatfmt=".3f")
    write_atomic(out_dir / "table.md", comparison_markdown(table) + "\n## Every case\n\n" + full + "\n")
