"""The user's PBS levels: the thresholds of each standard and level from the engineer's own copy of the rules.

The program holds no threshold (:mod:`.levels`): the rules' tables could not be read here, and none is written from
memory. An engineer preparing an application holds the document; ``offtrack assess --levels FILE.yaml`` reads its
thresholds from a file in the form of ``docs/pbs_levels_template.yaml``::

    document: "the rules' title and version the limits are quoted from"
    standards:
      tail_swing:
        unit: m               # m or mm for a length, - for a ratio
        direction: maximum    # maximum: a level is met at or below its limit; minimum: at or above
        levels:
          1: {limit: ..., clause: "clause and table"}
          2: [{limit: ..., clause: "...", max_length_m: 20}, {limit: ..., clause: "...", min_length_m: 20}]
          3: {limit: null, clause: ""}    # not given: the level is left out

The file is checked before any work (:func:`load_levels`), each fault refused in one line naming the field and what
it allows: every standard one the assessment measures (:data:`ASSESSED`; one it cannot assess is refused with the
reason, :data:`NOT_ASSESSED`), the unit one of the standard's, the direction the standard's own (a tail swing is met
below its limit, a yaw damping coefficient above), every given limit finite and in the standard's range, with a
clause, the length bands of a level apart, and the limits monotone across levels (no level more demanding than the
one before it). :func:`grade_record` grades a record with the file and cites the clause of the level met.
"""

from __future__ import annotations

import itertools
import math
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from vehicle_model.errors import InputError

from ..configuration.errors import did_you_mean
from ..yaml_input import load_yaml
from .high_speed import MEASURES, UNASSESSABLE_REASONS
from .levels import NO_LEVELS, Standard, Threshold, grade
from .low_speed import STANDARDS

__all__ = [
    "ASSESSED",
    "DIRECTIONS",
    "LIMIT_RANGES",
    "NOT_ASSESSED",
    "UNIT_SCALES",
    "UserLevels",
    "grade_record",
    "load_levels",
    "parse_levels",
    "standard_key",
    "template_text",
]

ASSESSED: dict[str, Standard] = {
    **STANDARDS,
    **{key: m for key, m in MEASURES.items() if key not in UNASSESSABLE_REASONS},
}
"""Every standard the assessment measures, by the key a levels file names it with: its unit and direction."""

NOT_ASSESSED: dict[str, str] = {
    **UNASSESSABLE_REASONS,
    "startability": "it needs the engine's torque, the gearing and the driveline, which the model does not have "
    "(its drive force is a demand capped by the tyres' friction)",
    "gradeability": "it needs the engine's torque, the gearing and the driveline on a grade; the model has none",
    "acceleration_capability": "it needs the engine's power and the gear changes; the model's drive force is a "
    "demand, not an engine's",
    "overtaking_provision": "it needs the engine's power and gearing to give the time taken to overtake; the "
    "model has neither",
    "directional_stability_under_braking": "it needs the brakes, wheel lock and the load moved forward under "
    "braking; the model has no brake system and no pitch or longitudinal load transfer",
    "handling_quality": "it needs the load moved across each axle in a turn (roll and the track width); the "
    "single-track model carries both tyres of an axle equally",
    "ride_quality": "it needs the vertical motion of the cab on a rough road; the model has no vertical dynamics",
}
"""Standards of the scheme the yaw-plane model cannot assess, by key, with the reason (the assessment lists them)."""

DIRECTIONS = {"maximum": "lower", "minimum": "higher"}
"""A levels file's ``direction`` and the :attr:`Standard.better` it means."""

UNIT_SCALES: dict[str, dict[str, float]] = {"m": {"m": 1.0, "mm": 1e-3}, "-": {"-": 1.0}}
"""The units a levels file may give a standard's limits in, by the standard's own unit: the factor to it."""

LIMIT_RANGES: dict[str, tuple[float, float]] = {
    "low_speed_swept_path": (0.0, 30.0),
    "tail_swing": (0.0, 5.0),
    "frontal_swing": (0.0, 5.0),
    "frontal_swing_max_of_difference": (0.0, 5.0),
    "frontal_swing_difference_of_maxima": (0.0, 5.0),
    "steer_tyre_friction_demand": (0.0, 2.0),
    "steer_tyre_friction_utilisation": (0.0, 1.0),
    "rearward_amplification": (0.0, 10.0),
    "high_speed_transient_offtracking": (0.0, 5.0),
    "yaw_damping_coefficient": (0.0, 1.0),
    "high_speed_steady_offtracking": (0.0, 5.0),
}
"""The range a limit must lie in, in the standard's own unit: what the measure can be (a damping ratio or a share
of the road's friction within [0, 1]), with room to spare for lengths; a limit outside is a typing slip or a wrong
unit."""

LEVELS = (1, 2, 3, 4)
"""The scheme's levels, 1 the most demanding."""
_LEVEL_FIELDS = ("limit", "clause", "min_length_m", "max_length_m")
_STANDARD_FIELDS = ("unit", "direction", "levels")
_TOP_FIELDS = ("document", "standards")


@dataclass(frozen=True)
class UserLevels:
    """The thresholds of a levels file.

    Attributes
    ----------
    document
        The rules the thresholds are quoted from, as the file names them (title and version).
    source
        The file.
    standards
        Each standard the file gives at least one limit for, by key: the program's :class:`Standard` with the file's
        thresholds (in the standard's own unit).
    """

    document: str
    source: str
    standards: dict[str, Standard]

    def standard(self, key: str) -> Standard | None:
        """The standard ``key`` with the file's thresholds, or None when the file gives it no limit."""
        return self.standards.get(key)


def standard_key(measure: str) -> str | None:
    """The key of the standard a record's ``measure`` names (as a record or a report spells it), or None."""
    for key, standard in ASSESSED.items():
        if measure in (key, key.replace("_", " "), standard.measure, standard.measure.replace("_", " ")):
            return key
    return None


def _fail(source: str, field: str, problem: str) -> InputError:
    return InputError(f"{source}: {field}: {problem}")


def _unknown(source: str, where: str, given: list[str], allowed: tuple[str, ...]) -> InputError | None:
    extra = [g for g in given if g not in allowed]
    if not extra:
        return None
    hint = did_you_mean(extra[0], allowed) or f"; allowed: {', '.join(allowed)}"
    return _fail(source, f"{where}{extra[0]}", f"not a field{hint}")


def _number(value: Any, source: str, field: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise _fail(source, field, f"{value!r} is not a finite number")
    return float(value)


def _bands(entry: Any, source: str, field: str, key: str, level: int, unit: str) -> list[Threshold]:
    """The thresholds of one level entry (a mapping, a list of length bands, or null), limits given in ``unit``."""
    scale = UNIT_SCALES[ASSESSED[key].unit][unit]
    if entry is None:
        return []
    items = entry if isinstance(entry, list) else [entry]
    out = []
    for i, item in enumerate(items):
        where = f"{field}[{i}]" if isinstance(entry, list) else field
        if not isinstance(item, dict):
            raise _fail(source, where, "give {limit: NUMBER or null, clause: TEXT}, or a list of them by length band")
        if (bad := _unknown(source, f"{where}.", [str(k) for k in item], _LEVEL_FIELDS)) is not None:
            raise bad
        if item.get("limit") is None:
            continue
        given = _number(item["limit"], source, f"{where}.limit")
        limit = given * scale
        low, high = LIMIT_RANGES[key]
        if not low <= limit <= high:
            raise _fail(
                source, f"{where}.limit", f"{given:g} {unit} is outside [{low / scale:g}, {high / scale:g}] {unit}"
            )
        clause = item.get("clause")
        if not isinstance(clause, str) or not clause.strip():
            raise _fail(source, f"{where}.clause", "give the clause and table of the rules the limit is quoted from")
        shortest = _number(item.get("min_length_m", 0.0), source, f"{where}.min_length_m")
        longest = item.get("max_length_m")
        longest = math.inf if longest is None else _number(longest, source, f"{where}.max_length_m")
        if not 0.0 <= shortest < longest:
            raise _fail(source, f"{where}.min_length_m", f"{shortest:g} m must be ≥ 0 and below max_length_m")
        out.append(Threshold(level, limit, clause.strip(), shortest, longest))
    ordered = sorted(out, key=lambda t: t.min_length)
    for a, b in itertools.pairwise(ordered):
        if b.min_length < a.max_length:
            raise _fail(source, field, f"length bands overlap at {b.min_length:g} m; each length has one limit a level")
    return out


def _monotone(source: str, key: str, thresholds: list[Threshold], better: str, unit: str) -> None:
    """Refuse a level whose limit is more demanding than a more demanding level's, where their length bands meet
    (the limits said in the file's ``unit``)."""
    scale = UNIT_SCALES[ASSESSED[key].unit][unit]
    for a in thresholds:
        for b in thresholds:
            if b.level <= a.level or b.min_length >= a.max_length or a.min_length >= b.max_length:
                continue
            loose = b.limit >= a.limit if better == "lower" else b.limit <= a.limit
            if not loose:
                rule = "must not fall" if better == "lower" else "must not rise"
                raise _fail(
                    source,
                    f"standards.{key}.levels.{b.level}.limit",
                    f"{b.limit / scale:g} is more demanding than level {a.level}'s {a.limit / scale:g} {unit}; from "
                    f"level 1 to 4 a "
                    f"{'maximum' if better == 'lower' else 'minimum'} {rule}",
                )


def _standard(key: str, spec: Any, source: str) -> Standard:
    field = f"standards.{key}"
    program = ASSESSED[key]
    if not isinstance(spec, dict):
        raise _fail(source, field, "give a mapping with unit, direction and levels")
    if (bad := _unknown(source, f"{field}.", [str(k) for k in spec], _STANDARD_FIELDS)) is not None:
        raise bad
    scales = UNIT_SCALES[program.unit]
    unit = spec.get("unit")
    if unit not in scales:
        raise _fail(source, f"{field}.unit", f"{unit!r}; the {program.measure} is given in {' or '.join(scales)}")
    direction = spec.get("direction")
    expected = "maximum" if program.better == "lower" else "minimum"
    if direction != expected:
        meets = "at or below" if program.better == "lower" else "at or above"
        raise _fail(
            source,
            f"{field}.direction",
            f"{direction!r}; a level of the {program.measure} is met {meets} its limit: give {expected}",
        )
    levels = spec.get("levels") or {}
    if not isinstance(levels, dict):
        raise _fail(source, f"{field}.levels", "give a mapping of level (1 to 4) to its limit and clause")
    thresholds: list[Threshold] = []
    for given, entry in levels.items():
        level = int(given) if isinstance(given, str) and given.strip().isdigit() else given
        if level not in LEVELS:
            raise _fail(source, f"{field}.levels.{given}", "not a level: the levels are 1, 2, 3 and 4")
        thresholds += _bands(entry, source, f"{field}.levels.{level}", key, int(level), unit)
    _monotone(source, key, thresholds, program.better, unit)
    return Standard(program.measure, program.unit, program.definition, tuple(thresholds), program.better)


def parse_levels(data: Any, source: str) -> UserLevels:
    """The thresholds of a levels file's parsed content, checked (module docstring).

    Parameters
    ----------
    data
        The parsed YAML.
    source
        The file, for the messages.

    Returns
    -------
    UserLevels

    Raises
    ------
    InputError
        One line naming the field and what it allows.
    """
    if not isinstance(data, dict):
        raise _fail(source, "the file", "give a mapping with document and standards (docs/pbs_levels_template.yaml)")
    if (bad := _unknown(source, "", [str(k) for k in data], _TOP_FIELDS)) is not None:
        raise bad
    standards = data.get("standards") or {}
    if not isinstance(standards, dict):
        raise _fail(source, "standards", "give a mapping of standard to its unit, direction and levels")
    out = {}
    for key, spec in standards.items():
        if key in NOT_ASSESSED:
            raise _fail(source, f"standards.{key}", f"not assessed by offtrack: {NOT_ASSESSED[key]}; remove it")
        if key not in ASSESSED:
            hint = did_you_mean(str(key), ASSESSED) or f"; the standards assessed: {', '.join(ASSESSED)}"
            raise _fail(source, f"standards.{key}", f"not a standard the assessment measures{hint}")
        standard = _standard(key, spec, source)
        if standard.thresholds:
            out[key] = standard
    document = data.get("document")
    if out and (not isinstance(document, str) or not document.strip()):
        raise _fail(source, "document", "give the rules' title and version the limits are quoted from")
    return UserLevels(str(document or "").strip(), source, out)


def load_levels(path: str | Path) -> UserLevels:
    """Read and check a levels file (:func:`parse_levels`).

    Raises
    ------
    InputError
        The file is missing, unreadable, not YAML, or a field is wrong: one line naming it.
    """
    source = f"levels file {path}"
    if not Path(path).is_file():
        raise InputError(f"{source} does not exist; start from docs/pbs_levels_template.yaml")
    try:
        data = load_yaml(Path(path).read_bytes(), source)
    except OSError as exc:
        raise InputError(f"{source} cannot be read: {exc.strerror or exc}") from None
    return parse_levels(data, str(path))


def _met(standard: Standard, level: int, length: float | None) -> Threshold | None:
    return next((t for t in standard.applicable(length) if t.level == level), None)


def grade_record(record: dict[str, Any], levels: UserLevels | None, length: float | None) -> dict[str, Any]:
    """``record`` graded with ``levels``: its ``level``, ``margin``, ``threshold_source`` and ``grade`` (in words,
    with the clause of the level met).

    Parameters
    ----------
    record
        A record of :func:`.low_speed.low_speed_assessment` or :func:`.high_speed.high_speed_assessment`.
    levels
        The user's levels; None when none were given.
    length
        The combination's overall length [m], for limits given by length band.

    Returns
    -------
    dict
        A new record with ``level`` (the best level met, ``"none"`` when none is, None when not graded),
        ``margin`` (to that level's limit, or negative to the least demanding one), ``margin_level_1``,
        ``threshold_source`` (the document and clause) and ``grade``. A record of no standard (the turning circle)
        is returned as it is.
    """
    key = standard_key(str(record.get("measure", "")))
    if key is None:
        return record
    standard = None if levels is None else levels.standard(key)
    if standard is None:
        why = NO_LEVELS if levels is None else f"{levels.source} gives no limit for it"
        return {**record, "level": None, "margin": None, "margin_level_1": None, "threshold_source": why, "grade": why}
    assert levels is not None  # a standard comes only from a levels file
    value = record.get("value")
    value = math.nan if value is None else float(value)
    g = grade(value, standard, length)
    applicable = standard.applicable(length)
    if g.level is not None:
        met = _met(standard, g.level, length)
        assert met is not None
        text = f"level {g.level} ({met.clause})"
        source = f"{levels.document}, {met.clause}"
        level: int | str | None = g.level
        margin = g.margin
    elif g.shortfall is not None:
        worst = applicable[-1]
        text = f"no level met: {g.reason} ({worst.clause})"
        source = f"{levels.document}, {worst.clause}"
        level, margin = "none", g.shortfall
    else:
        text = f"not graded: {g.reason}" if applicable else f"{levels.source} gives no limit for this length"
        source = levels.document
        level, margin = None, None
    graded = {"level": level, "margin": margin, "margin_level_1": g.margin_level_1}
    return {**record, **graded, "threshold_source": source, "grade": text}


def template_text() -> str:
    """A levels file listing every standard the assessment measures with its unit and direction, and empty
    thresholds (``docs/pbs_levels_template.yaml`` is this text)."""
    head = (
        "offtrack PBS levels: fill in from YOUR copy of the rules, then `offtrack assess COMBINATION --levels FILE`. "
        'offtrack holds no threshold of its own (docs/pbs.md, "Grading with your levels"). Each limit needs the '
        "clause and table it is quoted from; a level left at `limit: null` is not graded. A limit that depends on "
        "the combination's overall length is a list of bands: [{limit, clause, max_length_m: L}, {limit, clause, "
        "min_length_m: L}]. unit: m or mm for a length, - for a ratio. direction: maximum (a level is met at or "
        "below its limit) or minimum (at or above); each standard's is fixed and written here for you to check "
        "against the rules."
    )
    lines = [f"# {line}" for line in textwrap.wrap(head, 114)]
    lines += ['document: ""  # the rules\' title and version your limits are quoted from', "standards:"]
    for key, standard in ASSESSED.items():
        direction = "maximum" if standard.better == "lower" else "minimum"
        unit = f'"{standard.unit}"' if standard.unit == "-" else standard.unit
        lines += [f"  # {line}" for line in textwrap.wrap(f"{standard.measure}: {standard.definition}", 112)]
        lines += [f"  {key}:", f"    unit: {unit}", f"    direction: {direction}", "    levels:"]
        lines += [f'      {level}: {{limit: null, clause: ""}}' for level in LEVELS]
    return "\n".join(lines) + "\n"
