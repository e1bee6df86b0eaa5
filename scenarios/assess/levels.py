"""Performance levels: the thresholds of a standard, with the clause each is quoted from, and the grading of a value.

The PBS scheme grades each standard in four levels, level 1 the most demanding. A :class:`Standard` holds its
measure's :class:`Threshold` s (none until they are verified against :data:`DOCUMENT`); :func:`grade` gives the level
a value reaches and its margins. Every threshold names its clause and table; one that could not be verified is left
out, and the measure is reported without a level (:data:`NOT_VERIFIED`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["DOCUMENT", "NOT_VERIFIED", "SUMMARY_SOURCE", "Grade", "Standard", "Threshold", "grade"]

DOCUMENT = (
    "National Transport Commission, Performance Based Standards Scheme - The Standards and Vehicle Assessment "
    "Rules, as at 10 November 2008"
)
"""The document the thresholds are to be quoted from, with its version."""
SUMMARY_SOURCE = "NHVR, PBS vehicle standards (nhvr.gov.au/road-access/performance-based-standards/vehicle-standards)"
"""The one-line summaries of the standards the definitions here follow."""
NOT_VERIFIED = "threshold not verified"
"""The note of a measure whose level thresholds could not be read from :data:`DOCUMENT`."""


@dataclass(frozen=True)
class Threshold:
    """The limit of one performance level of a standard, as :data:`DOCUMENT` gives it.

    Attributes
    ----------
    level
        The PBS level, 1 to 4.
    limit
        The largest value that meets the level, in the standard's unit (SI).
    clause
        Where the document gives it: clause and table.
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
    """One low-speed measure: its unit, what it measures, and its level thresholds (none when not verified)."""

    measure: str
    unit: str
    definition: str
    thresholds: tuple[Threshold, ...] = ()

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
        The best (lowest-numbered) level whose limit the value meets; None when none is met, there are no verified
        thresholds, or the value is not finite.
    margin
        That level's limit minus the value [the measure's unit]; None without a level.
    margin_level_1
        Level 1's limit minus the value (negative: short of level 1); None without a level-1 threshold.
    reason
        Why, in words.
    threshold_source
        The clauses the thresholds come from, or the document and :data:`NOT_VERIFIED`.
    """

    level: int | None
    margin: float | None
    margin_level_1: float | None
    reason: str
    threshold_source: str


def grade(value: float, standard: Standard, length: float | None = None) -> Grade:
    """The level ``value`` reaches against ``standard``'s thresholds for a combination ``length`` metres long.

    Parameters
    ----------
    value
        The measure, in the standard's unit; smaller is better for every low-speed measure.
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
        return Grade(None, None, None, NOT_VERIFIED, f"{DOCUMENT}: {NOT_VERIFIED}")
    source = "; ".join(f"level {t.level}: {t.clause}" for t in thresholds)
    level_1 = next((t for t in thresholds if t.level == 1), None)
    if not math.isfinite(value):
        return Grade(None, None, None, "no finite value to grade", source)
    margin_1 = None if level_1 is None else level_1.limit - value
    met = next((t for t in thresholds if value <= t.limit), None)
    if met is None:
        worst = thresholds[-1]
        return Grade(None, None, margin_1, f"{value:.4g} exceeds level {worst.level}'s limit {worst.limit:.4g}", source)
    return Grade(
        met.level, met.limit - value, margin_1, f"{value:.4g} within level {met.level}'s {met.limit:.4g}", source
    )
