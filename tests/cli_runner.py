"""``offtrack`` through typer's test runner with its command built once per process.

:class:`typer.testing.CliRunner` builds the command of the app (every subcommand and option of ``offtrack``) anew on
each ``invoke`` (most of a short command's time); :func:`invoke` is that runner with the command built on the first
call only.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any
from unittest import mock

import typer
import typer.testing
from typer.testing import CliRunner, Result

from scenarios.cli import app


@functools.cache
def offtrack_command(of: typer.Typer = app) -> Any:
    """The command ``typer.testing.CliRunner`` runs for the app ``of`` (``offtrack``'s by default), built once."""
    return typer.main.get_command(of)


def invoke(args: Sequence[str], **kwargs: Any) -> Result:
    """``CliRunner().invoke(app, args, **kwargs)`` with the command of :func:`offtrack_command`.

    The runner's command builder is typer's own (not public) function: where a typer version names it otherwise, the
    runner is used as it is (the same results, the command built on every call)."""
    if not hasattr(typer.testing, "_get_command"):
        return CliRunner().invoke(app, list(args), **kwargs)
    with mock.patch.object(typer.testing, "_get_command", offtrack_command):
        return CliRunner().invoke(app, list(args), **kwargs)
