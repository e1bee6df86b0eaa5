"""The ``offtrack`` command line.

Exit codes (README, "Exit codes"): 0 done; 2 bad input (a usage error, or a value out of range — one line per
bad field, never a traceback); 3 a run that diverged, lost control or could not write a file, or a study with a
failed case; 130
Ctrl-C; 143 SIGTERM. Usage errors are typer's, shown in offtrack's style (``error: …`` and a ``try … --help``
line, exit code 2) by the command classes of :mod:`scenarios.cli_format`, which also make the help readable; every
command body runs under :func:`_command`, which turns offtrack's input errors into exit 2 and a stop into 130/143.
Nothing here depends on typer's vendored click: only ``typer.Exit``, typer's ``cls`` classes and its standalone
handling, tested end to end in ``tests/test_faults.py`` and ``tests/test_config_command.py``.

Why this module is long: it declares every command and its options (one annotated parameter a line, with its help);
each command body only checks its options and calls into its room.
"""

from __future__ import annotations

import errno
import functools
import json
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer
from pydantic import ValidationError
from rich.console import Console
from rich.markup import escape

from scenarios.bench.cli import bench_app
from scenarios.cli_format import OfftrackCommand, OfftrackGroup, offtrack_version
from scenarios.loop.ends import RunStatus
from scenarios.registry import feedback_sources
from scenarios.run.stopping import (
    exit_code_for_signal,
    handle_sigterm,
    raise_pending_stop,
    stop_behind,
    stop_handled,
    stop_message,
    stop_signal_name,
)
from vehicle_model.errors import OfftrackError, OutputError

EXIT_BAD_INPUT = 2
"""Exit code for bad input."""
EXIT_FAILED = 3
"""Exit code for a run that diverged, lost control or could not write a file, or a study with a failed case."""
EXIT_MISSED = 4
"""Exit code of ``--check`` for a run that completed but missed what it was asked to hold."""
CHECK_HELP = (
    "Exit 4 when the run completed but missed what it was asked to hold: a flag of its verdict, a failed "
    "roundabout test."
)
FULL = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS)
"""Errors of a write that found no room (a full disk, a quota, a file too large, a read-only file system): an
:class:`OSError` with one of these that no writer turned into an :class:`~vehicle_model.errors.OutputError` is one
line and exit 3 all the same."""
FEEDBACKS = ", ".join(feedback_sources())
"""The feedback choices (:mod:`scenarios.registry`), for the help texts."""
FORMAT_HELP = "Image format of the plots: png, svg or pdf."

app = typer.Typer(
    help="Tractor–semi-trailer off-tracking co-simulation.",
    cls=OfftrackGroup,
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode=None,  # help texts are plain: "[km/h]" is a unit, not markup
    pretty_exceptions_enable=False,
)
app.add_typer(bench_app, name="bench")
console = Console()
errors = Console(stderr=True, highlight=False, soft_wrap=True)  # a message stays on one line

F = TypeVar("F", bound=Callable[..., Any])


def _command(func: F) -> F:
    """Run a command body: offtrack's input errors → one line and exit 2; Ctrl-C → 130, SIGTERM → 143."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            result = func(*args, **kwargs)
            raise_pending_stop()  # a stop swallowed on the way still ends with its exit code
            return result
        except typer.Exit:
            raise
        except BaseException as exc:
            if (stop := stop_behind(exc)) is not None:  # also a failure a stop caused (inside numba's loading)
                stop_handled()
                errors.print(stop_message(stop), markup=False)
                raise typer.Exit(exit_code_for_signal(stop_signal_name(stop))) from None
            if isinstance(exc, OfftrackError | ValidationError | ValueError):  # a file not writable: failed, 3
                errors.print(f"error: {exc}", markup=False)
                raise typer.Exit(EXIT_FAILED if isinstance(exc, OutputError) else EXIT_BAD_INPUT) from None
            if isinstance(exc, OSError) and exc.errno in FULL:
                where = f"cannot write {exc.filename}" if exc.filename else "a file could not be written"
                errors.print(f"error: {where}: {exc.strerror or exc}", markup=False)
                raise typer.Exit(EXIT_FAILED) from None
            raise

    return wrapper  # type: ignore[return-value]


def _overrides(pairs: tuple[tuple[str, object], ...], surface: str | None, mu: float | None, set_: list[str] | None):
    """Dotted overrides from the options (``None``: not given) and the ``--set`` items."""
    from scenarios.config import parse_assignment

    overrides: dict[str, object] = {key: value for key, value in pairs if value is not None}
    if surface is not None and mu is None:
        overrides["surface.mu"] = None  # a named surface replaces an explicit μ from the file
    for item in set_ or []:
        key, value = parse_assignment(item)
        overrides[key] = value
    return overrides


def _load(scenario: str, overrides: dict[str, object]):
    """The validated scenario (a camera that cannot work is refused by the validation itself)."""
    from scenarios.config import load_scenario

    return load_scenario(scenario, overrides)


def _scenario_pairs(
    surface: str | None,
    mu: float | None,
    camber: float | None,
    camber_direction: str | None,
    speed: float | None,
    vehicle: str | None,
    direction: str | None,
    seed: int | None,
    feedback: str | None,
    duration: float | None,
) -> tuple[tuple[str, object], ...]:
    """The scenario options of ``offtrack run`` (and ``offtrack config``) as (dotted field, value) pairs."""
    return (
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
    )


def _show_version(value: bool) -> None:
    """``--version``: print ``offtrack X.Y.Z`` and stop."""
    if value:
        typer.echo(f"offtrack {offtrack_version()}")
        raise typer.Exit()


@app.callback()
def _options(
    version: Annotated[
        bool,
        typer.Option("--version", help="Print offtrack's version and exit.", callback=_show_version, is_eager=True),
    ] = False,
) -> None:
    """Tractor–semi-trailer off-tracking co-simulation."""


@app.command("list", cls=OfftrackCommand)
@_command
def list_presets() -> None:
    """List scenarios, vehicle presets and surface presets (tables fitted to the terminal's width)."""
    from scenarios.catalogue.listing import preset_tables

    for table in preset_tables():
        console.print(table)


@app.command(cls=OfftrackCommand)
@_command
def run(
    scenario: Annotated[str, typer.Argument(help="Catalogue name (see `offtrack list`) or a YAML file.")],
    surface: Annotated[str | None, typer.Option(help="Surface preset: dry, wet, snow, ice.")] = None,
    mu: Annotated[float | None, typer.Option(help="Friction coefficient (overrides --surface).")] = None,
    camber: Annotated[float | None, typer.Option(help="Camber [%] of the carriageway.")] = None,
    camber_direction: Annotated[
        str | None, typer.Option(help="outward (falls away from the loop centre; adverse) or inward.")
    ] = None,
    speed: Annotated[float | None, typer.Option(help="Cornering speed [km/h].")] = None,
    vehicle: Annotated[
        str | None, typer.Option(help="Vehicle preset (see `offtrack list`) or a combination file NAME.yaml.")
    ] = None,
    direction: Annotated[str | None, typer.Option(help="left or right.")] = None,
    feedback: Annotated[
        str | None, typer.Option(help=f"Trailer steering fed by one of: {FEEDBACKS} (its estimator runs).")
    ] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of every random choice.")] = None,
    duration: Annotated[float | None, typer.Option(help="Stop after this many simulated seconds.")] = None,
    set_: Annotated[
        list[str] | None, typer.Option("--set", help="Any config field, e.g. --set rates.control_hz=100.")
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Run directory (default runs/SCENARIO/TIMESTAMP).")] = None,
    force: Annotated[bool, typer.Option(help="Reuse a non-empty --out: the previous run's files are removed.")] = False,
    plots: Annotated[bool, typer.Option(help="Write the plots.")] = True,
    plot_format: Annotated[str, typer.Option("--format", help=FORMAT_HELP)] = "png",
    check: Annotated[bool, typer.Option(help=CHECK_HELP)] = False,
) -> None:
    """Run a scenario: time series, metrics.json and plots in a run directory."""
    from scenarios.run.results import check_plot_format, new_run_dir
    from scenarios.run.runner import run_scenario

    plot_format = check_plot_format(plot_format)

    pairs = _scenario_pairs(surface, mu, camber, camber_direction, speed, vehicle, direction, seed, feedback, duration)
    config = _load(scenario, _overrides(pairs, surface, mu, set_))
    run_dir = new_run_dir(out, config.name, force=force)
    with _simulation_progress() as bar:
        task = bar.add_task(escape(config.name), total=1.0, sim_t=0.0)
        metrics = run_scenario(
            config,
            run_dir,
            progress=lambda t, frac: bar.update(task, completed=frac, sim_t=t),
            plots=plots,
            plot_format=plot_format,
        )
    _print_summary(metrics, run_dir)
    _exit_for_status(metrics)
    if check:
        _exit_for_checks(metrics)


def _simulation_progress() -> Any:
    """The progress bar of simulated runs: share done, simulated time, elapsed time and ETA."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TextColumn("{task.percentage:>5.1f} %  t = {task.fields[sim_t]:.1f} s"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=console,
        transient=False,
    )


def _exit_for_checks(metrics: dict) -> None:
    """``--check``: say what a completed run missed and exit 4 (nothing missed: return)."""
    from scenarios.run.verdicts import missed_checks

    missed = missed_checks(metrics)
    if missed:
        errors.print(f"check: the run missed {len(missed)} of what it was asked to hold:", markup=False)
        for reason in missed:
            errors.print(f"  {reason}", markup=False, soft_wrap=True)
        raise typer.Exit(EXIT_MISSED)


@app.command("config", cls=OfftrackCommand)
@_command
def config_command(
    scenario: Annotated[
        str | None,
        typer.Argument(help="Catalogue name or YAML file; with --fields a SECTION (e.g. fusion, camera.lighting)."),
    ] = None,
    fields: Annotated[
        bool, typer.Option("--fields", help="List the configuration's fields: unit, default, range, reason.")
    ] = False,
    surface: Annotated[str | None, typer.Option(help="Surface preset: dry, wet, snow, ice.")] = None,
    mu: Annotated[float | None, typer.Option(help="Friction coefficient (overrides --surface).")] = None,
    camber: Annotated[float | None, typer.Option(help="Camber [%] of the carriageway.")] = None,
    camber_direction: Annotated[str | None, typer.Option(help="outward or inward.")] = None,
    speed: Annotated[float | None, typer.Option(help="Cornering speed [km/h].")] = None,
    vehicle: Annotated[
        str | None, typer.Option(help="Vehicle preset (see `offtrack list`) or a combination file NAME.yaml.")
    ] = None,
    direction: Annotated[str | None, typer.Option(help="left or right.")] = None,
    feedback: Annotated[str | None, typer.Option(help=f"Trailer steering fed by one of: {FEEDBACKS}.")] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of every random choice.")] = None,
    duration: Annotated[float | None, typer.Option(help="Stop after this many simulated seconds.")] = None,
    set_: Annotated[
        list[str] | None, typer.Option("--set", help="Any config field, e.g. --set rates.control_hz=100.")
    ] = None,
) -> None:
    """Print a scenario's resolved configuration as YAML (what `offtrack run` with the same options uses), or with
    --fields the fields of the configuration."""
    from vehicle_model.errors import InputError

    pairs = _scenario_pairs(surface, mu, camber, camber_direction, speed, vehicle, direction, seed, feedback, duration)
    if fields:
        from scenarios.config_fields import fields_table, section_fields

        if set_ or any(value is not None for _, value in pairs):
            raise InputError("--fields takes a SECTION only, no --set or scenario options")
        rows = section_fields(scenario)
        title = f"{scenario or 'configuration'}: {len(rows)} field{'s' if len(rows) > 1 else ''} (--set FIELD=VALUE)"
        console.print(fields_table(rows, console.width, title=escape(title)))
        return
    if scenario is None:
        raise InputError("give a SCENARIO (a catalogue name or a YAML file), or --fields [SECTION]")
    from scenarios.run.results import config_yaml

    print(config_yaml(_load(scenario, _overrides(pairs, surface, mu, set_))), end="")


def _exit_for_status(metrics: dict) -> None:
    """Say why a run did not complete and exit with its code (3 failed, 130/143 stopped)."""
    status = metrics["status"]
    if status == RunStatus.COMPLETED:
        return
    errors.print(f"run {status}: {metrics['message']}", markup=False)
    if status == RunStatus.INTERRUPTED:
        raise typer.Exit(exit_code_for_signal(metrics.get("stop_signal")))
    raise typer.Exit(EXIT_FAILED)


@app.command(cls=OfftrackCommand)
@_command
def report(
    run_dir: Annotated[Path, typer.Argument(help="A run directory (config.yaml and timeseries.parquet).")],
    plots: Annotated[bool, typer.Option(help="Redraw the plots.")] = True,
    plot_format: Annotated[str, typer.Option("--format", help=FORMAT_HELP)] = "png",
    check: Annotated[bool, typer.Option(help=CHECK_HELP)] = False,
) -> None:
    """Rebuild metrics.json and the plots of a run from its config and time series (e.g. after a kill)."""
    from scenarios.recorded.report import is_recorded_run, rebuild_recorded_report
    from scenarios.run.report import rebuild_report
    from scenarios.run.results import check_plot_format

    plot_format = check_plot_format(plot_format)
    recorded = is_recorded_run(run_dir)  # offtrack estimate's: recording.yaml for config.yaml
    metrics = (
        rebuild_recorded_report(run_dir, plots, plot_format=plot_format)
        if recorded
        else rebuild_report(run_dir, plots=plots, plot_format=plot_format)
    )
    _print_summary(metrics, run_dir)
    if check and metrics.get("status") == RunStatus.COMPLETED:
        _exit_for_checks(metrics)


@app.command(cls=OfftrackCommand)
@_command
def export(
    run_dir: Annotated[Path, typer.Argument(help="A run directory (timeseries.parquet, config.yaml).")],
    to: Annotated[str, typer.Option(help="csv (header row 'name [unit]') or mat (MATLAB, scipy.io.savemat).")],
    out: Annotated[
        Path | None, typer.Option(help="File, or directory for timeseries.csv/.mat (default: RUN_DIR).")
    ] = None,
    force: Annotated[bool, typer.Option(help="Replace a file already at --out.")] = False,
) -> None:
    """Export a run's time series with its units: CSV, or a MATLAB .mat file with units, descriptions, metadata."""
    from scenarios.export.table import export_run

    path = export_run(run_dir, to, out, force=force)
    console.print(f"time series of {run_dir} → {path}", markup=False, highlight=False, soft_wrap=True)


@app.command(cls=OfftrackCommand)
@_command
def compare(
    scenario: Annotated[str, typer.Argument(help="Catalogue name (see `offtrack list`) or a YAML file.")],
    surface: Annotated[str | None, typer.Option(help="Surface preset: dry, wet, snow, ice.")] = None,
    mu: Annotated[float | None, typer.Option(help="Friction coefficient (overrides --surface).")] = None,
    camber: Annotated[float | None, typer.Option(help="Camber [%].")] = None,
    camber_direction: Annotated[str | None, typer.Option(help="outward or inward.")] = None,
    vehicle: Annotated[
        str, typer.Option(help="Vehicle preset with steerable trailer axles, or a combination file NAME.yaml.")
    ] = "lst",
    feedbacks: Annotated[
        str,
        typer.Option(
            help=f"Comma-separated feedback sources to compare (default: every registered one, {FEEDBACKS}; the "
            "viso_ot ones render the camera).",
            show_default=False,
        ),
    ] = ",".join(feedback_sources()),
    duration: Annotated[float | None, typer.Option(help="Stop every run after this many simulated seconds.")] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", help="Any config field, e.g. --set path.turns=1.")] = None,
    out: Annotated[Path | None, typer.Option(help="Output directory (default runs/compare-SCENARIO/…).")] = None,
    force: Annotated[bool, typer.Option(help="Reuse a non-empty --out: the previous files are removed.")] = False,
    plot_format: Annotated[str, typer.Option("--format", help=FORMAT_HELP)] = "png",
) -> None:
    """Run each feedback source given (default: every one) on the same scenario; write a table and one overlay
    figure."""
    from scenarios.run.results import check_plot_format, new_run_dir
    from scenarios.run.summary import MISSING
    from scenarios.studies.compare import compare_feedback, display_table
    from scenarios.studies.summary import summary_table
    from vehicle_model.errors import InputError

    plot_format = check_plot_format(plot_format)
    chosen = tuple(f.strip() for f in feedbacks.split(",") if f.strip())
    unknown = [f for f in chosen if f not in feedback_sources()]
    if not chosen or unknown:
        raise InputError(f"--feedbacks {feedbacks!r}: give one or more of {FEEDBACKS}, separated by commas")
    if duration is not None and not duration > 0:  # also NaN
        raise InputError(f"--duration {duration:g}: give a positive number of simulated seconds")
    pairs = (
        ("vehicle", vehicle),
        ("surface.preset", surface),
        ("surface.mu", mu),
        ("camber.percent", camber),
        ("camber.direction", camber_direction),
        ("duration_s", duration),
    )
    overrides = _overrides(pairs, surface, mu, set_)
    config = _load(scenario, overrides)
    for feedback in chosen:  # every variant (a camera's included) must be able to run
        _load(scenario, {**overrides, "feedback": feedback})
    run_dir = new_run_dir(out, f"compare-{config.name}", force=force)
    with _simulation_progress() as bar:
        task = bar.add_task(escape(f"{chosen[0]} (1/{len(chosen)})"), total=1.0, sim_t=0.0)

        def progress(feedback: str, t: float, done: float) -> None:
            label = f"{feedback} ({chosen.index(feedback) + 1}/{len(chosen)})"
            bar.update(task, completed=done, sim_t=t, description=escape(label))

        table = compare_feedback(config, run_dir, chosen, progress=progress, plot_format=plot_format)
        bar.update(task, completed=1.0)
    files = (str(run_dir / "comparison.md"), str(run_dir / "comparison.csv"))
    title = f"{config.name}: feedback comparison"
    console.print(
        summary_table(display_table(table), console.width, files=files, title=title, rows="runs", missing=MISSING)
    )


@app.command(cls=OfftrackCommand)
@_command
def render(
    scenario: Annotated[str, typer.Argument(help="Catalogue name (see `offtrack list`) or a YAML file.")],
    out: Annotated[Path, typer.Option(help="Dataset directory (KITTI odometry layout).")],
    frames: Annotated[int | None, typer.Option(help="Render at most this many camera frames.", min=1)] = None,
    density: Annotated[float | None, typer.Option(help="Scenery density in [0, 1].", min=0.0, max=1.0)] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of the world and the run.", min=0)] = None,
    duration: Annotated[float | None, typer.Option(help="Simulated seconds.")] = None,
    set_: Annotated[
        list[str] | None, typer.Option("--set", help="Any config field, e.g. --set camera.baseline=1.5.")
    ] = None,
    video: Annotated[bool, typer.Option(help="Also write a side-by-side stereo video.")] = False,
    antialias: Annotated[bool, typer.Option(help="4× multisampling (slower).")] = False,
    force: Annotated[bool, typer.Option(help="Replace an earlier dataset in --out (offtrack's files only).")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Export the scenario's rendered stereo sequence as a KITTI-odometry-style dataset."""
    from rich.progress import Progress

    from scenarios.export.kitti import export_kitti, render_summary
    from scenarios.run.files import jsonable
    from scenarios.run.results import check_output_dir

    pairs = (("seed", seed), ("duration_s", duration), ("camera.scenery_density", density))
    config = _load(scenario, _overrides(pairs, None, None, set_))
    check_output_dir(out)
    with Progress(console=console, transient=True, disable=as_json) as bar:
        task = bar.add_task(escape(f"rendering {config.name}"), total=None)
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
    if as_json:
        print(json.dumps(jsonable(summary), allow_nan=False))
        return
    console.print(render_summary(summary), markup=False, highlight=False, soft_wrap=True)


@app.command(cls=OfftrackCommand)
@_command
def estimate(
    recording: Annotated[
        Path, typer.Argument(help="KITTI-odometry folder, ROS 1/2 bag, or the left video (with --right-video).")
    ],
    rig: Annotated[Path, typer.Option(help="Rig YAML: vehicle, psi_c2v_deg, lever_arm_m [, follow_point_offset_m].")],
    out: Annotated[Path | None, typer.Option(help="Run directory (default runs/recording-NAME/TIMESTAMP).")] = None,
    force: Annotated[bool, typer.Option(help="Reuse a non-empty --out: the previous run's files are removed.")] = False,
    calibration: Annotated[
        Path | None, typer.Option(help="OpenCV YAML of offtrack calibrate: raw images, rectified on the fly.")
    ] = None,
    calib: Annotated[
        Path | None, typer.Option(help="KITTI calib.txt of rectified images (default: the folder's).")
    ] = None,
    right_video: Annotated[Path | None, typer.Option(help="The right camera's video (RECORDING the left one).")] = None,
    times: Annotated[Path | None, typer.Option(help="One time per video frame [s].")] = None,
    left_topic: Annotated[str | None, typer.Option(help="Bag: the left camera's image topic.")] = None,
    right_topic: Annotated[str | None, typer.Option(help="Bag: the right camera's image topic.")] = None,
    pair_tolerance: Annotated[
        float | None, typer.Option(help="Bag: largest left-right stamp difference [s] (default: interval/4).")
    ] = None,
    signals: Annotated[
        Path | None, typer.Option(help="CSV time_s, speed_m_s, yaw_rate_deg_s, articulation_deg: fused + zero-slip.")
    ] = None,
    reference: Annotated[Path | None, typer.Option(help="Reference camera poses (KITTI or TUM).")] = None,
    reference_format: Annotated[str | None, typer.Option(help="kitti or tum (default: from the file).")] = None,
    reference_offtracking: Annotated[
        Path | None, typer.Option(help="Reference off-tracking CSV: time_s, offtracking_m.")
    ] = None,
    folder_poses: Annotated[bool, typer.Option(help="Use a KITTI folder's poses.txt as the reference.")] = True,
    refinement: Annotated[int, typer.Option(help="Odometry match refinement: 0, 1 pixel, 2 sub-pixel.")] = 2,
    seed: Annotated[int, typer.Option(help="Seed of the odometry's RANSAC.", min=0)] = 0,
    rear_point: Annotated[
        str,
        typer.Option(
            help="The tractor's rear point of the zero-slip and fused estimates: axle_mean, equivalent, "
            "speed_compensated or lateral_acceleration (needs lateral_acceleration_m_s2 in --signals)."
        ),
    ] = "axle_mean",
    plots: Annotated[bool, typer.Option(help="Write the plots.")] = True,
) -> None:
    """VISO-OT (and with --signals the fused and zero-slip estimates) on a recorded stereo sequence: a run directory
    like a simulated run's (offtrack report and offtrack animate take it)."""
    from rich.progress import Progress

    from scenarios.recorded.estimate import estimate_recording
    from scenarios.recorded.inputs import resolve_inputs
    from scenarios.recorded.report import recording_lines
    from scenarios.run.results import check_output_dir, new_run_dir

    if out is not None:
        check_output_dir(out)
    inputs = resolve_inputs(
        recording,
        rig=rig,
        calibration=calibration,
        calib=calib,
        right_video=right_video,
        times=times,
        left_topic=left_topic,
        right_topic=right_topic,
        pair_tolerance=pair_tolerance,
        signals=signals,
        reference=reference,
        reference_format=reference_format,
        reference_offtracking=reference_offtracking,
        use_folder_poses=folder_poses,
        refinement=refinement,
        seed=seed,
        rear_point=rear_point,
    )
    run_dir = new_run_dir(out, f"recording-{recording.resolve().name}", force=force)
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task(escape(f"estimating on {recording.name}"), total=len(inputs.recording.slots))
        metrics = estimate_recording(
            inputs, run_dir, plots=plots, progress=lambda done, _: bar.update(task, completed=done)
        )
    _print_summary(metrics, run_dir)
    for line in recording_lines(metrics):
        console.print(escape(line))
    _exit_for_status(metrics)


@app.command("vo-eval", cls=OfftrackCommand)
@_command
def vo_eval(
    sequence: Annotated[Path, typer.Argument(help="KITTI-odometry folder (image_0/, image_1/, times.txt).")],
    poses: Annotated[
        Path | None, typer.Option(help="The left camera's poses, KITTI format (default poses.txt).")
    ] = None,
    calibration: Annotated[Path | None, typer.Option(help="OpenCV YAML of offtrack calibrate (raw images).")] = None,
    calib: Annotated[Path | None, typer.Option(help="KITTI calib.txt (default: the folder's).")] = None,
    refinement: Annotated[int, typer.Option(help="Odometry match refinement: 0, 1 pixel, 2 sub-pixel.")] = 2,
    seed: Annotated[int, typer.Option(help="Seed of the odometry's RANSAC.", min=0)] = 0,
    out: Annotated[Path | None, typer.Option(help="Write vo_eval.json and drift.png here.")] = None,
    force: Annotated[bool, typer.Option(help="Reuse a non-empty --out (offtrack's files only).")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """The visual odometry on a KITTI-format sequence with poses: KITTI metric, per-frame error, drift plot."""
    from rich.progress import Progress

    from scenarios.recorded.vo_eval import evaluate_vo, plot_drift, result_lines
    from scenarios.run.files import jsonable, write_atomic
    from scenarios.run.results import check_output_dir, new_run_dir

    if out is not None:
        check_output_dir(out)
    with Progress(console=console, transient=True, disable=as_json) as bar:
        task = bar.add_task(escape(f"odometry on {sequence.name}"), total=None)
        result, arrays = evaluate_vo(
            sequence,
            poses=poses,
            calibration=calibration,
            calib=calib,
            refinement=refinement,
            seed=seed,
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )
    if out is not None:
        run_dir = new_run_dir(out, "vo-eval", force=force)
        write_atomic(run_dir / "vo_eval.json", json.dumps(jsonable(result), indent=2, allow_nan=False))
        plot_drift(run_dir / "drift.png", result, arrays)
    if as_json:
        print(json.dumps(jsonable(result), allow_nan=False))
        return
    for line in result_lines(result):
        console.print(escape(line))


@app.command(cls=OfftrackCommand)
@_command
def study(
    name: Annotated[str, typer.Argument(help="The study (an unknown name lists them all).")],
    full: Annotated[bool, typer.Option(help="Run the whole study (default: a small subset).")] = False,
    out: Annotated[Path | None, typer.Option(help="Output directory (default runs/study-NAME/…).")] = None,
    force: Annotated[bool, typer.Option(help="Reuse a non-empty --out: the previous files are removed.")] = False,
    workers: Annotated[
        int, typer.Option(help="Local worker processes (1: one case after another in this process).", min=1)
    ] = 1,
    scheduler: Annotated[
        str | None, typer.Option(help="Dask scheduler address (e.g. tcp://HOST:8786): run the cases on that cluster.")
    ] = None,
    resume: Annotated[
        bool, typer.Option(help="Skip the cases already finished in --out; failed ones run again.")
    ] = True,
    vehicle: Annotated[
        str | None,
        typer.Option(
            help="Another combination (preset or NAME.yaml) for unit-steering or estimators-under-slip; "
            "it needs a steerable towed unit."
        ),
    ] = None,
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="A run setting for every case, e.g. --set fusion.kinematic_error_model=state."),
    ] = None,
) -> None:
    """Run a study: every case into its own directory, then one table and the figures."""
    from scenarios.config import parse_assignment
    from scenarios.run.results import new_run_dir
    from scenarios.studies.definitions import STUDIES, check_study_vehicle, run_study, study_cases
    from scenarios.studies.progress import rich_progress
    from scenarios.studies.records import CASES_DIR
    from vehicle_model.errors import InputError

    if name not in STUDIES:
        raise InputError(f"unknown study {name!r}; choose one of {', '.join(sorted(STUDIES))}")
    for note in check_study_vehicle(name, vehicle):  # a vehicle it cannot drive: refused before any work
        errors.print(f"note: {note}", markup=False)
    settings = dict(parse_assignment(item) for item in set_ or [])
    if settings:
        study_cases(name, full, vehicle, settings)  # settings a case refuses: one line, before any work
    if out is not None and resume and (out / CASES_DIR).is_dir():
        run_dir = out  # an earlier run of the study: finish it
    else:
        run_dir = new_run_dir(out, f"study-{name}", force=force)
    with rich_progress(name, console=console) as progress:
        table = run_study(
            name,
            run_dir,
            full=full,
            workers=workers,
            scheduler=scheduler,
            resume=resume,
            on_progress=progress,
            vehicle=vehicle,
            settings=settings,
        )
    _print_study_summary(table, run_dir, name)
    failed = int((table["status"] == RunStatus.FAILED).sum()) if "status" in table.columns else 0
    if failed:
        errors.print(
            f"{failed} case(s) failed (error and traceback in {run_dir / CASES_DIR}/); "
            f"run the same command with --out {run_dir} to retry them",
            markup=False,
        )
        raise typer.Exit(EXIT_FAILED)


@app.command(cls=OfftrackCommand)
@_command
def assess(
    combination: Annotated[str, typer.Argument(help="The combination: a preset's name or a combination YAML file.")],
    feedback: Annotated[
        list[str] | None,
        typer.Option(
            help="Feedback steering every steerable towed unit (repeatable): none, truth, zero_slip, viso_ot_fused."
        ),
    ] = None,
    side_by_side: Annotated[
        bool, typer.Option(help="Compare unsteered, truth-, zero-slip- (and for one semi-trailer VISO-OT-) fed.")
    ] = False,
    surface: Annotated[
        list[str] | None, typer.Option(help="Surface preset, repeatable: dry, wet, snow, ice (default dry).")
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Output directory (default runs/assess-NAME/…).")] = None,
    force: Annotated[bool, typer.Option(help="Reuse a non-empty --out: the previous files are removed.")] = False,
    workers: Annotated[
        int, typer.Option(help="Local worker processes (1: one case after another in this process).", min=1)
    ] = 1,
    scheduler: Annotated[
        str | None, typer.Option(help="Dask scheduler address (e.g. tcp://HOST:8786): run the cases on that cluster.")
    ] = None,
    resume: Annotated[
        bool, typer.Option(help="Skip the cases already finished in --out; failed ones run again.")
    ] = True,
    plot_format: Annotated[str, typer.Option("--format", help=FORMAT_HELP)] = "png",
) -> None:
    """Assess one combination: the PBS measures a yaw-plane model supports and the UK/EU turning circle, each on its
    manoeuvre, into assessment.md / .csv / .json with a figure per measure (docs/pbs.md)."""
    from scenarios.run.results import check_plot_format, new_run_dir
    from scenarios.studies.pbs_assessment import assessment_cases, run_assessment, side_by_side_feedbacks
    from scenarios.studies.progress import rich_progress
    from scenarios.studies.records import CASES_DIR

    plot_format = check_plot_format(plot_format)
    surfaces = tuple(surface or ("dry",))
    feedbacks = side_by_side_feedbacks(combination) if side_by_side else tuple(feedback or ("none",))
    assessment_cases(combination, feedbacks, surfaces)  # every option checked before any work
    name = Path(combination).stem if combination.endswith((".yaml", ".yml")) else combination
    if out is not None and resume and (out / CASES_DIR).is_dir():
        run_dir = out
    else:
        run_dir = new_run_dir(out, f"assess-{name}", force=force)
    with rich_progress(f"assess {name}", console=console) as progress:
        table = run_assessment(
            combination,
            run_dir,
            feedbacks,
            surfaces,
            workers=workers,
            scheduler=scheduler,
            resume=resume,
            on_progress=progress,
            plot_format=plot_format,
        )
    console.print(f"assessment: {run_dir / 'assessment.md'} (and .csv, .json, measure-*.{plot_format})")
    failed = int((table["status"] == RunStatus.FAILED).sum()) if "status" in table.columns else 0
    if failed:
        errors.print(
            f"{failed} case(s) failed (error and traceback in {run_dir / CASES_DIR}/); "
            f"run the same command with --out {run_dir} to retry them",
            markup=False,
        )
        raise typer.Exit(EXIT_FAILED)


def _print_study_summary(table, run_dir: Path, name: str) -> None:
    """The columns that matter, to the terminal's width; the rest is in table.md / table.csv."""
    from scenarios.studies.summary import summary_table

    files = (str(run_dir / "table.md"), str(run_dir / "table.csv"))
    console.print(summary_table(table, console.width, files=files, title=f"{name}: {len(table)} cases"))


def _print_summary(metrics: dict, run_dir: Path) -> None:
    """The closing table of a run and its verdicts (:func:`scenarios.run.summary.run_summary`)."""
    from scenarios.run.summary import run_summary

    for item in run_summary(metrics, run_dir):
        console.print(item)


@app.command(cls=OfftrackCommand)
@_command
def calibrate(
    scenario: Annotated[
        str | None, typer.Argument(help="Catalogue name or YAML file: its rendered camera is calibrated.")
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Directory for calibration.yaml and residuals.json.")] = None,
    set_: Annotated[
        list[str] | None, typer.Option("--set", help="Any config field, e.g. --set camera.calibration.views=30.")
    ] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of the target poses and the noise.", min=0)] = None,
    force: Annotated[bool, typer.Option(help="Reuse a non-empty --out (offtrack's files only).")] = False,
    images: Annotated[
        Path | None, typer.Option(help="Folder of photos of a board: left*/right* files, or left/ and right/ folders.")
    ] = None,
    left: Annotated[str | None, typer.Option(help="Glob of the left photos (with --right).")] = None,
    right: Annotated[str | None, typer.Option(help="Glob of the right photos (with --left).")] = None,
    pattern: Annotated[str, typer.Option(help="Board: chessboard or charuco.")] = "chessboard",
    corners: Annotated[
        str, typer.Option(help="Inner corners COLSxROWS (a ChArUco board has one more square).")
    ] = "9x6",
    square: Annotated[float, typer.Option(help="Side of a square [m].")] = 0.025,
    marker: Annotated[float | None, typer.Option(help="ChArUco marker side [m] (default 0.75 × square).")] = None,
    dictionary: Annotated[str, typer.Option(help="ChArUco ArUco dictionary (OpenCV name).")] = "DICT_4X4_50",
    min_views: Annotated[int, typer.Option(help="Fewest views with the board in both photos.")] = 5,
    alpha: Annotated[float, typer.Option(help="stereoRectify's free scaling: 0 valid pixels only, 1 all.")] = 0.0,
    corner_window: Annotated[
        int | None, typer.Option(help="cornerSubPix half-window [px] (default: a third of the corner spacing).")
    ] = None,
    reject_outliers: Annotated[
        bool, typer.Option("--reject-outliers/--keep-outliers", help="Reject views whose RMS is far above the median.")
    ] = True,
) -> None:
    """Calibrate a stereo camera (OpenCV): from photos of a board (--images or --left/--right), or the scenario's
    rendered camera on a rendered checkerboard. Writes calibration.yaml and residuals.json (and calibration.png).

    A run uses the file with --set camera.calibration.mode=file --set camera.calibration.file=OUT/calibration.yaml;
    offtrack estimate with --calibration OUT/calibration.yaml.
    """
    from vehicle_model.errors import InputError

    if out is None:
        raise InputError("--out DIR is required: the directory for calibration.yaml and residuals.json")
    if images is not None or left is not None or right is not None:
        if scenario is not None or set_ or seed is not None:
            raise InputError("photos (--images, --left/--right) take no SCENARIO, --set or --seed")
        _calibrate_photos(
            out,
            force,
            corners,
            images=images,
            left=left,
            right=right,
            pattern=pattern,
            square=square,
            marker=marker,
            dictionary=dictionary,
            min_views=min_views,
            alpha=alpha,
            corner_window=corner_window,
            reject_outliers=reject_outliers,
        )
        return
    if scenario is None:
        raise InputError("give a SCENARIO (its rendered camera), or photos with --images DIR or --left/--right GLOB")
    from scenarios.camera.build import calibration_target_rig, lenses, rig_from_config, run_calibration
    from scenarios.run.files import write_atomic
    from scenarios.run.results import new_run_dir
    from sensor.calibration_report import calibration_line, calibration_summary

    config = _load(scenario, _overrides((("seed", seed),), None, None, set_))
    run_dir = new_run_dir(out, "calibration", force=force)
    rig = rig_from_config(config)
    with console.status("calibrating: imaging the target and solving"):
        result = run_calibration(rig, config)
    path = result.write(run_dir / "calibration.yaml")
    summary = calibration_summary(result, calibration_target_rig(rig, config), *lenses(config))
    write_atomic(run_dir / "residuals.json", json.dumps(summary, indent=2, default=float))
    console.print(escape(f"calibration → {path}; residuals → {run_dir / 'residuals.json'}"))
    console.print(calibration_line(summary))


def _calibrate_photos(out: Path, force: bool, corners: str, **options: Any) -> None:
    """``offtrack calibrate`` on photos (:mod:`scenarios.recorded.calibrate`): files, then a table of the views."""
    from scenarios.recorded.calibrate import board_pattern, calibrate_from_photos, check_photos, report_lines
    from scenarios.run.results import check_output_dir, new_run_dir

    board = board_pattern(corners, **{k: options.pop(k) for k in ("pattern", "square", "marker", "dictionary")})
    check_output_dir(out)
    check_photos(options["images"], options["left"], options["right"])  # refused before the directory is made
    run_dir = new_run_dir(out, "calibration", force=force)
    with console.status("calibrating: finding the board and solving"):
        calibration, report = calibrate_from_photos(run_dir, board, **options)
    for line in report_lines(calibration, report, run_dir):
        console.print(line)


@app.command(cls=OfftrackCommand)
@_command
def animate(
    run_dir: Annotated[Path, typer.Argument(help="A run directory (config.yaml and timeseries.parquet).")],
    out: Annotated[Path | None, typer.Option(help="Video file (.mp4 or .gif; default RUN_DIR/animation.mp4).")] = None,
    fps: Annotated[float, typer.Option(help="Video frames per second.", min=1.0, max=60.0)] = 10.0,
    speed: Annotated[float, typer.Option(help="Simulated seconds per video second.", min=0.1, max=100.0)] = 4.0,
    max_frames: Annotated[
        int | None, typer.Option(help="At most this many frames, spread over the run.", min=2)
    ] = None,
    camera: Annotated[
        bool | None, typer.Option(help="Show the left camera with its matched features (default: if it ran).")
    ] = None,
) -> None:
    """Animate a run from its directory: plan view, off-tracking traces and, for camera runs, the camera image."""
    from rich.progress import Progress

    from scenarios.export.animation import animate_run
    from scenarios.recorded.report import is_recorded_run

    recorded = is_recorded_run(run_dir)  # offtrack estimate's run
    if not recorded and not (run_dir / "config.yaml").is_file():
        from vehicle_model.errors import InputError

        raise InputError(f"RUN_DIR {run_dir} holds no config.yaml: give the directory of an offtrack run")
    if recorded:
        from scenarios.recorded.animation import animate_recorded_run as animate_run  # type: ignore[no-redef]
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task("animating", total=None)
        path = animate_run(
            run_dir,
            out,
            fps=fps,
            max_frames=max_frames,
            speed=speed,
            camera=camera,
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )
    console.print(escape(f"animation → {path}"))


@app.command(cls=OfftrackCommand)
@_command
def tune(
    trials: Annotated[int, typer.Option(help="Optuna trials (the first is the designed gains).", min=1)] = 30,
    draws: Annotated[int, typer.Option(help="Training draws of the randomised roads per trial.", min=1)] = 3,
    seed: Annotated[int, typer.Option(help="Seed of the draws and of the sampler.", min=0)] = 0,
    feedback: Annotated[
        str, typer.Option(help=f"Feedback source, one of: {FEEDBACKS.removeprefix('none, ')}.")
    ] = "truth",
    scenario: Annotated[
        str, typer.Option(help="Scenario driven (catalogue name or YAML file), a quarter turn of it: path.turns=0.25.")
    ] = "roundabout-3",
    out: Annotated[
        Path | None,
        typer.Option(help="Write trials.csv, comparison.csv/.md and tuned_gains.yaml (a scenario a run loads) here."),
    ] = None,
    force: Annotated[bool, typer.Option(help="Reuse a non-empty --out: the previous files are removed.")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Tune the trailer PID gains with Optuna (offtrack/GainTuning-v0); compare them on held-out roads."""
    from rich.progress import Progress

    from scenarios.envs.scenario import DEFAULT_OVERRIDES
    from scenarios.envs.tuning import tune_gains
    from scenarios.envs.tuning_report import gains_table, held_out_table, set_options, write_tuning
    from scenarios.run.results import new_run_dir

    base = _load(scenario, {"feedback": feedback, "vehicle": "lst"})  # the gains' scenario, refused before tuning
    out_dir = None if out is None else new_run_dir(out, "tune", force=force)
    with Progress(console=console, transient=True, disable=as_json) as bar:
        task = bar.add_task("tuning", total=trials)

        def progress(done: int, total: int, best: float) -> None:
            bar.update(task, completed=done, description=f"tuning: best training cost {best:.5f}")

        env_kwargs = {"feedback": feedback, "scenario": scenario, "overrides": dict(DEFAULT_OVERRIDES)}
        result = tune_gains(n_trials=trials, train_draws=draws, seed=seed, env_kwargs=env_kwargs, progress=progress)
    paths = None if out_dir is None else write_tuning(result, out_dir, base)
    if as_json:
        files = None if paths is None else {key: str(path) for key, path in paths.items()}
        print(json.dumps({"benchmark": "tune_gains", **result.to_dict(), "files": files}))
        return
    console.print(gains_table(result))
    console.print(held_out_table(result))
    for condition, better in result.verdicts().items():
        console.print(f"{condition}: {'tuned' if better else 'designed'} gains better", markup=False)
    console.print(f"{result.trials} trials, {result.evaluations} scenario runs, {result.wall_s:.0f} s wall time")
    console.print(f"apply the tuned gains: {set_options(result.tuned)}", markup=False, highlight=False, soft_wrap=True)
    if paths is not None:
        console.print(
            f"trials, comparison and gains in {paths['gains'].parent}; offtrack run {paths['gains']} runs {scenario} "
            "with them",
            markup=False,
            highlight=False,
        )


def main() -> None:
    """Entry point of ``offtrack``: SIGTERM is handled like Ctrl-C, then typer runs the command.

    Typer's standalone mode prints usage errors (unknown option or command, a value of the wrong type or out
    of an option's range; in offtrack's style, :mod:`scenarios.cli_format`) with exit code 2 and turns
    ``typer.Exit`` into the process's exit code.
    """
    handle_sigterm()
    app(prog_name="offtrack")


if __name__ == "__main__":  # python -m scenarios.cli, the same as the offtrack script
    main()
