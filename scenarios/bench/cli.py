"""The ``offtrack bench`` commands: each prints one JSON object with ``--json``, a table otherwise."""

from __future__ import annotations

from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from ..camera.workers import DEFAULT_WORKERS
from ..cli_format import OfftrackCommand, OfftrackGroup
from ..run.json_output import strict_json

bench_app = typer.Typer(
    help="Benchmarks printing machine-readable results.",
    cls=OfftrackGroup,
    no_args_is_help=True,
    rich_markup_mode=None,
)
console = Console()


@bench_app.command("render", cls=OfftrackCommand)
def bench_render_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    frames: Annotated[int, typer.Option(help="Stereo pairs to render.", min=5)] = 50,
    antialias: Annotated[bool, typer.Option(help="4× multisampling.")] = False,
    field: Annotated[bool, typer.Option(help="Also time field-conditions pairs (sun, shadows, exposure).")] = True,
    supersample: Annotated[
        int, typer.Option(help="Also time pairs of this many samples a pixel side (2 to 4) against one.", min=1, max=4)
    ] = 1,
) -> None:
    """Rendering speed: stereo pairs per second at 1344×391 on the default world, ideal and field conditions."""
    from scenarios.bench.render import bench_render

    figures = bench_render(frames, antialias=antialias, field=field, supersample=supersample)
    _print_bench(figures, as_json, "Render benchmark")


@bench_app.command("vo", cls=OfftrackCommand)
def bench_vo_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    frames: Annotated[int, typer.Option(help="Rendered frames to process (cached after the first run).", min=5)] = 30,
    seed: Annotated[int, typer.Option(help="Scenario seed of the rendered sequence.")] = 0,
    passes: Annotated[int, typer.Option(help="Timed passes; per frame the fastest counts.", min=1)] = 3,
    compare: Annotated[
        list[str] | None,
        typer.Option(
            help="An odometry setting KEY=VALUE (repeatable; VALUE read as --set reads it) of a second odometry timed "
            "beside the default in the same passes, e.g. gradient_refinement=lucas_kanade: its figures and the CPU "
            "ratio."
        ),
    ] = None,
) -> None:
    """Visual odometry alone at 1344×391, one thread: thread CPU ms per frame (median, p90), wall ms, stages, and
    the mean per-frame error against the true motion; with ``--compare`` a second odometry beside it."""
    from scenarios.bench.vo import bench_vo

    changes = None if not compare else dict(_comparison(item) for item in compare)
    _print_bench(bench_vo(frames, seed=seed, passes=passes, compare=changes), as_json, "Visual odometry benchmark")


def _comparison(item: str) -> tuple[str, object]:
    """``KEY=VALUE`` of ``--compare``, its value read as ``--set`` reads one."""
    from scenarios.config import parse_assignment

    if "=" not in item:
        raise ValueError(f"--compare {item!r}: give KEY=VALUE, e.g. gradient_refinement=lucas_kanade")
    return parse_assignment(item)


@bench_app.command("sweep", cls=OfftrackCommand)
def bench_sweep_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    workers: Annotated[int, typer.Option(help="Worker processes to compare with one.", min=2)] = 2,
    cases: Annotated[int, typer.Option(help="Model-only roundabout-3 cases in the sweep.", min=2)] = 8,
    duration: Annotated[float, typer.Option(help="Simulated seconds per case.", min=1.0)] = 20.0,
) -> None:
    """Sweep speed-up: N local worker processes over one on a small model-only study."""
    from scenarios.bench.sweep import bench_sweep

    _print_bench(bench_sweep(workers, cases, duration), as_json, "Sweep benchmark")


@bench_app.command("model", cls=OfftrackCommand)
def bench_model_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    duration: Annotated[float, typer.Option(help="Simulated seconds.", min=1.0)] = 60.0,
    vehicle: Annotated[
        str, typer.Option(help="A preset, or a combination file (.yaml; up to four units, docs/vehicles.md).")
    ] = "reference",
) -> None:
    """Model-only speed: real-time factor of 60 s of a turning manoeuvre at the default step."""
    from scenarios.bench.model import bench_model

    _print_bench(bench_model(duration=duration, vehicle=vehicle), as_json, "Model benchmark")


@bench_app.command("terrain", cls=OfftrackCommand)
def bench_terrain_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    vehicle: Annotated[str, typer.Option(help="The combination (a catalogue name).")] = "lst",
    ticks: Annotated[int, typer.Option(help="States a round, each a new tick.", min=50)] = 1000,
    rounds: Annotated[int, typer.Option(help="Rounds; the figures are their medians.", min=1)] = 3,
) -> None:
    """The model's surface look-up on the rough yard: thread CPU ms a tick with each body's slope from its supports
    against its axles, side by side, and their ratio."""
    from scenarios.bench.terrain import bench_terrain

    _print_bench(bench_terrain(vehicle, ticks, rounds), as_json, "Terrain surface benchmark")


@bench_app.command("loop", cls=OfftrackCommand)
def bench_loop_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    duration: Annotated[float, typer.Option(help="Simulated seconds per run.", min=4.0)] = 15.0,
    workers: Annotated[
        int, typer.Option(help="Render worker processes of the pipelined run.", min=1)
    ] = DEFAULT_WORKERS,
    serial: Annotated[bool, typer.Option(help="Also run it serial, for the speed-up in the same call.")] = True,
) -> None:
    """Rendered closed loop (render + VO + VISO-OT + control): simulated seconds per wall second, CPU shares."""
    from scenarios.bench.loop import bench_loop

    _print_bench(bench_loop(duration, workers, compare_serial=serial), as_json, "Closed-loop benchmark")


@bench_app.command("rigs", cls=OfftrackCommand)
def bench_rigs_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    frames: Annotated[int, typer.Option(help="Frames (every rig rendered in each).", min=5)] = 30,
    vehicle: Annotated[str, typer.Option(help="The combination (a catalogue name).")] = "au-b-double",
    masks: Annotated[bool, typer.Option(help="Mask the other units out of the odometry.")] = True,
    repeats: Annotated[int, typer.Option(help="Repetitions of ceiling and loop; ratios are their medians.", min=1)] = 3,
) -> None:
    """Two rigs (lead trailer's left side, rear trailer's rear) by one render process's context: pipelined loop
    frame rate against the render-only ceiling."""
    from scenarios.bench.rigs import bench_rigs

    _print_bench(bench_rigs(frames, vehicle=vehicle, masks=masks, repeats=repeats), as_json, "Rigs benchmark")


@bench_app.command("optimal", cls=OfftrackCommand)
def bench_optimal_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    duration: Annotated[
        float,
        typer.Option(help="Simulated seconds of the roundabout (the kingpin must drive a trailer length).", min=6.0),
    ] = 8.0,
) -> None:
    """The optimal reference's NLP: CPU seconds of the mapped formulation against the same NLP expanded as a whole,
    on one case, with their ratio and both costs (minutes of CPU)."""
    from scenarios.bench.optimal import bench_optimal

    _print_bench(bench_optimal(duration), as_json, "Optimal reference benchmark")


@bench_app.command("env", cls=OfftrackCommand)
def bench_env_cmd(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    feedback: Annotated[str, typer.Option(help="Model-based feedback source: truth or zero_slip.")] = "truth",
) -> None:
    """Gymnasium steering env: steps per second against the bare co-simulation loop on the same scenario."""
    from scenarios.bench.env import bench_env

    _print_bench(bench_env(feedback=feedback), as_json, "Environment benchmark")


def _print_bench(result: dict, as_json: bool, title: str) -> None:
    if as_json:
        print(strict_json(result, indent=None))
        return
    table = Table(title=title)
    table.add_column("figure")
    table.add_column("value", justify="right")
    for key, value in result.items():
        table.add_row(escape(key), f"{value:.4g}" if isinstance(value, float) else escape(str(value)))
    console.print(table)
