"""No history in the source: docstrings and comments say what a thing is and why, not what a run measured.

Measured figures (a time on some machine, an RMS a study got, a speed-up against a commit) date the moment they
are written and go stale silently. They belong in benchmarks/README.md, docs/ (as results with their command) and
CHANGELOG.md. This test walks every docstring (:mod:`ast`) and comment (:mod:`tokenize`) of the source packages
and fails on the patterns such figures take: a number with a unit in a sentence that says it was measured (or
took, takes, got, came to...), words that date a sentence (this build, today, last week), commit hashes and
calendar dates. Physical constants, defaults, tolerances and published figures with their citation pass: they
carry none of those words.
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("vehicle_model", "controller", "sensor", "scenarios")

NUMBER = r"(?<![\w.])\d+(?:[.,]\d+)?(?:\s*[–-]\s*\d+(?:\.\d+)?)?"
UNIT = (
    r"(?:k?m/s|km/h|mm|cm|km|m|µs|us|ms|s|min|h|px|Hz|kHz|GB|MB|kB|%|°|deg|mdeg|rad|×|x(?=\s)|fps|"
    r"frames?/s|seconds?|minutes?|hours?)"
)
FIGURE = rf"{NUMBER}\s*{UNIT}(?![\w/])"
"""A number with a unit: ``0.046 m``, ``3.2 s``, ``14 min``, ``2.62×``, ``16 %``."""

MEASURING = (
    rf"\bmeasured\b:?\s+(?:[\w-]+\s+){{0,4}}?{FIGURE}|\b(?:takes|took|taking)\s+(?:[\w-]+\s+){{0,3}}?{FIGURE}|"
    rf"\b(?:holds|held|keeps|kept)\s+{FIGURE}|"
    rf"\b(?:go|goes|went|drops?|dropped|rises?|rose|falls?|fell|grows?|grew) from\s+{NUMBER}|"
    r"\b(?:benchmarked|profiled|clocked|came to|comes to|ran in|in a (?:quick )?check|on one core)\b|\(one core\)|"
    rf"{FIGURE}\s+(?:against|instead of)\s+{NUMBER}|{NUMBER}\s*×\s+(?:slower|faster|quicker)\b|"
    rf"(?:{NUMBER}|two|three|four|five|ten|twenty|fifty|a hundred)\s+times\s+slower\b|"
    rf"\bcosts?\s+(?:about\s+|roughly\s+|~)?{NUMBER}\s*×|"
    rf"{NUMBER}\s*(?:µs|us|ms|s|min)\s+(?:per|a|an|each)\s+(?:stereo\s+)?"
    r"(?:frame|pair|call|step|tick|run|study|case|cell|render)s?\b"
)
"""A figure that a run got: ``measured 0.03 m``, ``took 14 min``, ``holds 0.04 m``, ``went from 0.17``, ``7.7 ms against
9.9 ms``, ``2.6× faster``, ``ten times slower``, ``costs 2.5×``, ``50 ms a stereo pair``; or any figure in a sentence
that says it was benchmarked, timed on one core or came from a quick check."""

HISTORY = (
    r"\b(?:this build|the final build|the last build|this machine|this laptop|today|yesterday|tonight|"
    r"last (?:week|night)|this morning|as of now|(?:was|were) measured with|with which [^.;]*(?:was|were) measured)\b"
)
"""Words that date a sentence whatever it holds, or tie it to the run that got a result."""

COMMIT = r"(?<![\w./-])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![\w/-])"
"""A word of 7 to 40 hex digits with both a letter and a digit: an abbreviated or full commit hash."""

DATE = r"\b(?:19|20)\d\d-(?:0[1-9]|1[0-2])(?:-\d\d)?\b"
"""A calendar date, ``2026-12-05`` or ``2026-12``."""

RESULT_RMS = rf"{FIGURE}\s+RMS\b"
"""``0.034 m RMS``: an RMS is a result unless the sentence names it a target or cites where it was published."""

NOT_A_RESULT = (
    r"\b(?:off-tracking|RMS|max) targets?\b|\btarget of\b|\bpaper's\b|"
    r"\b[A-Z][a-z]+(?: (?:&|and|et al\.) [A-Z][a-z]+)? (?:19|20)\d\d\b"
)
"""A target, or a published figure with its citation (``de Saxe & Cebon 2018``)."""


def sentences(text: str) -> Iterator[str]:
    """The sentences of ``text``, whitespace collapsed.

    Paragraphs (blank lines), numpydoc parameter headers (``name : type``) and section rules end a sentence, and
    so do ``.``, ``!``, ``?`` before a capital or a bracket.
    """
    for block in re.split(r"\n\s*\n|\n(?=\s*[\w*]+ : )|\n\s*-{3,}\s*\n", text):
        flat = re.sub(r"\s+", " ", block).strip()
        yield from (s for s in re.split(r"(?<=[.!?])\s+(?=[A-Z(`*])", flat) if s.strip())


def findings(text: str) -> list[str]:
    """Each sentence of ``text`` that reads as a measured figure, with the pattern it matched."""
    found = []
    for sentence in sentences(text):
        if re.search(FIGURE, sentence) and re.search(MEASURING, sentence, re.IGNORECASE):
            found.append(f"figure a run got: {sentence!r}")
        elif re.search(RESULT_RMS, sentence) and not re.search(NOT_A_RESULT, sentence):
            found.append(f"RMS result: {sentence!r}")
        if re.search(HISTORY, sentence, re.IGNORECASE):
            found.append(f"history: {sentence!r}")
        if re.search(COMMIT, sentence):
            found.append(f"commit hash: {sentence!r}")
        if re.search(DATE, sentence):
            found.append(f"calendar date: {sentence!r}")
    return found


def docstrings_and_comments(path: Path) -> Iterator[tuple[int, str]]:
    """``(line, text)`` of every docstring (module, class, function, attribute) and comment of ``path``."""
    source = path.read_text(encoding="utf-8")
    tree = ast.parse(source)
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if not isinstance(body, list):
            continue
        for i, stmt in enumerate(body):
            is_string = (
                isinstance(stmt, ast.Expr)
                and isinstance(stmt.value, ast.Constant)
                and isinstance(stmt.value.value, str)
            )
            # The first statement of a module/class/function, or the string after an assignment (attribute doc).
            if is_string and (i == 0 or isinstance(body[i - 1], ast.Assign | ast.AnnAssign)):
                yield stmt.lineno, stmt.value.value
    comments: list[tuple[int, str]] = []
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            text = token.string.lstrip("#").strip()
            # A comment continued on the next lines reads as one sentence.
            if comments and comments[-1][0] + comments[-1][1].count("\n") + 1 == token.start[0]:
                comments[-1] = (comments[-1][0], f"{comments[-1][1]}\n{text}")
            else:
                comments.append((token.start[0], text))
    yield from comments


ALLOWED: dict[tuple[str, str], str] = {}
"""``(module path, a fragment of the sentence)`` → why that sentence is not a measured figure."""


def _allowed(relative: str, finding: str) -> bool:
    return any(relative == path and fragment in finding for path, fragment in ALLOWED)


def source_files() -> list[Path]:
    return sorted(p for package in PACKAGES for p in (ROOT / package).rglob("*.py"))


def test_the_walk_finds_the_source_packages() -> None:
    files = source_files()
    assert len(files) > 100, len(files)
    assert {p.relative_to(ROOT).parts[0] for p in files} == set(PACKAGES)


def test_no_docstring_or_comment_holds_a_measured_figure() -> None:
    problems = []
    for path in source_files():
        relative = path.relative_to(ROOT).as_posix()
        for line, text in docstrings_and_comments(path):
            problems += [f"{relative}:{line}: {f}" for f in findings(text) if not _allowed(relative, f)]
    assert not problems, "measured figures belong in docs/benchmarks/CHANGELOG:\n" + "\n".join(problems)


@pytest.mark.parametrize(
    "text",
    [
        "The fused loop measured 0.034 m RMS on roundabout-3.",
        "One frame takes 3.2 s with llvmpipe.",
        "The study took 14 min on two cores.",
        "The kernel is 2.62× faster than before (commit ccc8e1e).",
        "Since 2026-11-30 the default is 8°.",
        "On this build the loop holds the target.",
        "Fed the truth it holds 0.041 / 0.113 m RMS / max.",
        "The figure-of-eight went from 0.17 m to 0.21 m.",
        "Multisampling costs about 2.5× the time.",
        "The virtual machine is about ten times slower than C (50 ms).",
        "It is within 2 cm RMS at walking pace on roundabout-3.",
    ],
)
def test_a_measured_figure_is_found(text: str) -> None:
    assert findings(text), text


@pytest.mark.parametrize(
    "text",
    [
        "Integration step [s]; 2 ms keeps RK4 well inside its stability region.",
        "Stations are measured from the steer axle, positive forward.",
        "Largest RMS reprojection error [px] of the inliers. Default 1.75 px.",
        "Target of the true off-tracking, 0.10 m RMS and 0.15 m at most (de Saxe & Cebon 2018, §2).",
        "On ice, μ = 0.1, the peak is at 2.9° of slip.",
        "RMS and largest true off-tracking [m] of unit 3.",
        "The default, 8°, is a safeguard that does not need μ.",
        "Every step is one control period (20 ms) of the co-simulation.",
    ],
)
def test_a_constant_default_or_tolerance_is_not_flagged(text: str) -> None:
    assert not findings(text), findings(text)


def test_the_walk_reads_docstrings_and_comments(tmp_path: Path) -> None:
    module = tmp_path / "module.py"
    module.write_text(
        '"""The module."""\n\nX = 1\n"""The fused loop measured 0.034 m RMS on roundabout-3."""\n\n\n'
        "def f():\n    # took 3.2 s on this machine\n    return 1\n",
        encoding="utf-8",
    )
    found = [f for _, text in docstrings_and_comments(module) for f in findings(text)]
    assert len(found) == 3, found  # the attribute docstring; the comment (figure and dating word)
