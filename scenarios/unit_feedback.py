"""Which estimate steers which towed unit: the run's ``feedback`` and ``rear_feedback``.

``feedback`` is the estimate fed back to the first towed unit (the semi-trailer on the tractor's fifth wheel), any
estimator of :mod:`scenarios.registry`. Each unit behind it (a B-double's rear trailer, an A-double's dolly and second
trailer) follows its own coupling's path on an estimate of its own off-tracking, of which the loop has two: the ground
truth and every estimator the registry declares per unit (:attr:`scenarios.registry.EstimatorEntry.per_unit`: the
zero-slip estimate carried down the chain, :class:`controller.zero_slip.ZeroSlipEstimator` with ``unit``, and any
plug-in's); a camera sits on the first towed unit only. ``rear_feedback`` names one per unit behind the first, or is
left out, and then every unit behind the first that has a steerable axle is steered on the same kind of estimate as
the first (which must then be one of those two).

A towed unit is numbered here as in the axle table (:class:`vehicle_model.parameters.AxleTable`): 1 the first towed
unit, 2 the one it tows, …; the recorded columns number the units of the combination from the tractor (unit ``k`` of
the combination is towed unit ``k − 1``), so the estimate of towed unit 2 is ``truth3`` / ``zero_slip3``
(columns ``offtracking_truth3``, ``offtracking_zero_slip3``).
"""

from __future__ import annotations

from vehicle_model.parameters import VehicleParams

from .registry import NO_FEEDBACK, unit_feedback_sources

__all__ = ["check_unit_feedback", "estimate_key", "one_semi_trailer", "steered_units"]


def __getattr__(name: str) -> tuple[str, ...]:
    """``REAR_FEEDBACK``: the estimates a towed unit behind the first can be steered on
    (:func:`scenarios.registry.unit_feedback_sources`, read from the registry when asked for)."""
    if name == "REAR_FEEDBACK":
        return unit_feedback_sources()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


CAMERA_UNIT = (
    "the camera estimators see the first towed unit of a tractor or rigid truck with one semi-trailer; a longer "
    "combination (or a first towed unit that is not a semi-trailer) is steered on truth or zero_slip"
)
"""Why a run of a longer combination refuses the camera and the estimates made from it."""


def one_semi_trailer(params: VehicleParams) -> bool:
    """Whether the combination is a tractor or rigid truck with one semi-trailer (what the camera estimators
    assume)."""
    return params.n_units == 2 and params.trailer.front_load


def estimate_key(name: str, unit: int) -> str:
    """The name under which the loop holds estimator ``name``'s estimate of towed unit ``unit`` (module docstring):
    ``name`` itself for the first, ``name<k>`` for unit ``k`` of the combination behind it."""
    return name if unit == 1 else f"{name}{unit + 1}"


def _steerable(params: VehicleParams, unit: int) -> bool:
    return any(a.steerable for a in params.trailers[unit - 1].axles)


def rear_feedbacks(params: VehicleParams, feedback: str, rear_feedback: tuple[str, ...] | None) -> tuple[str, ...]:
    """The estimate steering each towed unit behind the first (``none`` for an unsteered one), as configured."""
    if rear_feedback is not None:
        return tuple(rear_feedback)
    return tuple(feedback if _steerable(params, unit) else NO_FEEDBACK for unit in range(2, params.n_units))


def steered_units(
    params: VehicleParams, feedback: str, rear_feedback: tuple[str, ...] | None = None
) -> list[tuple[int, str]]:
    """Every steered towed unit and the key of the estimate it is steered on (:func:`estimate_key`), front to rear.

    Parameters
    ----------
    params
        The combination.
    feedback
        The first towed unit's feedback.
    rear_feedback
        One feedback per unit behind the first, or ``None`` (the first's, where a unit has a steerable axle).
    """
    out = [(1, feedback)] if feedback != NO_FEEDBACK and _steerable(params, 1) else []
    for unit, name in enumerate(rear_feedbacks(params, feedback, rear_feedback), start=2):
        if name != NO_FEEDBACK:
            out.append((unit, estimate_key(name, unit)))
    return out


def check_unit_feedback(
    params: VehicleParams, feedback: str, rear_feedback: tuple[str, ...] | None, uses_camera: bool
) -> None:
    """Refuse, in one line naming the field, feedback the combination cannot be steered on.

    Raises
    ------
    ValueError
        The camera on a longer combination; a first-unit feedback a unit behind it cannot have; a
        ``rear_feedback`` of the wrong length, with an unknown estimate, or steering a unit without a steerable
        axle.
    """
    per_unit = unit_feedback_sources()
    if not one_semi_trailer(params):
        if feedback not in per_unit:
            raise ValueError(f"feedback = {feedback!r}: {CAMERA_UNIT}")
        if uses_camera:
            raise ValueError(f"estimators: the run includes a camera; {CAMERA_UNIT}")
    behind = params.n_units - 2
    if rear_feedback is None:
        return
    if len(rear_feedback) != behind:
        raise ValueError(
            f"rear_feedback: one estimate per towed unit behind the first ({behind} for {params.name!r}), "
            f"got {len(rear_feedback)}"
        )
    for i, name in enumerate(rear_feedback):
        if name not in per_unit:
            raise ValueError(f"rear_feedback[{i}] = {name!r} must be one of {', '.join(per_unit)}")
        if name != NO_FEEDBACK and not _steerable(params, i + 2):
            raise ValueError(
                f"rear_feedback[{i}] = {name!r} steers unit {i + 3}, which has no steerable axle "
                f"(--set vehicle.units[{i + 2}].axles[0].steerable=true)"
            )
