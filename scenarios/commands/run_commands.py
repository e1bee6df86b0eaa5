"""The commands of one run: ``list``, ``run``, ``config``, ``report`` and ``export``."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.markup import escape

from .options import (
    FEEDBACKS,
    CamberDirectionOption,
    CamberOption,
    CheckOption,
    DirectionOption,
    DurationOption,
    ForceRunOption,
    MuOption,
    PlotFormatOption,
    PlotsOption,
    RunDirArgument,
    ScenarioArgument,
    SeedOption,
    SetOption,
    SpeedOption,
    SurfaceOption,
    VehicleOption,
)
from .scenario_input import load_config, scenario_overrides, scenario_pairs
from .terminal import console, exit_for_checks, exit_for_status, handled, print_summary, simulation_progress

VEHICLE_CHECK_SCENARIO = "roundabout-test"
"""The scenario a vehicle given alone is checked in (any catalogue scenario that takes every combination)."""

if TYPE_CHECKING:
    from scenarios.config import ScenarioConfig


@handled
def list_presets(
    vehicle: Annotated[
        str | None,
        typer.Option(
            help="Show this combination's specification instead (a preset or a combination file NAME.yaml): units, "
            "dimensions, axle groups and their static loads, mass."
        ),
    ] = None,
) -> None:
    """List scenarios, vehicle presets and surface presets (tables fitted to the terminal's width), or with --vehicle
    one combination's specification."""
    if vehicle is not None:
        from scenarios.catalogue.vehicle_spec import specification_tables, unit_kinds, vehicle_specification

        config = load_config(VEHICLE_CHECK_SCENARIO, {"vehicle": vehicle})
        spec = vehicle_specification(config.vehicle_params(), unit_kinds(config.vehicle))
        for table in specification_tables(spec):
            console.print(table)
        return
    from scenarios.catalogue.listing import preset_tables

    for table in preset_tables():
        console.print(table)


@handled
def run(
    scenario: ScenarioArgument,
    surface: SurfaceOption = None,
    mu: MuOption = None,
    camber: CamberOption = None,
    camber_direction: Annotated[
        str | None, typer.Option(help="outward (falls away from the loop centre; adverse) or inward.")
    ] = None,
    speed: SpeedOption = None,
    vehicle: VehicleOption = None,
    direction: DirectionOption = None,
    feedback: Annotated[
        str | None, typer.Option(help=f"Trailer steering fed by one of: {FEEDBACKS} (its estimator runs).")
    ] = None,
    seed: SeedOption = None,
    duration: DurationOption = None,
    set_: SetOption = None,
    out: Annotated[Path | None, typer.Option(help="Run directory (default runs/SCENARIO/TIMESTAMP).")] = None,
    force: ForceRunOption = False,
    plots: PlotsOption = True,
    plot_format: PlotFormatOption = "png",
    check: CheckOption = False,
) -> None:
    """Run a scenario: time series, metrics.json and plots in a run directory."""
    from scenarios.run.results import check_plot_format, new_run_dir
    from scenarios.run.runner import run_scenario

    plot_format = check_plot_format(plot_format)

    pairs = scenario_pairs(surface, mu, camber, camber_direction, speed, vehicle, direction, seed, feedback, duration)
    config = load_config(scenario, scenario_overrides(pairs, surface, mu, set_))
    run_dir = new_run_dir(out, config.name, force=force)
    with simulation_progress() as bar:
        task = bar.add_task(escape(config.name), total=1.0, sim_t=0.0)
        metrics = run_scenario(
            config,
            run_dir,
            progress=lambda t, frac: bar.update(task, completed=frac, sim_t=t),
            plots=plots,
            plot_format=plot_format,
        )
    print_summary(metrics, run_dir)
    exit_for_status(metrics)
    if check:
        exit_for_checks(metrics)


@handled
def config_command(
    scenario: Annotated[
        str | None,
        typer.Argument(help="Catalogue name or YAML file; with --fields a SECTION (e.g. fusion, camera.lighting)."),
    ] = None,
    fields: Annotated[
        bool, typer.Option("--fields", help="List the configuration's fields: unit, default, range, reason.")
    ] = False,
    surface: SurfaceOption = None,
    mu: MuOption = None,
    camber: CamberOption = None,
    camber_direction: CamberDirectionOption = None,
    speed: SpeedOption = None,
    vehicle: VehicleOption = None,
    direction: DirectionOption = None,
    feedback: Annotated[str | None, typer.Option(help=f"Trailer steering fed by one of: {FEEDBACKS}.")] = None,
    seed: SeedOption = None,
    duration: DurationOption = None,
    set_: SetOption = None,
) -> None:
    """Print a scenario's resolved configuration as YAML (what `offtrack run` with the same options uses), or with
    --fields the fields of the configuration."""
    from vehicle_model.errors import InputError

    pairs = scenario_pairs(surface, mu, camber, camber_direction, speed, vehicle, direction, seed, feedback, duration)
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

    config = load_config(scenario, scenario_overrides(pairs, surface, mu, set_))
    print(config_yaml(config, _road_columns(config)), end="")


def _road_columns(config: ScenarioConfig) -> dict[str, tuple[float, float]] | None:
    """The road file's speed and μ columns that a run of ``config`` drives instead of its speed and surface (the
    road is read and checked as the run reads it), or None without a road file."""
    if config.path.file is None:
        return None
    from scenarios.setup.build import road_columns
    from scenarios.setup.roads import load_road

    spec = config.path
    return road_columns(load_road(spec.file, spec.smoothing, spec.road, spec.lane))


@handled
def report(
    run_dir: RunDirArgument,
    plots: Annotated[bool, typer.Option(help="Redraw the plots.")] = True,
    plot_format: PlotFormatOption = "png",
    check: CheckOption = False,
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
    print_summary(metrics, run_dir)
    if check:  # a run that did not complete has not held what it was asked: its own exit code, as `run` gives
        exit_for_status(metrics)
        exit_for_checks(metrics)


@handled
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
