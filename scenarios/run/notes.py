"""Notes on a run's result that a reader would otherwise have to find: each one triggered by its condition, never a
blanket text.

* A zero-slip estimate far off on a high-friction road at walking pace: not friction slip but the scrub of the fixed
  axle groups, which moves each unit's real turning point from where the zero-slip kinematics put it
  (docs/vehicle_dynamics.md §2.3, §6.6); on a combination of several units each unit's estimate starts from the
  coupling the unit ahead gives it, so the chain carries the error to the rear.
* A steered run that missed its off-tracking target: whether steering helped at all is a comparison with the
  unsteered run, which ``offtrack compare`` makes (a single run does not drive the manoeuvre twice).
"""

from __future__ import annotations

from typing import Any

from .verdicts import OFFTRACKING_TARGET_RMS_M

__all__ = [
    "COMPARE_NOTE",
    "SCRUB_MAX_SPEED_KMH",
    "SCRUB_MIN_MU",
    "SCRUB_NOTE",
    "run_notes",
    "scrub_note",
    "unsteered_comparison_note",
]

SCRUB_NOTE = "zero_slip_scrub"
"""The note's kind: the zero-slip estimate off through the scrub of fixed axle groups (:func:`scrub_note`)."""
COMPARE_NOTE = "compare_with_unsteered"
"""The note's kind: how to see whether steering was worse than not steering (:func:`unsteered_comparison_note`)."""

SCRUB_MIN_MU = 0.5
"""Least friction coefficient [-] at which a walking-pace turn leaves the tyres far from their friction limit (a wet
road and better), so that a zero-slip error there is the fixed groups' scrub, not sliding."""

SCRUB_MAX_SPEED_KMH = 10.0
"""Largest cornering speed [km/h] of the walking-pace regime, where the lateral acceleration hardly moves the
tractor's rear point (docs/vehicle_dynamics.md §6.6) and the scrub of fixed groups is what remains."""

LOCKED_FRACTION = 0.2
"""Share of the time at its lock above which a steered axle is named as pushing the unit's turning point back."""


def _fixed_groups(params: Any) -> list[str]:
    """Each unit with two or more unsteered axles, as ``unit K: n fixed axles`` (1 the tractor or truck)."""
    out = []
    for number, unit in enumerate(params.units, start=1):
        fixed = sum(1 for axle in unit.axles if not axle.steerable)
        if fixed >= 2:
            out.append(f"unit {number}: {fixed} fixed axles")
    return out


def _zero_slip_errors(metrics: dict[str, Any]) -> dict[int, float]:
    """The zero-slip estimate's RMS error [m] by unit (2 the first towed one), where the run had one."""
    offtracking = metrics.get("offtracking") or {}
    errors = {2: ((offtracking.get("estimators") or {}).get("zero_slip") or {}).get("rms_error")}
    for unit, own in (offtracking.get("units") or {}).items():
        errors[int(unit)] = ((own.get("estimators") or {}).get("zero_slip") or {}).get("rms_error")
    return {unit: float(e) for unit, e in errors.items() if isinstance(e, int | float) and e == e}


def scrub_note(metrics: dict[str, Any], params: Any, mu: float, speed_kmh: float) -> str | None:
    """Why the zero-slip estimate is off on a high-friction road at walking pace (None when it is within the target,
    the road is slippery, the speed higher, or no unit has a fixed group).

    Parameters
    ----------
    metrics
        The run's metrics (:func:`~scenarios.run.metrics.compute_metrics`).
    params : vehicle_model.parameters.VehicleParams
        The combination.
    mu
        The road's friction coefficient.
    speed_kmh
        The cornering speed [km/h].
    """
    errors = {unit: e for unit, e in _zero_slip_errors(metrics).items() if e > OFFTRACKING_TARGET_RMS_M}
    groups = _fixed_groups(params)
    if not errors or mu < SCRUB_MIN_MU or speed_kmh > SCRUB_MAX_SPEED_KMH or not groups:
        return None
    shown = ", ".join(f"unit {unit} {e:.3f} m RMS" for unit, e in sorted(errors.items()))
    note = (
        f"the zero-slip estimate is off ({shown}) at {speed_kmh:g} km/h on μ {mu:.2f}, where no tyre nears its "
        f"friction limit: the fixed axle groups ({'; '.join(groups)}) cannot all roll without side-slip in a turn, "
        "they scrub and push on the coupling ahead, so each unit turns about a point the zero-slip kinematics do not "
        "use (docs/vehicle_dynamics.md §2.3, §6.6)"
    )
    locked = [
        axle for axle, m in (metrics.get("trailer_steering") or {}).items() if m.get("saturated_fraction", 0) > 0.2
    ]
    if locked:
        note += f"; steered axles at their lock ({', '.join(locked)}) push the other way"
    if params.n_units > 2:
        note += "; each unit's estimate starts from the coupling the unit ahead gives it, so the chain carries it back"
    return note


def unsteered_comparison_note(metrics: dict[str, Any], scenario: str) -> str | None:
    """For a steered run above its off-tracking target: how to see whether steering was worse than not steering.

    A single run does not drive the manoeuvre a second time unsteered (that would double its cost and make every
    run two); ``offtrack compare`` drives both and says when the steered one is worse (None for an unsteered run
    or one within its target).
    """
    feedback = metrics.get("feedback")
    flags = {f.get("flag") for f in (metrics.get("verdict") or {}).get("flags", [])}
    if feedback in (None, "none") or "offtracking_above_target" not in flags:
        return None
    return (
        f"whether steering on {feedback} was worse than not steering: `offtrack compare {scenario} "
        f"--feedbacks none,{feedback}` with this run's options drives both"
    )


def run_notes(metrics: dict[str, Any], params: Any, config: Any) -> list[dict[str, str]]:
    """The notes of a run, ``{"note": kind, "text": sentence}`` (each one only when its condition holds; empty: none).

    The kinds are :data:`SCRUB_NOTE` and :data:`COMPARE_NOTE`.

    Parameters
    ----------
    metrics
        The run's metrics.
    params : vehicle_model.parameters.VehicleParams
        The combination.
    config : scenarios.config.ScenarioConfig
        The run's configuration (the road's friction, the cornering speed, the scenario's name).
    """
    notes = {
        SCRUB_NOTE: scrub_note(metrics, params, config.surface.base_mu, config.speed.cornering_kmh),
        COMPARE_NOTE: unsteered_comparison_note(metrics, config.name),
    }
    return [{"note": kind, "text": text} for kind, text in notes.items() if text]
