"""Figures a vehicle engineer reads at a glance: the swept-path plan view, the comparison, the animation and
the study summary that fits a terminal.

Checked by what they show (the figure's artists, the video's frame count and size, the rendered text), never
pixel by pixel. One model-only UK roundabout test with the reference trailer (5 km/h, a few seconds) feeds
them all; the reference trailer fails the test (its innermost point enters the 5.30 m circle). The checks of a
figure's layout draw every 10th sample of it (:data:`THIN`); those of its verdict's radii and marked points, all.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import imageio.v2 as imageio
import imageio.v3 as iio
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest
from matplotlib.patches import PathPatch
from rich.console import Console

from scenarios.config import load_scenario
from scenarios.export.animation import OfftrackingTrace, animate_run, animation_title, frame_times
from scenarios.export.trace_panel import band_polygons, towed_unit_traces
from scenarios.loop.participant import Column
from scenarios.loop.schema import RecordedColumns
from scenarios.run.metrics import after_warmup
from scenarios.run.plan_marks import LIMIT_COLOURS
from scenarios.run.plots import load_run, offtracking_figure, plot_plan_view
from scenarios.run.runner import run_scenario
from scenarios.run.swept_path import envelope_samples, swept_path_figure
from scenarios.run.unit_shapes import vehicle_polygons
from scenarios.studies.compare import comparison_figure
from scenarios.studies.figures import grid_figure
from scenarios.studies.summary import summary_table


@pytest.fixture(scope="module")
def roundabout_run(roundabout_test_run: Path) -> Path:
    """A model-only UK roundabout test of the reference combination (unsteered trailer, the zero-slip estimator):
    the session's shared run, read only."""
    assert json.loads((roundabout_test_run / "metrics.json").read_text())["status"] == "completed"
    return roundabout_test_run


THIN = 10
"""Every 10th sample of the run (5 Hz): enough for the checks of a figure's layout, a tenth of the envelopes'
vertices to draw."""


def _thinned(columns) -> dict[str, np.ndarray]:
    return {k: np.asarray(v)[::THIN] for k, v in dict(columns).items()}


def _texts(fig) -> list[str]:
    return [t.get_text() for ax in fig.axes for t in ax.texts] + [fig._suptitle.get_text() if fig._suptitle else ""]


def _gids(fig, prefix: str) -> list:
    return [a for ax in fig.axes for a in ax.get_children() if str(a.get_gid() or "").startswith(prefix)]


def test_swept_path_figure_shows_verdict_radii_envelopes_and_instants(roundabout_run: Path) -> None:
    run = load_run(roundabout_run)
    test = run.metrics["roundabout_test"]
    assert test["pass"] is False  # the reference trailer's innermost point enters the 5.30 m circle
    fig = swept_path_figure(
        run.params,
        run.columns,
        run.setup.path.points,
        run.setup.annulus_centre,
        run.title,
        roundabout_test=test,
        turn_span=run.setup.path.turn_span,
        instants=4,
    )
    try:
        texts = _texts(fig)
        assert "FAIL" in fig._suptitle.get_text()
        inner, outer = f"{test['inner_radius_min']:.3f} m", f"{test['outer_radius_max']:.3f} m"
        assert any(inner in t and "5.30" in t and f"{test['inner_margin']:+.3f}" in t for t in texts)
        assert any(outer in t and "12.50" in t for t in texts)
        centre = np.asarray(run.setup.annulus_centre)
        for key, radius in (("inner", test["inner_radius_min"]), ("outer", test["outer_radius_max"])):
            markers = _gids(fig, f"extreme:{key}")
            markers = [m for m in markers if hasattr(m, "get_xydata")]
            assert markers, key
            for m in markers:  # each marked point lies on the reported radius
                assert np.hypot(*(m.get_xydata()[0] - centre)) == pytest.approx(radius, abs=1e-9)
        main = fig.axes[0]
        envelopes = {a.get_gid(): a for a in main.patches if str(a.get_gid()).startswith("envelope:")}
        assert set(envelopes) == {"envelope:tractor", "envelope:trailer"}
        for patch in envelopes.values():
            assert isinstance(patch, PathPatch) and len(patch.get_path().vertices) > 100
        assert envelopes["envelope:tractor"].get_facecolor() != envelopes["envelope:trailer"].get_facecolor()
        per_vehicle = len(vehicle_polygons(run.params, 0.0, 0.0, 0.0, 0.0))
        assert len([p for p in main.patches if p.get_gid() == "instant"]) == 4 * per_vehicle
        assert len(fig.axes) == 3  # main panel and a zoom on each extreme point
        for zoom in fig.axes[1:]:  # each zoom names its envelopes and points to the turn centre
            labels = [t.get_text() for t in zoom.get_legend().get_texts()]
            assert {"tractor swept envelope", "trailer swept envelope"} <= set(labels)
            (arrow,) = [a for a in zoom.texts if a.get_gid() == "turn-centre"]
            tip, tail = np.asarray(arrow.xy), np.asarray(arrow.xyann)
            data = zoom.transData.inverted().transform(zoom.transAxes.transform(np.vstack([tail, tip])))
            towards = centre - data[0]
            pointing = (data[1] - data[0]) / np.hypot(*(data[1] - data[0]))
            assert pointing @ towards / np.hypot(*towards) > 0.99  # aimed at the circles' centre within 8°
        time_labels = [a for a in main.texts if a.get_gid() == "instant:label"]
        assert len(time_labels) == 4 and all(a.get_bbox_patch() is not None for a in time_labels)
    finally:
        plt.close(fig)


def test_verdict_computed_without_metrics_matches_the_metrics(roundabout_run: Path) -> None:
    run = load_run(roundabout_run)
    test = run.metrics["roundabout_test"]
    fig = swept_path_figure(
        run.params, run.columns, run.setup.path.points, run.setup.annulus_centre, turn_span=run.setup.path.turn_span
    )
    try:
        assert f"{test['inner_radius_min']:.3f}" in fig._suptitle.get_text()
        assert f"{test['outer_radius_max']:.3f}" in fig._suptitle.get_text()
    finally:
        plt.close(fig)


def test_plan_view_keeps_its_positional_signature(roundabout_run: Path, tmp_path: Path) -> None:
    run = load_run(roundabout_run)
    out = tmp_path / "plan_view.png"
    fig = plot_plan_view(out, run.params, _thinned(run.columns), run.setup.path.points, None, "no test circles")
    assert out.stat().st_size > 10_000
    assert not _gids(fig, "extreme:")  # no roundabout test: no radii, one zoom on the largest off-tracking
    assert len(fig.axes) == 2 and "largest true off-tracking" in fig.axes[1].get_title()


def test_envelope_samples_keep_the_ends_and_thin_the_rest(roundabout_run: Path) -> None:
    from vehicle_model.geometry import trailer_outline

    c = load_run(roundabout_run).columns
    params = load_run(roundabout_run).params
    polys = trailer_outline(params, c["X"], c["Y"], c["psi1"], c["gamma"])
    kept = envelope_samples(polys, 0.1)
    assert kept[0] == 0 and kept[-1] == len(polys) - 1 and len(kept) < len(polys)
    assert np.all(np.linalg.norm(np.diff(polys[kept], axis=0), axis=-1).max(axis=-1) < 0.2)


def test_comparison_figure_overlays_trailer_envelopes(roundabout_run: Path) -> None:
    run = load_run(roundabout_run)
    frame = pd.read_parquet(roundabout_run / "timeseries.parquet").iloc[::THIN]
    shifted = frame.copy()
    shifted["X"] += 0.3  # a second, distinguishable run
    traces = {"none": frame, "truth": shifted}
    fig = comparison_figure(run.config, traces, {"none": run.metrics["roundabout_test"], "truth": None})
    try:
        gids = {a.get_gid() for a in _gids(fig, "envelope:trailer:")}
        assert {"envelope:trailer:none", "envelope:trailer:truth"} <= gids
        assert "FAIL" in fig._suptitle.get_text()
        assert _gids(fig, "extreme:inner:none") and _gids(fig, "extreme:inner:truth")
    finally:
        plt.close(fig)


def test_comparison_figure_shows_the_units_behind_the_first(roundabout_run: Path) -> None:
    """A run with a second towed unit's truth draws it too, labelled with that unit's own RMS after warm-up."""
    run = load_run(roundabout_run)
    frame = pd.read_parquet(roundabout_run / "timeseries.parquet")
    frame["offtracking_truth3"] = 2.0 * frame["offtracking_truth"]
    fig = comparison_figure(run.config, {"none": frame})
    try:
        (line,) = _gids(fig, "offtracking:none:3")
        settled = after_warmup({c: frame[c].to_numpy() for c in frame.columns}, run.params.follow_point_offset)
        expected = np.sqrt(np.mean((2.0 * frame["offtracking_truth"].to_numpy()[settled]) ** 2))
        assert line.get_label() == f"none, unit 3: RMS {expected:.3f} m"
        legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
        assert {"±0.10 m RMS target", "±0.15 m max target"} <= set(legend)  # the target lines are named
    finally:
        plt.close(fig)


def test_limit_circles_have_their_own_colours_and_labels_off_the_swept_annulus(roundabout_run: Path) -> None:
    run = load_run(roundabout_run)
    run = dataclasses.replace(run, columns=_thinned(run.columns))
    fig = run.swept_path_figure(instants=2)
    try:
        main = fig.axes[0]
        outer, inner = (next(a for a in main.get_lines() if a.get_gid() == f"limit:{k}") for k in ("outer", "inner"))
        assert outer.get_color() != inner.get_color()
        assert (outer.get_color(), inner.get_color()) == (LIMIT_COLOURS["outer"], LIMIT_COLOURS["inner"])
        centre = np.asarray(run.setup.annulus_centre)
        for key, line in (("outer", outer), ("inner", inner)):
            radius = np.hypot(*(line.get_xydata() - centre).T)
            assert np.allclose(radius, 12.50 if key == "outer" else 5.30)
            assert f"{radius[0]:.2f} m" in line.get_label()
        legend = [t.get_text() for t in main.get_legend().get_texts()]
        assert any("12.50 m" in t for t in legend) and any("5.30 m" in t for t in legend)
        labels = {a.get_gid(): a for a in main.texts if str(a.get_gid()).startswith("limit:")}
        assert set(labels) == {"limit:outer:label", "limit:inner:label"}
        r = {k: np.hypot(*(np.asarray(t.get_position()) - centre)) for k, t in labels.items()}
        assert r["limit:outer:label"] > 12.50 and r["limit:inner:label"] < 5.30  # off the swept annulus
    finally:
        plt.close(fig)


def test_a_small_effect_on_a_large_roundabout_gets_a_zoom_of_its_size_and_a_scale_bar(roundabout_run: Path) -> None:
    run = load_run(roundabout_run)
    columns = _thinned(run.columns)
    columns["offtracking_truth"] = np.where(np.isfinite(columns["offtracking_truth"]), 0.05, np.nan)
    fig = swept_path_figure(run.params, columns, run.setup.path.points, None, "5 cm of off-tracking", instants=0)
    try:
        zoom = fig.axes[1]
        width = np.diff(zoom.get_xlim())[0]
        assert 0.05 <= width <= 10 * 0.05  # a window of the effect's size, not the 5 m default
        bars = [a for a in zoom.get_children() if a.get_gid() == "scale_bar"]
        assert len(bars) == 1
        assert bars[0].txt_label.get_text() in ("5 cm", "2 cm", "1 cm")
    finally:
        plt.close(fig)


def test_a_long_title_is_not_clipped(roundabout_run: Path, tmp_path: Path) -> None:
    run = load_run(roundabout_run)
    long_title = run.title + " " + "and a very long remark about the run " * 6
    fig = swept_path_figure(run.params, _thinned(run.columns), run.setup.path.points, None, long_title, instants=0)
    try:
        fig.savefig(tmp_path / "plan.png", dpi=40, bbox_inches="tight")
        box = fig._suptitle.get_window_extent(fig.canvas.get_renderer())
        assert box.x0 >= 0.0 and box.x1 <= fig.bbox.width  # wrapped inside the figure
        assert "\n" in fig._suptitle.get_text()
    finally:
        plt.close(fig)


def test_comparison_figure_legend_has_rms_and_puts_a_dominant_unsteered_run_on_its_own_axis(
    roundabout_run: Path,
) -> None:
    run = load_run(roundabout_run)
    frame = pd.read_parquet(roundabout_run / "timeseries.parquet").iloc[::THIN]
    steered = frame.copy()
    steered["offtracking_truth"] = 0.01 * np.sign(frame["offtracking_truth"])  # a run steered to 1 cm
    steered["X"] += 0.02
    peak = np.nanmax(np.abs(frame["offtracking_truth"]))
    assert peak > 5 * 0.01  # the unsteered run dominates
    fig = comparison_figure(run.config, {"none": frame, "truth": steered}, {"none": run.metrics["roundabout_test"]})
    try:
        lines = {a.get_gid(): a for a in _gids(fig, "offtracking:")}
        assert set(lines) == {"offtracking:none", "offtracking:truth"}
        assert lines["offtracking:none"].axes is not lines["offtracking:truth"].axes  # its own (twin) axis
        labels = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]
        for feedback in ("none", "truth"):
            assert any(t.startswith(feedback) and "RMS" in t and " m" in t for t in labels), feedback
        zoom = next(ax for ax in fig.axes if _gids_in(ax, "envelope:trailer:"))
        assert zoom.get_legend() is not None and np.diff(zoom.get_xlim())[0] < 20.0  # no 100 m plan view
        assert any(a.get_gid() == "scale_bar" for a in zoom.get_children())
    finally:
        plt.close(fig)
    fig = comparison_figure(run.config, {"truth": steered, "zero_slip": steered})
    try:
        lines = _gids(fig, "offtracking:")
        assert len({line.axes for line in lines}) == 1  # nothing dominates: one axis
    finally:
        plt.close(fig)


def _gids_in(ax, prefix: str) -> list:
    return [a for a in ax.get_children() if str(a.get_gid() or "").startswith(prefix)]


def test_heat_maps_mark_the_target_show_mu_and_do_not_clip_the_largest_cell() -> None:
    table = _study_table()
    part = table[table["scenario"] == "roundabout-3"].copy()
    part.loc[part.index[3], "true_offtracking_rms_after_warmup_m"] = 0.9  # one cell far above the rest
    fig = grid_figure(part, "roundabout-3")
    try:
        targets = _gids(fig, "target")
        assert targets and all(t.get_gid() in ("target", "target:colorbar") for t in targets)
        images = [im for ax in fig.axes for im in ax.get_images()]
        top = images[: len(part["feedback"].unique())]
        assert max(im.norm.vmax for im in top) >= 0.9
        rows = [t.get_text() for t in fig.axes[0].get_yticklabels()]
        assert rows[0] == "dry (μ 0.80)" and rows[-1] == "ice (μ 0.10)"
        titles = [ax.get_title() for ax in fig.axes]
        assert any("estimator" in t for t in titles)  # the estimator-error maps beside the closed loop's
        for ax in fig.axes[: len(top)]:  # outlined cells are those within the target
            for rect in _gids_in(ax, "target"):
                i, j = round(rect.get_y() + 0.5), round(rect.get_x() + 0.5)
                assert ax.get_images()[0].get_array()[i, j] <= 0.10
    finally:
        plt.close(fig)


def test_format_svg_writes_svg_plots_and_a_bad_format_exits_2(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Every command runs in-process through ``main()`` (the exit code a process gets from it is tested in
    # test_faults.py).
    from test_faults import offtrack_in_process

    for command in (["run", "roundabout-test"], ["report", str(tmp_path)], ["compare", "roundabout-test"]):
        bad = offtrack_in_process(monkeypatch, capsys, *command, "--format", "jpg", "--out", str(tmp_path / "bad"))
        if command[0] == "report":
            bad = offtrack_in_process(monkeypatch, capsys, *command, "--format", "jpg")
        assert bad.returncode == 2, command
        lines = bad.stderr.strip().splitlines()
        assert len(lines) == 1 and "--format" in lines[0] and "png, svg or pdf" in lines[0]
        assert not (tmp_path / "bad").exists()  # refused before any work
    out = tmp_path / "svg"
    ran = offtrack_in_process(
        monkeypatch, capsys, "run", "roundabout-test", "--duration", "3", "--format", "svg", "--out", str(out)
    )
    assert ran.returncode == 0, ran.stdout + ran.stderr
    assert (out / "plan_view.svg").read_text().lstrip().startswith(("<?xml", "<svg"))
    assert (out / "offtracking.svg").is_file() and not list(out.glob("*.png"))
    again = offtrack_in_process(monkeypatch, capsys, "report", str(out), "--format", "pdf")
    assert again.returncode == 0, again.stdout + again.stderr
    assert (out / "plan_view.pdf").read_bytes().startswith(b"%PDF") and (out / "offtracking.pdf").is_file()


def test_animation_has_the_expected_frames_and_size(roundabout_run: Path, tmp_path: Path) -> None:
    out = animate_run(roundabout_run, tmp_path / "run.mp4", fps=5.0, max_frames=6, size=(320, 240))
    reader = imageio.get_reader(out)
    try:
        assert reader.get_meta_data()["size"] == (320, 240)
        assert reader.count_frames() == 6
        assert reader.get_data(0).shape == (240, 320, 3)
    finally:
        reader.close()
    gif = animate_run(roundabout_run, tmp_path / "run.gif", fps=5.0, max_frames=3, size=(160, 120))
    assert iio.imread(gif).shape[:3] == (3, 120, 160)


def test_the_offtracking_trace_draws_nothing_ahead_of_its_cursor() -> None:
    time = np.arange(0.0, 60.001, 0.1)
    cols = {"offtracking_truth": np.sin(time), "offtracking_zero_slip": np.full(time.size, np.nan)}
    cols["offtracking_zero_slip"][300:] = 0.25
    fig, axes = plt.subplots()
    try:
        panel = OfftrackingTrace(axes, time, cols, ["truth", "zero_slip"], window_s=30.0)
        k = 400  # t = 40 s
        panel.show(k)
        for line in axes.get_lines()[:2]:
            assert np.nanmax(line.get_xdata()) == pytest.approx(time[k])  # drawn up to the cursor, not beyond
        assert axes.get_xlim() == pytest.approx((40.0 - 22.5, 40.0 + 7.5))
        texts = [t.get_text() for t in axes.get_legend().get_texts()]
        assert texts == [f"truth {np.sin(40.0):+.3f} m", "zero_slip +0.250 m"]
        panel.show(100)  # before the estimate exists: a dash, not a number
        assert axes.get_legend().get_texts()[1].get_text() == "zero_slip —"
    finally:
        plt.close(fig)


def test_every_towed_unit_has_its_trace_with_its_band_up_to_the_cursor() -> None:
    time = np.arange(0.0, 20.001, 0.1)
    values = {
        "time": time,
        "offtracking_truth": 0.1 * np.sin(time),
        "offtracking_viso_ot_fused": 0.1 * np.sin(time) + 0.01,
        "offtracking_viso_ot_fused_std": np.full(time.size, 0.02),
        "rear_truth": 0.2 * np.sin(time),
        "rear_fused": np.where(time >= 5.0, 0.2 * np.sin(time) - 0.02, np.nan),
        "rear_fused_std": np.where(time >= 5.0, 0.03, np.nan),
    }
    schema = [
        Column("rear_truth", "m", role="estimate", vehicle_unit=3, estimator="truth"),
        Column("rear_fused", "m", role="estimate", vehicle_unit=3, estimator="viso_ot_fused"),
        Column("rear_fused_std", "m", role="std", vehicle_unit=3, estimator="viso_ot_fused"),
    ]
    cols = RecordedColumns(values, schema)
    traced = towed_unit_traces(cols)
    assert traced == [(2, ["truth", "viso_ot_fused"]), (3, ["truth", "viso_ot_fused"])]
    fig, axes = plt.subplots(2, 1)
    try:
        panels = [
            OfftrackingTrace(ax, time, cols, names, 10.0, unit=u) for ax, (u, names) in zip(axes, traced, strict=True)
        ]
        k = 100  # t = 10 s
        for panel in panels:
            panel.show(k)
        for ax, sigma in zip(axes, (0.02, 0.03), strict=True):
            (band,) = [c for c in ax.collections if str(c.get_gid()).startswith("sigma2:viso_ot_fused")]
            vertices = np.concatenate([path.vertices for path in band.get_paths()])
            assert vertices[:, 0].max() == pytest.approx(time[k])  # the band ends at the cursor
            width = vertices[:, 1].max() - vertices[:, 1].min()
            assert width > 4 * sigma  # a 4σ-wide band around the estimate (plus its swing)
        unit3 = [t.get_text() for t in axes[1].get_legend().get_texts()]
        assert unit3 == [f"truth {0.2 * np.sin(10.0):+.3f} m", f"viso_ot_fused {0.2 * np.sin(10.0) - 0.02:+.3f} m"]
        assert "unit 3" in axes[1].get_ylabel()
        panels[1].show(30)  # before unit 3's estimate: no band, a dash
        band = next(c for c in axes[1].collections if str(c.get_gid()).startswith("sigma2:"))
        assert len(band.get_paths()) == 0 and axes[1].get_legend().get_texts()[1].get_text() == "viso_ot_fused —"
    finally:
        plt.close(fig)


def test_a_band_is_split_where_its_standard_deviation_is_missing() -> None:
    time = np.arange(10.0)
    lo, hi = -np.ones(10), np.ones(10)
    hi[4] = np.nan
    polygons = band_polygons(time, lo, hi)
    assert [p[:, 0].min() for p in polygons] == [0.0, 5.0] and [p[:, 0].max() for p in polygons] == [3.0, 9.0]


def test_the_animation_of_a_b_double_traces_both_trailers(tmp_path: Path) -> None:
    import yaml

    data = Path(__file__).parent / "data" / "combinations" / "b-double.yaml"
    vehicle = {"name": "b-double", **yaml.safe_load(data.read_text(encoding="utf-8"))}
    overrides = {"vehicle": vehicle, "feedback": "none", "duration_s": 3.0, "estimators.viso_ot": False}
    config = load_scenario("roundabout-test", {**overrides, "estimators.zero_slip": True})
    assert run_scenario(config, tmp_path, plots=False)["status"] == "completed"
    assert [u for u, _ in towed_unit_traces(load_run(tmp_path).columns)] == [2, 3]
    out = animate_run(tmp_path, tmp_path / "run.gif", fps=5.0, max_frames=2, size=(200, 160))
    assert iio.imread(out).shape[:3] == (2, 160, 200)


def test_the_offtracking_figure_shows_targets_bands_steer_camera_and_warm_up() -> None:
    t = np.arange(0.0, 30.001, 0.1)
    truth = np.where(t >= 5.0, 0.05 * np.sin(t), np.nan)
    steer = np.where(t > 10.0, np.radians(25.0), np.radians(2.0 * t))
    cols = {
        "time": t,
        "offtracking_truth": truth,
        "offtracking_truth_geometric": truth,
        "offtracking_viso_ot_fused": truth + 0.01,
        "offtracking_viso_ot_fused_std": np.full(t.size, 0.02),
        "steer_trailer2": steer,
        "saturated_trailer2": (t > 10.0).astype(float),
        "vo_matches": np.full(t.size, 250.0),
        "vo_inliers": np.full(t.size, 180.0),
        "camera_frame": (np.arange(t.size) % 10 == 0).astype(float),
    }
    settled = t >= 8.0
    fig = offtracking_figure(cols, ["viso_ot_fused"], "title", settled=settled, max_steer_deg=25.0)
    try:
        assert len(fig.axes) == 4  # off-tracking, error, steer, camera
        assert {"target:0.10", "target:0.15", "sigma2:viso_ot_fused", "steer:trailer2", "steer_limit"} <= {
            str(a.get_gid()) for ax in fig.axes for a in ax.get_children()
        }
        assert _gids(fig, "camera:matches") and _gids(fig, "camera:inliers")
        spans = _gids(fig, "warmup")
        assert len(spans) == 4  # shaded in every panel, up to the first settled sample
        assert spans[0].get_x() + spans[0].get_width() == pytest.approx(8.0)
        labels = [text.get_text() for text in fig.axes[0].get_legend().get_texts()]
        assert labels[0].startswith("truth: 0.0") and "RMS" in labels[0] and "max after warm-up" in labels[0]
        assert "viso_ot_fused: error 0.010 m RMS after warm-up" in labels
        steer_label = fig.axes[2].get_legend().get_texts()[0].get_text()
        assert steer_label == f"trailer2: at its lock {np.mean(t > 10.0):.0%} of the time"
    finally:
        plt.close(fig)


def test_the_offtracking_figure_shows_every_towed_unit_and_every_steered_axle() -> None:
    """A B-double's figure: each trailer's off-tracking and error panels (the rear one included, with its own RMS),
    and one steer panel with the axles of both trailers."""
    from scenarios.loop.participant import Column
    from scenarios.loop.schema import RecordedColumns

    t = np.arange(0.0, 20.001, 0.1)
    lead, rear = np.where(t >= 4.0, 0.02, np.nan), np.where(t >= 6.0, 0.3, np.nan)
    values = {
        "time": t,
        "offtracking_truth": lead,
        "offtracking_zero_slip": lead + 0.01,
        "offtracking_truth3": rear,
        "offtracking_zero_slip3": rear - 0.1,
        "steer_lead2": np.full(t.size, 0.05),
        "steer_rear2": np.full(t.size, -0.07),
    }
    schema = [
        Column("time", "s", "", role="time"),
        Column.estimate("truth", ""),
        Column.estimate("zero_slip", ""),
        Column.estimate("truth", "", vehicle_unit=3),
        Column.estimate("zero_slip", "", vehicle_unit=3),
        Column("steer_lead2", "rad", "", role="command", vehicle_unit=2),
        Column("steer_rear2", "rad", "", role="command", vehicle_unit=3),
    ]
    fig = offtracking_figure(RecordedColumns(values, schema), ["zero_slip"], "B-double", settled=t >= 5.0)
    try:
        assert len(fig.axes) == 5  # two panels per trailer, one steer panel
        assert _gids(fig, "truth:3") and _gids(fig, "estimate:zero_slip:3")
        rear_labels = [text.get_text() for text in fig.axes[2].get_legend().get_texts()]
        assert rear_labels == [
            "unit 3: truth: 0.300 m RMS, 0.300 m max after warm-up",
            "unit 3: zero_slip: error 0.100 m RMS after warm-up",
        ]
        assert {"steer:lead2", "steer:rear2"} <= {str(a.get_gid()) for a in fig.axes[4].get_children()}
    finally:
        plt.close(fig)


def test_the_animation_title_carries_the_roundabout_verdict(roundabout_run: Path) -> None:
    run = load_run(roundabout_run)
    test = run.metrics["roundabout_test"]
    title = animation_title(run)
    assert title.startswith(run.title) and "roundabout test FAIL" in title  # the reference trailer fails (above)
    assert f"{test['inner_radius_min']:.3f} m" in title


def test_frame_times_follow_fps_and_speed() -> None:
    time = np.arange(0.0, 10.001, 0.02)
    assert len(frame_times(time, fps=10.0, speed=2.0)) == 51  # a frame every 0.2 s of the 10 s run
    capped = frame_times(time, fps=10.0, speed=2.0, max_frames=7)
    assert len(capped) == 7 and capped[0] == 0.0 and capped[-1] == pytest.approx(10.0)


def _study_table() -> pd.DataFrame:
    """A table shaped like estimators-under-slip's (labels, status, metrics, a failed case with its error)."""
    rng = np.random.default_rng(1)
    rows = []
    for scenario in ("roundabout-3", "figure-eight"):
        for surface in ("dry", "wet", "snow", "ice"):
            for camber in (0.0, 2.5, 5.0):
                for feedback in ("none", "zero_slip", "viso_ot", "truth"):
                    row = {"scenario": scenario, "surface": surface, "camber": camber, "feedback": feedback}
                    row.update(status="completed", truth_rms_m=rng.random())
                    if feedback == "viso_ot":
                        row.update(
                            viso_ot_rms_error_m=0.03,
                            viso_ot_mean_error_m=0.01,
                            viso_ot_max_abs_error_m=0.1,
                            viso_ot_valid_fraction=0.97,
                            mean_matches=312.5,
                            mean_inliers=280.1,
                            inlier_percent=89.6,
                            failed_frames=1,
                        )
                    row.update(
                        zero_slip_rms_error_m=0.2 * rng.random(),
                        true_offtracking_rms_after_warmup_m=0.1 * rng.random(),
                        true_offtracking_max_after_warmup_m=0.3 * rng.random(),
                        saturated_fraction=0.05,
                        wall_time_s=321.0,
                    )
                    rows.append(row)
    rows[5] = {**{k: rows[5][k] for k in ("scenario", "surface", "camber", "feedback")}, "status": "failed"}
    rows[5]["error"] = "SimulationDivergedError: the model left its valid region at t = 41.2 s (jackknife)"
    return pd.DataFrame(rows)


@pytest.mark.parametrize("width", [100, 80])
def test_summary_table_fits_the_terminal_and_keeps_units(width: int) -> None:
    table = _study_table()
    console = Console(width=width, record=True, color_system=None)
    console.print(summary_table(table, width, files=("OUT/table.md", "OUT/table.csv"), title="estimators-under-slip"))
    text = console.export_text()
    lines = text.splitlines()
    assert max(len(line) for line in lines) <= width
    assert "[m]" in text and "[%]" in text  # units survive rich's markup
    assert "status" in text and "failed" in text and "RMS" in text
    assert "OUT/table.md" in " ".join(text.split()) and "OUT/table.csv" in " ".join(text.split())
    assert sum("│" in line for line in lines) == len(table)  # one line per case: no cell wraps


def test_summary_table_names_the_columns_it_leaves_out() -> None:
    table = _study_table()
    console = Console(width=60, record=True, color_system=None)
    console.print(summary_table(table, 60))
    text = " ".join(console.export_text().split())
    assert "more columns" in text and "table.md" in text


@pytest.mark.rendering
def test_animation_of_a_camera_run_shows_the_left_image(
    tmp_path: Path, tmp_path_factory: pytest.TempPathFactory
) -> None:
    """A 0.45 s VISO-OT run (five camera frames) at half the image size under field conditions, made in a child
    process (which owns its renderer; ``field_camera_run.py``, shared with test_camera_assembly.py), animated here
    with the camera."""
    import shutil

    from field_camera_run import field_camera_run

    run_dir = tmp_path / "viso"
    shutil.copytree(field_camera_run(tmp_path_factory), run_dir)  # the animation is written into the run
    out = animate_run(run_dir, fps=10.0, speed=1.0, max_frames=4, size=(640, 360))
    assert out == run_dir / "animation.mp4"
    reader = imageio.get_reader(out)
    try:
        assert reader.get_meta_data()["size"] == (640, 360) and reader.count_frames() == 4
        last = reader.get_data(3)
    finally:
        reader.close()
    # The camera panel (upper right) holds a grey image with coloured feature marks, not an empty axes.
    panel = last[40:200, 260:630].astype(int)
    assert panel.std() > 20
    assert np.any((panel[..., 1] - panel[..., 0] > 80) & (panel[..., 1] - panel[..., 2] > 80))  # green inliers
