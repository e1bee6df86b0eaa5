"""The command line's terminal: its two consoles, the exit codes, the error handling every command body runs under,
and what runs print (the progress bar, the summary, the exit for a run's status or a missed check)."""

from __future__ import annotations

import errno
import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import typer
from pydantic import ValidationError
from rich.console import Console

from scenarios.loop.ends import RunStatus
from scenarios.run.stopping import (
    exit_code_for_signal,
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
FULL = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS)
"""Errors of a write that found no room (a full disk, a quota, a file too large, a read-only file system): an
:class:`OSError` with one of these that no writer turned into an :class:`~vehicle_model.errors.OutputError` is one
line and exit 3 all the same."""
console = Console()
errors = Console(stderr=True, highlight=False, soft_wrap=True)  # a message stays on one line

F = TypeVar("F", bound=Callable[..., Any])


def handled(func: F) -> F:
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


def simulation_progress() -> Any:
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


def exit_for_checks(metrics: dict) -> None:
    """``--check``: say what a completed run missed and exit 4 (nothing missed: return)."""
    from scenarios.run.verdicts import missed_checks

    missed = missed_checks(metrics)
    if missed:
        errors.print(f"check: the run missed {len(missed)} of what it was asked to hold:", markup=False)
        for reason in missed:
            errors.print(f"  {reason}", markup=False, soft_wrap=True)
        raise typer.Exit(EXIT_MISSED)


def exit_for_status(metrics: dict) -> None:
    """Say why a run did not complete and exit with its code (3 failed, 130/143 stopped)."""
    status = metrics["status"]
    if status == RunStatus.COMPLETED:
        return
    errors.print(f"run {status}: {metrics['message']}", markup=False)
    if status == RunStatus.INTERRUPTED:
        raise typer.Exit(exit_code_for_signal(metrics.get("stop_signal")))
    raise typer.Exit(EXIT_FAILED)


def print_study_summary(table, run_dir: Path, name: str) -> None:
    """The study's own columns (:attr:`~scenarios.studies.registry.Study.columns`, on its terminal rows), to the
    terminal's width; the rest is in table.md / table.csv."""
    from scenarios.studies.registry import STUDIES
    from scenarios.studies.summary import summary_table

    study = STUDIES.get(name)
    title = f"{name}: {len(table)} cases"
    rows, what = table, "cases"
    if study is not None and study.terminal_rows is not None:
        rows, note = study.terminal_rows(table)
        title, what = f"{name}: {len(table)} cases, {note}", "cells"
    files = (str(run_dir / "table.md"), str(run_dir / "table.csv"))
    columns = study.columns if study is not None else ()
    console.print(summary_table(rows, console.width, files=files, title=title, rows=what, columns=columns))


def print_summary(metrics: dict, run_dir: Path) -> None:
    """The closing table of a run and its verdicts (:func:`scenarios.run.summary.run_summary`)."""
    from scenarios.run.summary import run_summary

    for item in run_summary(metrics, run_dir):
        console.print(item)
