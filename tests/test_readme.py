"""The README is a manual: every ``offtrack …`` line it shows parses, and every file and section it links to exists.

A command line in a code block is parsed by the real command line with ``--help`` appended: an unknown command or
option, or an option without its value, is a usage error (exit 2) before ``--help`` is acted on, while the
placeholders (``DIR``, ``N``) are never converted, so nothing is run. A command in the README's text (an inline
``offtrack …`` span, whose options may be shown as ``[--workers N \\| --scheduler ADDRESS]``) is checked by name:
its command exists and so does every option it names. The same checks cover the pages under ``docs/``.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path
from typing import Any

import pytest
from cli_runner import invoke, offtrack_command

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
PAGES = [README, *sorted((REPO / "docs").glob("*.md"))]

FENCE = re.compile(r"^```[^\n]*\n(.*?)^```", re.M | re.S)
INLINE = re.compile(r"`(offtrack [^`]+)`")
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
OPTION = re.compile(r"--[a-z][a-z0-9-]*")


def code_block_commands(text: str) -> list[str]:
    """Every line of the code blocks that runs ``offtrack`` (also ``$ offtrack`` and ``.venv/bin/offtrack``).

    Lines continued with a backslash are joined; shell comments are dropped by the caller's ``shlex``.
    """
    commands = []
    for block in FENCE.findall(text):
        lines = block.replace("\\\n", " ").splitlines()
        for line in lines:
            line = line.strip().removeprefix("$ ")
            first = line.split(maxsplit=1)[0] if line else ""
            if first.rsplit("/", 1)[-1] == "offtrack":
                commands.append("offtrack " + line.split(maxsplit=1)[1] if " " in line else "offtrack")
    return commands


def inline_commands(text: str) -> list[str]:
    """Every inline code span of the text that starts with ``offtrack ``, outside the code blocks."""
    return INLINE.findall(FENCE.sub("", text))


def _subcommands(group: Any) -> dict[str, Any]:
    return dict(getattr(group, "commands", {}) or {})


def _option_names(command: Any) -> set[str]:
    names: set[str] = set()
    for param in command.params:
        names.update(name for name in [*param.opts, *getattr(param, "secondary_opts", [])] if name.startswith("-"))
    return names | {"--help"}


def _resolve(words: list[str]) -> list[tuple[str, Any]]:
    """The commands a line names, each with its path: ``bench model\\|vo`` names two."""
    command = offtrack_command()
    found: list[tuple[str, Any]] = [("offtrack", command)]
    for word in words:
        subcommands = _subcommands(found[0][1])
        if not subcommands or word.startswith("-"):
            break
        alternatives = word.replace("\\|", "|").split("|")
        assert all(name in subcommands for name in alternatives), f"no command {word!r} under {found[0][0]!r}"
        found = [(f"{found[0][0]} {name}", subcommands[name]) for name in alternatives]
    return found


def test_code_blocks_and_inline_spans_are_found() -> None:
    text = "a `offtrack run X --seed 1` b\n```sh\n$ offtrack list\n"
    text += ".venv/bin/offtrack run a \\\n    --mu 0.2\necho\n```\n"
    assert code_block_commands(text) == ["offtrack list", "offtrack run a      --mu 0.2"]
    assert inline_commands(text) == ["offtrack run X --seed 1"]


def test_the_readme_shows_commands() -> None:
    text = README.read_text()
    assert len(code_block_commands(text)) >= 5
    assert len(inline_commands(text)) >= 15


@pytest.mark.parametrize("line", [c for page in PAGES for c in code_block_commands(page.read_text())])
def test_every_offtrack_line_in_a_code_block_parses(line: str) -> None:
    args = shlex.split(line, comments=True)[1:]
    _resolve(args)  # a clear message for an unknown command
    done = invoke([*args, "--help"])
    assert done.exit_code == 0, f"{line!r} does not parse: {done.output}"
    assert "Usage:" in done.output


@pytest.mark.parametrize("span", [c for page in PAGES for c in inline_commands(page.read_text())])
def test_every_offtrack_command_in_the_text_exists_with_its_options(span: str) -> None:
    words = span.split()[1:]
    for path, command in _resolve(words):
        known = _option_names(command)
        if _subcommands(command):  # a group: only its own options may be named
            continue
        named = set(OPTION.findall(span))
        assert named <= known, f"{span!r}: {path} has no option {sorted(named - known)}"


def _slug(heading: str) -> str:
    """A heading's anchor as GitHub makes it: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _anchors(page: Path) -> set[str]:
    text = FENCE.sub("", page.read_text())
    return {_slug(m.group(1)) for m in re.finditer(r"^#+ (.+)$", text, re.M)}


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_every_relative_link_names_a_file_and_section_that_exist(page: Path) -> None:
    for target in LINK.findall(FENCE.sub("", page.read_text())):
        if re.match(r"[a-z]+:", target):
            continue
        path, _, anchor = target.partition("#")
        linked = (page.parent / path).resolve() if path else page
        assert linked.exists(), f"{page.name} links to {target}, which does not exist"
        if anchor and linked.suffix == ".md":
            assert anchor in _anchors(linked), f"{page.name} links to {target}: no such section"


def test_a_bogus_command_or_option_is_caught() -> None:
    with pytest.raises(AssertionError, match="no command"):
        _resolve(["simulate"])
    assert invoke(["run", "roundabout-3", "--no-such-option", "--help"]).exit_code == 2
    assert "--no-such-option" not in _option_names(dict(_resolve(["run"]))["offtrack run"])
