"""The ``offtrack`` command line.

Exit codes (README, "Exit codes"): 0 done; 2 bad input (a usage error, or a value out of range — one line per
bad field, never a traceback); 3 a run that diverged, lost control or could not write a file, or a study with a
failed case; 130
Ctrl-C; 143 SIGTERM. Usage errors are typer's, shown in offtrack's style (``error: …`` and a ``try … --help``
line, exit code 2) by the command classes of :mod:`scenarios.cli_format`, which also make the help readable; every
command body runs under :func:`scenarios.commands.terminal.handled`, which turns offtrack's input errors into exit 2
and a stop into 130/143.
Nothing here depends on typer's vendored click: only ``typer.Exit``, typer's ``cls`` classes and its standalone
handling, tested end to end in ``tests/test_faults.py`` and ``tests/test_config_command.py``.

This module makes the app and registers the commands, in the order ``offtrack --help`` lists them; the commands
live in :mod:`scenarios.commands`, one module a room, and the options several of them take are declared once
(:mod:`scenarios.commands.options`). Each command body only checks its options and calls into its room.
"""

from __future__ import annotations

from typing import Annotated

import typer

from scenarios.bench.cli import bench_app
from scenarios.cli_format import OfftrackCommand, OfftrackGroup, offtrack_version
from scenarios.commands.camera_commands import animate, calibrate, estimate, render, vo_eval
from scenarios.commands.optimal_command import optimal
from scenarios.commands.run_commands import config_command, export, list_presets, report, run
from scenarios.commands.study_commands import assess, compare, study, tune
from scenarios.commands.terminal import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_MISSED, handled
from scenarios.portable_arithmetic import PortableArithmeticError
from scenarios.portable_arithmetic import apply as apply_portable_arithmetic
from scenarios.run.stopping import handle_sigterm

__all__ = ["EXIT_BAD_INPUT", "EXIT_FAILED", "EXIT_MISSED", "app", "main"]

app = typer.Typer(
    help="Tractor–semi-trailer off-tracking co-simulation.",
    cls=OfftrackGroup,
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode=None,  # help texts are plain: "[km/h]" is a unit, not markup
    pretty_exceptions_enable=False,
)
for _command in bench_app.registered_commands:  # the benchmarks' bad input too: one line, exit 2
    _command.callback = handled(_command.callback)
app.add_typer(bench_app, name="bench")

COMMANDS = (
    ("list", list_presets),
    ("run", run),
    ("config", config_command),
    ("report", report),
    ("export", export),
    ("compare", compare),
    ("render", render),
    ("estimate", estimate),
    ("vo-eval", vo_eval),
    ("study", study),
    ("assess", assess),
    ("calibrate", calibrate),
    ("animate", animate),
    ("tune", tune),
    ("optimal", optimal),
)
"""Every command's name and body, in the order ``offtrack --help`` lists them."""
for _name, _body in COMMANDS:
    app.command(_name, cls=OfftrackCommand)(_body)


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


def main() -> None:
    """Entry point of ``offtrack``: SIGTERM is handled like Ctrl-C, then typer runs the command.

    ``OFFTRACK_PORTABLE_ARITHMETIC`` is checked and applied first (:mod:`scenarios.portable_arithmetic`; a bad
    value is one ``error:`` line and exit code 2). Typer's standalone mode prints usage errors (unknown option or
    command, a value of the wrong type or out of an option's range; in offtrack's style,
    :mod:`scenarios.cli_format`) with exit code 2 and turns ``typer.Exit`` into the process's exit code.
    """
    handle_sigterm()
    try:
        apply_portable_arithmetic()  # OFFTRACK_PORTABLE_ARITHMETIC=1: before any OpenCV operation
    except PortableArithmeticError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise SystemExit(EXIT_BAD_INPUT) from None
    app(prog_name="offtrack")


if __name__ == "__main__":  # python -m scenarios.cli, the same as the offtrack script
    main()
