"""The ``offtrack`` command line."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated

import typer
from pydantic import ValidationError
from rich.console import Console
from rich.table import Table

from vehicle_model.errors import OfftrackError

app = typer.Typer(help="Tractor–semi-trailer off-tracking co-simulation.", no_args_is_help=True, add_completion=False)
bench_app = typer.Typer(help="Benchmarks printing machine-readable results.", no_args_is_help=True)
app.add_typer(bench_app, name="bench")
console = Console()


@app.command("list")
def list_presets() -> None:
    """List scenarios, vehicle presets and surface presets."""
    from scenarios.config import catalogue_names, load_scenario_data
    from vehicle_model.presets import VEHICLE_PRESETS
    from vehicle_model.surface import FRICTION_PRESETS

    table = Table(title="Scenarios (offtrack run NAME)")
    table.add_column("name")
    table.add_column("description")
    for name in catalogue_names():
        table.add_row(name, " ".join(str(load_scenario_data(name).get("description", "")).split()))
    console.print(table)

    table = Table(title="Vehicle presets")
    table.add_column("name")
    table.add_column("description")
    for name, factory in VEHICLE_PRESETS.items():
        table.add_row(name, (factory.__doc__ or "").strip().splitlines()[0])
    console.print(table)
    table = Table(title="Surface presets")
    table.add_column("name")
    table.add_column("μ", justify="right")
    for name, mu in FRICTION_PRESETS.items():
        table.add_row(name, f"{mu:.2f}")
    console.print(table)


@app.command()
def run(
    scenario: Annotated[str, typer.Argument(help="Catalogue name (see `offtrack list`) or a YAML file.")],
    surface: Annotated[str | None, typer.Option(help="Surface preset: dry, wet, snow, ice.")] = None,
    mu: Annotated[float | None, typer.Option(help="Friction coefficient (overrides --surface).")] = None,
    camber: Annotated[float | None, typer.Option(help="Camber [%] of the carriageway.")] = None,
    camber_direction: Annotated[
        str | None, typer.Option(help="outward (falls away from the loop centre; adverse) or inward.")
    ] = None,
    speed: Annotated[float | None, typer.Option(help="Cornering speed [km/h].")] = None,
    vehicle: Annotated[str | None, typer.Option(help="Vehicle preset (see `offtrack list`).")] = None,
    direction: Annotated[str | None, typer.Option(help="left or right.")] = None,
    feedback: Annotated[
        str | None, typer.Option(help="Trailer steering fed by: none, truth, zero_slip or viso_ot.")
    ] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of every random choice.")] = None,
    duration: Annotated[float | None, typer.Option(help="Stop after this many simulated seconds.")] = None,
    set_: Annotated[
        list[str] | None, typer.Option("--set", help="Any config field, e.g. --set rates.control_hz=100.")
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Run directory (default runs/SCENARIO/TIMESTAMP).")] = None,
    force: Annotated[bool, typer.Option(help="Allow writing into a non-empty --out.")] = False,
    plots: Annotated[bool, typer.Option(help="Write the plots.")] = True,
) -> None:
    """Run a scenario: time series, metrics.json and plots in a run directory."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from scenarios.config import load_scenario, parse_assignment
    from scenarios.run.results import new_run_dir
    from scenarios.run.runner import run_scenario

    overrides: dict[str, object] = {}
    for key, value in (
        ("surface.preset", surface),
        ("surface.mu", mu),
        ("camber.percent", camber),
        ("camber.direction", camber_direction),
        ("speed.cornering_kmh", speed),
        ("vehicle", vehicle),
        ("direction", direction),
        ("seed", seed),
        ("feedback", feedback),
        ("duration_s", duration),
    ):
        if value is not None:
            overrides[key] = value
    if surface is not None and mu is None:
        overrides["surface.mu"] = None  # a named surface replaces an explicit μ from the file
    for item in set_ or []:
        key, value = parse_assignment(item)
        overrides[key] = value
    config = load_scenario(scenario, overrides)
    run_dir = new_run_dir(out, config.name, force=force)
    with Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TextColumn("{task.percentage:>5.1f} %  t = {task.fields[sim_t]:.1f} s"),
        TimeElapsedColumn(),
        console=console,
        transient=False,
    ) as bar:
        task = bar.add_task(config.name, total=1.0, sim_t=0.0)
        metrics = run_scenario(
            config, run_dir, progress=lambda t, frac: bar.update(task, completed=frac, sim_t=t), plots=plots
        )
    _print_summary(metrics, run_dir)
    if metrics["status"] != "completed":
        console.print(f"[bold yellow]run {metrics['status']}:[/] {metrics['message']}")
        raise typer.Exit(3)


@app.command()
def compare(
    scenario: Annotated[str, typer.Argument(help="Catalogue name (see `offtrack list`) or a YAML file.")],
    surface: Annotated[str | None, typer.Option(help="Surface preset: dry, wet, snow, ice.")] = None,
    mu: Annotated[float | None, typer.Option(help="Friction coefficient (overrides --surface).")] = None,
    camber: Annotated[float | None, typer.Option(help="Camber [%].")] = None,
    camber_direction: Annotated[str | None, typer.Option(help="outward or inward.")] = None,
    vehicle: Annotated[str, typer.Option(help="Vehicle preset with steerable trailer axles.")] = "lst",
    feedbacks: Annotated[
        str, typer.Option(help="Comma-separated feedback sources to compare.")
    ] = "none,zero_slip,viso_ot,truth",
    set_: Annotated[list[str] | None, typer.Option("--set", help="Any config field, e.g. --set path.turns=1.")] = None,
    out: Annotated[Path | None, typer.Option(help="Output directory (default runs/compare-SCENARIO/…).")] = None,
    force: Annotated[bool, typer.Option(help="Allow writing into a non-empty --out.")] = False,
) -> None:
    """Run every feedback source on the same scenario; write a table and one overlay figure."""
    from scenarios.config import load_scenario, parse_assignment
    from scenarios.run.results import new_run_dir
    from scenarios.studies.compare import compare_feedback, comparison_rows_as_text

    overrides: dict[str, object] = {"vehicle": vehicle}
    for key, value in (
        ("surface.preset", surface),
        ("surface.mu", mu),
        ("camber.percent", camber),
        ("camber.direction", camber_direction),
    ):
        if value is not None:
            overrides[key] = value
    if surface is not None and mu is None:
        overrides["surface.mu"] = None
    for item in set_ or []:
        key, value = parse_assignment(item)
        overrides[key] = value
    config = load_scenario(scenario, overrides)
    chosen = tuple(f.strip() for f in feedbacks.split(",") if f.strip())
    run_dir = new_run_dir(out, f"compare-{config.name}", force=force)
    table = compare_feedback(config, run_dir, chosen)
    view = Table(title=f"{config.name}: feedback comparison — {run_dir}")
    headers = [
        "feedback",
        "status",
        "true RMS [m]",
        "true max [m]",
        "max steer [°]",
        "saturated",
        "roundabout",
        "R out [m]",
        "R in [m]",
    ]
    for column in headers:
        view.add_column(column, justify="left" if column in ("feedback", "status") else "right")
    for cells in comparison_rows_as_text(table):
        view.add_row(*cells)
    console.print(view)


@app.command()
def render(
    scenario: Annotated[str, typer.Argument(help="Catalogue name (see `offtrack list`) or a YAML file.")],
    out: Annotated[Path, typer.Option(help="Dataset directory (KITTI odometry layout).")],
    frames: Annotated[int | None, typer.Option(help="Render at most this many camera frames.", min=1)] = None,
    density: Annotated[float | None, typer.Option(help="Scenery density in [0, 1].")] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of the world and the run.")] = None,
    duration: Annotated[float | None, typer.Option(help="Simulated seconds.")] = None,
    set_: Annotated[
        list[str] | None, typer.Option("--set", help="Any config field, e.g. --set camera.baseline=1.5.")
    ] = None,
    video: Annotated[bool, typer.Option(help="Also write a side-by-side stereo video.")] = False,
    antialias: Annotated[bool, typer.Option(help="4× multisampling (slower).")] = False,
    force: Annotated[bool, typer.Option(help="Overwrite an existing dataset in --out.")] = False,
) -> None:
    """Export the scenario's rendered stereo sequence as a KITTI-odometry-style dataset."""
    from rich.progress import Progress

    from scenarios.config import load_scenario, parse_assignment
    from scenarios.export.kitti import export_kitti

    overrides: dict[str, object] = {}
    if seed is not None:
        overrides["seed"] = seed
    if duration is not None:
        overrides["duration_s"] = duration
    for item in set_ or []:
        key, value = parse_assignment(item)
        overrides[key] = value
    config = load_scenario(scenario, overrides)
    with Progress(console=console) as bar:
        task = bar.add_task(f"rendering {config.name}", total=None)
        summary = export_kitti(
            config,
            out,
            max_frames=frames,
            scenery_density=density,
            video=video,
            overwrite=force,
            antialias=antialias,
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )
    console.print({k: v for k, v in summary.items() if not isinstance(v, list | dict)})


@bench_app.command("render")
def bench_render_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    frames: Annotated[int, typer.Option(help="Stereo pairs to render.", min=5)] = 50,
    antialias: Annotated[bool, typer.Option(help="4× multisampling.")] = False,
) -> None:
    """Rendering speed: stereo pairs per second at 1344×391 on the default world."""
    from scenarios.bench.render import bench_render

    _print_bench(bench_render(frames, antialias=antialias), as_json, "Render benchmark")


@bench_app.command("vo")
def bench_vo_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    frames: Annotated[int, typer.Option(help="Rendered frames to process.", min=5)] = 30,
) -> None:
    """Visual odometry alone at 1344×391, one thread, on rendered frames."""
    from scenarios.bench.vo import bench_vo

    _print_bench(bench_vo(frames), as_json, "Visual odometry benchmark")


def _print_bench(result: dict, as_json: bool, title: str) -> None:
    if as_json:
        print(json.dumps(result))
        return
    table = Table(title=title)
    table.add_column("figure")
    table.add_column("value", justify="right")
    for key, value in result.items():
        table.add_row(key, f"{value:.4g}" if isinstance(value, float) else str(value))
    console.print(table)


@app.command()
def study(
    name: Annotated[str, typer.Argument(help="paper-section3 or estimators-under-slip.")],
    full: Annotated[bool, typer.Option(help="Run the whole study (default: a small subset).")] = False,
    out: Annotated[Path | None, typer.Option(help="Output directory (default runs/study-NAME/…).")] = None,
    force: Annotated[bool, typer.Option(help="Allow writing into a non-empty --out.")] = False,
    workers: Annotated[
        int, typer.Option(help="Local worker processes (1: one case after another in this process).", min=1)
    ] = 1,
    scheduler: Annotated[
        str | None, typer.Option(help="Dask scheduler address (e.g. tcp://HOST:8786): run the cases on that cluster.")
    ] = None,
    resume: Annotated[
        bool, typer.Option(help="Skip the cases already finished in --out; failed ones run again.")
    ] = True,
) -> None:
    """Run a study: every case into its own directory, then one table and the figures."""
    from scenarios.run.results import new_run_dir
    from scenarios.studies.definitions import STUDIES, run_study
    from scenarios.studies.progress import rich_progress
    from scenarios.studies.records import CASES_DIR

    if name not in STUDIES:
        raise ValueError(f"unknown study {name!r}; choose one of {sorted(STUDIES)}")
    if out is not None and resume and (out / CASES_DIR).is_dir():
        run_dir = out  # an earlier run of the study: finish it
    else:
        run_dir = new_run_dir(out, f"study-{name}", force=force)
    with rich_progress(name, console=console) as progress:
        table = run_study(
            name, run_dir, full=full, workers=workers, scheduler=scheduler, resume=resume, on_progress=progress
        )
    console.print(f"{len(table)} cases → {run_dir / 'table.md'}")
    console.print((run_dir / "table.md").read_text())
    failed = int((table["status"] == "failed").sum()) if "status" in table.columns else 0
    if failed:
        console.print(
            f"[bold yellow]{failed} case(s) failed[/] (error and traceback in {run_dir / CASES_DIR}/); "
            f"run the same command with --out {run_dir} to retry them"
        )
        raise typer.Exit(3)


@bench_app.command("sweep")
def bench_sweep_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    workers: Annotated[int, typer.Option(help="Worker processes to compare with one.", min=2)] = 2,
    cases: Annotated[int, typer.Option(help="Model-only roundabout-3 cases in the sweep.", min=2)] = 8,
    duration: Annotated[float, typer.Option(help="Simulated seconds per case.", min=1.0)] = 20.0,
) -> None:
    """Sweep speed-up: N local worker processes over one on a small model-only study."""
    from scenarios.bench.sweep import bench_sweep

    _print_bench(bench_sweep(workers, cases, duration), as_json, "Sweep benchmark")


def _print_summary(metrics: dict, run_dir: Path) -> None:
    table = Table(title=f"{metrics['scenario']} — {metrics['status']} — {run_dir}")
    table.add_column("off-tracking")
    table.add_column("RMS [m]", justify="right")
    table.add_column("max |·| [m]", justify="right")
    table.add_column("valid", justify="right")
    truth = metrics["offtracking"]["truth"]
    table.add_row("truth", f"{truth['rms']:.3f}", f"{truth['max_abs']:.3f}", f"{truth['valid_fraction']:.0%}")
    for name, err in metrics["offtracking"]["estimators"].items():
        table.add_row(
            f"{name} error", f"{err['rms_error']:.3f}", f"{err['max_abs_error']:.3f}", f"{err['valid_fraction']:.0%}"
        )
    console.print(table)
    test = metrics.get("roundabout_test")
    if test:
        verdict = "[green]PASS[/]" if test["pass"] else "[red]FAIL[/]"
        console.print(
            f"roundabout test {verdict}: outer radius max {test['outer_radius_max']:.3f} m (limit 12.50), "
            f"inner radius min {test['inner_radius_min']:.3f} m (limit 5.30)"
        )
    console.print(f"simulated {metrics['simulated_s']:.1f} s in {metrics['wall_time_s']:.1f} s wall time")


@bench_app.command("model")
def bench_model_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    duration: Annotated[float, typer.Option(help="Simulated seconds.", min=1.0)] = 60.0,
) -> None:
    """Model-only speed: real-time factor of 60 s of a turning manoeuvre at the default step."""
    from scenarios.bench.model import bench_model

    _print_bench(bench_model(duration=duration), as_json, "Model benchmark")


@bench_app.command("env")
def bench_env_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    feedback: Annotated[str, typer.Option(help="Model-based feedback source: truth or zero_slip.")] = "truth",
) -> None:
    """Gymnasium steering env: steps per second against the bare co-simulation loop on the same scenario."""
    from scenarios.bench.env import bench_env

    _print_bench(bench_env(feedback=feedback), as_json, "Environment benchmark")


@app.command()
def tune(
    trials: Annotated[int, typer.Option(help="Optuna trials (the first is the designed gains).", min=1)] = 30,
    draws: Annotated[int, typer.Option(help="Training draws of the randomised roads per trial.", min=1)] = 3,
    seed: Annotated[int, typer.Option(help="Seed of the draws and of the sampler.", min=0)] = 0,
    feedback: Annotated[str, typer.Option(help="Feedback source: truth, zero_slip or viso_ot.")] = "truth",
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Tune the trailer PID gains with Optuna (offtrack/GainTuning-v0); compare them on held-out roads."""
    from rich.progress import Progress

    from scenarios.envs.tuning import tune_gains

    with Progress(console=console, transient=True, disable=as_json) as bar:
        task = bar.add_task("tuning", total=trials)

        def progress(done: int, total: int, best: float) -> None:
            bar.update(task, completed=done, description=f"tuning: best training cost {best:.5f}")

        result = tune_gains(
            n_trials=trials, train_draws=draws, seed=seed, env_kwargs={"feedback": feedback}, progress=progress
        )
    if as_json:
        print(json.dumps({"benchmark": "tune_gains", **result.to_dict()}))
        return
    print(result.table())
    for condition, better in result.verdicts().items():
        print(f"{condition}: {'tuned' if better else 'designed'} gains better")
    console.print(f"{result.trials} trials, {result.evaluations} scenario runs, {result.wall_s:.0f} s wall time")


def main() -> None:
    """Entry point: run the app and turn known errors into one clear line and exit code 2."""
    try:
        app(standalone_mode=False)
    except (OfftrackError, ValueError, ValidationError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    except typer.Exit as exc:
        raise SystemExit(exc.exit_code) from None
    except typer.Abort:
        raise SystemExit(130) from None
    except Exception as exc:  # click usage errors
        import click

        if isinstance(exc, click.ClickException):
            exc.show()
            raise SystemExit(exc.exit_code) from None
        raise
