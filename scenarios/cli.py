"""The ``offtrack`` command line."""

from __future__ import annotations

import json
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
    """List vehicle and surface presets."""
    from vehicle_model.presets import VEHICLE_PRESETS
    from vehicle_model.surface import FRICTION_PRESETS

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
def demo(
    out: Annotated[Path, typer.Option(help="Output directory.")] = Path("runs/demo"),
    vehicle: Annotated[str, typer.Option(help="Vehicle preset (see `offtrack list`).")] = "reference",
    surface: Annotated[str, typer.Option(help="Surface preset: dry, wet, snow, ice.")] = "dry",
    speed: Annotated[float, typer.Option(help="Speed [km/h].", min=1.0, max=60.0)] = 15.0,
) -> None:
    """Model demo: a full circle at roundabout size, with a plan-view plot."""
    from scenarios.demo import run_demo

    summary = run_demo(out, vehicle=vehicle, surface=surface, speed_kmh=speed)
    table = Table(title=f"Demo written to {out}")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    for key, value in summary.items():
        table.add_row(key, f"{value:.3f}" if isinstance(value, float) else str(value))
    console.print(table)


@bench_app.command("model")
def bench_model_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    duration: Annotated[float, typer.Option(help="Simulated seconds.", min=1.0)] = 60.0,
) -> None:
    """Model-only speed: real-time factor of 60 s of a turning manoeuvre at the default step."""
    from scenarios.bench import bench_model

    result = bench_model(duration=duration)
    if as_json:
        print(json.dumps(result))
    else:
        table = Table(title="Model benchmark")
        table.add_column("figure")
        table.add_column("value", justify="right")
        for key, value in result.items():
            table.add_row(key, f"{value:.4g}" if isinstance(value, float) else str(value))
        console.print(table)


def main() -> None:
    """Entry point: run the app and turn known errors into one clear line and exit code 2."""
    try:
        app(standalone_mode=False)
    except (OfftrackError, ValueError, ValidationError) as exc:
        console.print(f"[bold red]error:[/] {exc}")
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
