"""Performance levels: the thresholds of a standard, with the clause each is quoted from, and the grading of a value.

The PBS scheme grades each standard in four levels, level 1 the most demanding. A :class:`Standard` holds its
measure's :class:`Threshold` s; :func:`grade` gives the level a value reaches and its margins. The program holds no
threshold of its own: the rules' tables of levels could not be read here, and none is written from memory. The
thresholds come from the user's levels file (:mod:`.user_levels`, ``offtrack assess --levels FILE``), each with the
document and clause it was quoted from; without one a measure is reported without a level (:data:`NO_LEVELS`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

__all__ = ["DOCUMENT", "NO_LEVELS", "SUMMARY_SOURCE", "Grade", "Standard", "Threshold", "grade"]

DOCUMENT = (
    "National Transport Commission, Performance Based Standards Scheme - The Standards and Vehicle Assessment "
    "Rules, as at 10 November 2008"
)
"""The version of the rules the definitions here were written against (their tables of levels could not be read)."""
SUMMARY_SOURCE = "NHVR, PBS vehicle standards (nhvr.gov.au/road-access/performance-based-standards/vehicle-standards)"
"""The one-line summaries of the standards the definitions here follow."""
NO_LEVELS = "no levels given"
"""The grade of a measure without thresholds: no levels file was given, or it gives no limit for the standard."""


@dataclass(frozen=True)
class Threshold:
    """The limit of one performance level of a standard, as the user's copy of the rules gives it.

    Attributes
    ----------
    level
        The PBS level, 1 to 4.
    limit
        The level's limit in the standard's unit (SI): the largest value that meets it where lower is better, the
        smallest where higher is.
    clause
        Where the document gives it: clause and table (the user's citation).
    min_length, max_length
        The overall lengths of combination [m] the limit applies to (a level's limit may depend on the length).
    """

    level: int
    limit: float
    clause: str
    min_length: float = 0.0
    max_length: float = math.inf


@dataclass(frozen=True)
class Standard:
    """One measure: its unit, what it measures, its level thresholds (none until a levels file gives them) and which
    way is better.

    Attributes
    ----------
    measure
        Its name, as reported.
    unit
        Of the value.
    definition
        What it measures, in words.
    thresholds
        The level thresholds; empty where none is given.
    better
        ``"lower"``: a value at or below a level's limit meets it; ``"higher"``: at or above.
    """

    measure: str
    unit: str
    definition: str
    thresholds: tuple[Threshold, ...] = ()
    better: Literal["lower", "higher"] = "lower"

    def applicable(self, length: float | None) -> tuple[Threshold, ...]:
        """The thresholds for a combination ``length`` metres long (every one when the length is not given),
        best level first."""
        found = [t for t in self.thresholds if length is None or t.min_length <= length < t.max_length]
        return tuple(sorted(found, key=lambda t: t.level))


@dataclass(frozen=True)
class Grade:
    """A measure against its thresholds.

    Attributes
    ----------
    level
        The best (lowest-numbered) level whose limit the value meets; None when none is met, there are no
        thresholds, or the value is not finite.
    margin
        How far inside that level's limit the value lies (positive, the measure's unit); None without a level.
    margin_level_1
        How far inside level 1's limit the value lies (negative: short of level 1); None without a level-1 threshold.
    reason
        Why, in words.
    threshold_source
        The clauses the thresholds come from, or :data:`NO_LEVELS`.
    shortfall
        When thresholds apply but no level is met: how far inside the least demanding level's limit the value lies
        (negative); None otherwise.
    """

    level: int | None
    margin: float | None
    margin_level_1: float | None
    reason: str
    threshold_source: str
    shortfall: float | None = None


def grade(value: float, standard: Standard, length: float | None = None) -> Grade:
    """The level ``value`` reaches against ``standard``'s thresholds for a combination ``length`` metres long.

    Parameters
    ----------
    value
        The measure, in the standard's unit (``standard.better`` says which way is better).
    standard
        The measure's :class:`Standard`.
    length
        Overall length of the combination [m] (:func:`combination_length`), for thresholds that depend on it.

    Returns
    -------
    Grade
    """
    thresholds = standard.applicable(length)
    if not thresholds:
        return Grade(None, None, None, NO_LEVELS, NO_LEVELS)
    source = "; ".join(f"level {t.level}: {t.clause}" for t in thresholds)
    level_1 = next((t for t in thresholds if t.level == 1), None)
    if not math.isfinite(value):
        return Grade(None, None, None, "no finite value to grade", source)
    sign = 1.0 if standard.better == "lower" else -1.0
    margin_1 = None if level_1 is None else sign * (level_1.limit - value)
    met = next((t for t in thresholds if sign * (t.limit - value) >= 0.0), None)
    if met is None:
        worst = thresholds[-1]
        beyond = "exceeds" if standard.better == "lower" else "falls short of"
        reason = f"{value:.4g} {beyond} level {worst.level}'s limit {worst.limit:.4g}"
        return Grade(None, None, margin_1, reason, source, sign * (worst.limit - value))
    reason = f"{value:.4g} within level {met.level}'s {met.limit:.4g}"
    return Grade(met.level, sign * (met.limit - value), margin_1, reason, source)
