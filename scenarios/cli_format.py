"""How the ``offtrack`` command line presents itself: readable help, usage errors in its one style, its version.

Help: typer writes a value's type as ``<str>``, ``<list[str]>`` and a required argument as ``{scenario}``;
:class:`OfftrackCommand` names each value the way a man page does (``SCENARIO``, ``TEXT``, ``FLOAT``, ``PATH``),
from the command function's own type hints. Usage errors (an unknown option or command, a missing argument, a value
of the wrong type or out of range) print ``error: <message>`` and ``try 'offtrack CMD --help'`` on stderr with exit
code 2, the style of every other input error. Both use only typer's documented extension points: the command and
group classes given as ``cls`` (:class:`typer.core.TyperCommand`, :class:`typer.core.TyperGroup`) and the public
methods and attributes of the click commands, parameters and exceptions they are.
"""

from __future__ import annotations

import inspect
import tomllib
import typing
from collections.abc import Iterator
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path
from typing import Any, get_args, get_origin

import typer
from typer.core import TyperCommand, TyperGroup

EXIT_USAGE = 2
"""Exit code of a usage error (the same as every bad input)."""

_METAVARS: dict[Any, str] = {str: "TEXT", int: "INTEGER", float: "FLOAT", Path: "PATH", bool: "BOOLEAN"}
"""The name shown for a value of each type."""


def offtrack_version() -> str:
    """offtrack's version: the installed distribution's, else the one in ``pyproject.toml`` beside the sources.

    Returns
    -------
    str
        ``X.Y.Z``, or ``unknown`` if neither says.
    """
    try:
        return metadata.version("offtrack")
    except metadata.PackageNotFoundError:
        pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
        try:
            return str(tomllib.loads(pyproject.read_text())["project"]["version"])
        except (OSError, KeyError, tomllib.TOMLDecodeError):
            return "unknown"


def _value_type(annotation: Any) -> Any:
    """The type of one value: ``str`` of ``str | None``, of ``list[str]``, of ``Annotated[str, …]``."""
    while get_origin(annotation) is typing.Annotated:
        annotation = get_args(annotation)[0]
    inner = [a for a in get_args(annotation) if a is not type(None)]
    if get_origin(annotation) in (list, tuple) or (inner and get_origin(annotation) is not None):
        return _value_type(inner[0]) if inner else annotation
    return annotation


def _hints(callback: Any) -> dict[str, Any]:
    """The command function's type hints by parameter name (through its decorators)."""
    if callback is None:
        return {}
    function = inspect.unwrap(callback)
    try:
        return typing.get_type_hints(function, include_extras=True)
    except (NameError, TypeError):  # a hint that cannot be resolved: typer's own names stay
        return {}


class OfftrackCommand(TyperCommand):
    """A command whose help names values like a man page and whose usage errors are one ``error:`` line."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        hints = _hints(self.callback)
        for param in self.params:
            if param.metavar is not None:
                continue
            if param.param_type_name == "argument":
                param.metavar = (param.name or "value").upper()
            elif not getattr(param, "is_flag", False) and param.name in hints:
                param.metavar = _METAVARS.get(_value_type(hints[param.name]), "VALUE")

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        """``[OPTIONS] SCENARIO``: an argument by its name, in brackets if it may be left out."""
        pieces = [self.options_metavar] if self.options_metavar else []
        for param in self.get_params(ctx):
            if param.param_type_name == "argument":
                name = param.metavar or (param.name or "value").upper()
                pieces.append((name if param.required else f"[{name}]") + ("..." if param.nargs != 1 else ""))
        return pieces

    def format_options(self, ctx: Any, formatter: Any) -> None:
        """The arguments by name (without typer's ``<str>``) and the options as typer writes them."""
        arguments, options = [], []
        for param in self.get_params(ctx):
            record = param.get_help_record(ctx)
            if record is None:
                continue
            if param.param_type_name == "argument":
                arguments.append((param.metavar or (param.name or "value").upper(), record[1]))
            else:
                options.append(record)
        for title, records in (("Arguments", arguments), ("Options", options)):
            if records:
                with formatter.section(title):
                    formatter.write_dl(records)

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        """Parse as typer does; a usage error is shown in offtrack's style (:class:`UsageError`)."""
        with offtrack_usage_errors():
            return super().parse_args(ctx, args)


class OfftrackGroup(TyperGroup):
    """The ``offtrack`` group (and ``offtrack bench``): its usage errors are one ``error:`` line."""

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        """Parse as typer does; no arguments at all still shows the help."""
        if not args:
            return super().parse_args(ctx, args)
        with offtrack_usage_errors():
            return super().parse_args(ctx, args)

    def resolve_command(self, ctx: Any, args: list[str]) -> Any:
        """The command named; an unknown one is a usage error in offtrack's style (with typer's suggestion)."""
        with offtrack_usage_errors():
            return super().resolve_command(ctx, args)


class UsageError(typer.BadParameter):
    """A usage error shown as ``error: <message>`` and ``try 'offtrack CMD --help'`` on stderr (exit code 2)."""

    exit_code = EXIT_USAGE

    def format_message(self) -> str:
        """The message alone (the parameter is already named in it)."""
        return self.message

    def show(self, file: Any = None) -> None:
        """Print the two lines on stderr (or ``file``)."""
        command = self.ctx.command_path if self.ctx is not None else "offtrack"
        typer.echo(f"error: {self.message}\ntry '{command} --help'", file=file, err=file is None)


def _sentence(text: str) -> str:
    """``No such option: --x`` → ``no such option: --x`` (an acronym such as ``VALUE`` is kept)."""
    text = text.strip().removesuffix(".")
    return text[0].lower() + text[1:] if len(text) > 1 and text[1].islower() else text


@contextmanager
def offtrack_usage_errors() -> Iterator[None]:
    """Turn typer's usage errors raised inside into :class:`UsageError` (its message, its context).

    A usage error is one of typer's exceptions with exit code 2 that has a context (``ctx``); it is recognised by those
    public attributes, not by click's class, which typer does not export.
    """
    try:
        yield
    except UsageError:
        raise
    except typer.TyperException as exc:
        ctx = getattr(exc, "ctx", None)
        if getattr(exc, "exit_code", None) != EXIT_USAGE or ctx is None or not hasattr(exc, "format_message"):
            raise
        raise UsageError(_sentence(exc.format_message()), ctx=ctx) from None
