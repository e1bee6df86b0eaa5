"""The options that several commands take, each declared once: its type, its flag and its help.

A command names one in its signature (``surface: SurfaceOption = None``); typer reads the flag from the parameter's
name (``--surface``) unless the declaration gives one (``--set``, ``--format``, ``--json``). An option with the
same name but a different help in another command (``--camber`` of ``compare``, ``--seed`` of ``render``) is a
different option and is declared at that command.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from scenarios.registry import feedback_sources

FEEDBACKS = ", ".join(feedback_sources())
"""The feedback choices (:mod:`scenarios.registry`), for the help texts."""
FORMAT_HELP = "Image format of the plots: png, svg or pdf."
CHECK_HELP = (
    "Exit 4 when the run completed but missed what it was asked to hold: a flag of its verdict, a failed "
    "roundabout test."
)

# The scenario and its options (offtrack run, config, compare, render).
ScenarioArgument = Annotated[str, typer.Argument(help="Catalogue name (see `offtrack list`) or a YAML file.")]
SurfaceOption = Annotated[str | None, typer.Option(help="Surface preset: dry, wet, snow, ice.")]
MuOption = Annotated[float | None, typer.Option(help="Friction coefficient (overrides --surface).")]
CamberOption = Annotated[float | None, typer.Option(help="Camber [%] of the carriageway.")]
CamberDirectionOption = Annotated[str | None, typer.Option(help="outward or inward.")]
SpeedOption = Annotated[float | None, typer.Option(help="Cornering speed [km/h].")]
VehicleOption = Annotated[
    str | None, typer.Option(help="Vehicle preset (see `offtrack list`) or a combination file NAME.yaml.")
]
DirectionOption = Annotated[str | None, typer.Option(help="left or right.")]
SeedOption = Annotated[int | None, typer.Option(help="Seed of every random choice.")]
DurationOption = Annotated[float | None, typer.Option(help="Stop after this many simulated seconds.")]
SetOption = Annotated[
    list[str] | None, typer.Option("--set", help="Any config field, e.g. --set rates.control_hz=100.")
]

# Run directories and what is written into them.
RunDirArgument = Annotated[Path, typer.Argument(help="A run directory (config.yaml and timeseries.parquet).")]
ForceRunOption = Annotated[bool, typer.Option(help="Reuse a non-empty --out: the previous run's files are removed.")]
ForceOption = Annotated[bool, typer.Option(help="Reuse a non-empty --out: the previous files are removed.")]
ForceOfftrackFilesOption = Annotated[bool, typer.Option(help="Reuse a non-empty --out (offtrack's files only).")]
PlotsOption = Annotated[bool, typer.Option(help="Write the plots.")]
PlotFormatOption = Annotated[str, typer.Option("--format", help=FORMAT_HELP)]
CheckOption = Annotated[bool, typer.Option(help=CHECK_HELP)]
JsonOption = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]

# Many cases (offtrack study, assess).
WorkersOption = Annotated[
    int, typer.Option(help="Local worker processes (1: one case after another in this process).", min=1)
]
SchedulerOption = Annotated[
    str | None, typer.Option(help="Dask scheduler address (e.g. tcp://HOST:8786): run the cases on that cluster.")
]
ResumeOption = Annotated[bool, typer.Option(help="Skip the cases already finished in --out; failed ones run again.")]

# The visual odometry on recorded images (offtrack estimate, vo-eval).
RefinementOption = Annotated[int, typer.Option(help="Odometry match refinement: 0, 1 pixel, 2 sub-pixel.")]
OdometrySeedOption = Annotated[int, typer.Option(help="Seed of the odometry's RANSAC.", min=0)]
