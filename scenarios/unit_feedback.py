"""Which estimate steers which towed unit: the run's ``feedback`` and ``rear_feedback``.

``feedback`` is the estimate fed back to the first towed unit (the semi-trailer on the tractor's fifth wheel), any
estimator of :mod:`scenarios.registry`. Each unit behind it (a B-double's rear trailer, an A-double's dolly and second
trailer) follows its own coupling's path on an estimate of its own off-tracking, of which the loop has two: the ground
truth and every estimator the registry declares per unit (:attr:`scenarios.registry.EstimatorEntry.per_unit`: the
zero-slip estimate carried down the chain, :class:`controller.zero_slip.ZeroSlipEstimator` with ``unit``, VISO-OT
and fused VISO-OT on each unit's own camera rig (``camera.rigs``), and any plug-in's). ``rear_feedback`` names one per
unit behind the first, or is left out, and then every unit behind the first that has a steerable axle is steered on
the same kind of estimate as the first (which must then be one of those). A unit is steered on a camera estimate
only if a rig is mounted on it; the first towed unit must be a semi-trailer for the camera estimators (VISO-OT
follows its kingpin's path).

A towed unit is numbered here as in the axle table (:class:`vehicle_model.parameters.AxleTable`): 1 the first towed
unit, 2 the one it tows, …; the recorded columns number the units of the combination from the tractor (unit ``k`` of
the combination is towed unit ``k − 1``), so the estimate of towed unit 2 is ``truth3`` / ``zero_slip3``
(columns ``offtracking_truth3``, ``offtracking_zero_slip3``).
"""

from __future__ import annotations

from collections.abc import Collection

from vehicle_model.parameters import VehicleParams

from .registry import NO_FEEDBACK, estimator_entry, unit_feedback_sources

__all__ = ["check_unit_feedback", "estimate_key", "one_semi_trailer", "steered_units", "uses_camera"]


def __getattr__(name: str) -> tuple[str, ...]:
    """``REAR_FEEDBACK``: the estimates a towed unit behind the first can be steered on
    (:func:`scenarios.registry.unit_feedback_sources`, read from the registry when asked for)."""
    if name == "REAR_FEEDBACK":
        return unit_feedback_sources()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


CAMERA_UNIT = (
    "the camera estimators follow the kingpin of a semi-trailer: a combination whose first towed unit is not one is "
    "steered on truth or zero_slip"
)
"""Why a run of a combination whose first towed unit is not a semi-trailer refuses the camera."""


def uses_camera(name: str) -> bool:
    """Whether the estimate ``name`` (a registered estimator, or ``none``) is made from a camera."""
    return name != NO_FEEDBACK and estimator_entry(name).needs_camera


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
    params: VehicleParams,
    feedback: str,
    rear_feedback: tuple[str, ...] | None,
    camera: bool,
    camera_units: Collection[int] | None = None,
) -> None:
    """Refuse, in one line naming the field, feedback the combination cannot be steered on.

    Parameters
    ----------
    params
        The combination.
    feedback, rear_feedback
        The configuration's.
    camera
        Whether the run includes a camera.
    camera_units
        The towed units that carry a camera rig (``None``: every one).

    Raises
    ------
    ValueError
        The camera on a combination whose first towed unit is not a semi-trailer; a first-unit feedback a unit
        behind it cannot have; a ``rear_feedback`` of the wrong length, with an unknown estimate, or steering a unit
        without a steerable axle; a unit steered on a camera estimate without a rig on it.
    """
    per_unit = unit_feedback_sources()
    if not params.trailer.front_load:
        if feedback not in per_unit or uses_camera(feedback):
            raise ValueError(f"feedback = {feedback!r}: {CAMERA_UNIT}")
        if camera:
            raise ValueError(f"estimators: the run includes a camera; {CAMERA_UNIT}")
    if not one_semi_trailer(params) and feedback not in per_unit:
        raise ValueError(
            f"feedback = {feedback!r} estimates the first towed unit only; {params.name!r} is steered on one of "
            f"{', '.join(per_unit)}"
        )
    behind = params.n_units - 2
    if rear_feedback is not None:
        _check_rear(params, rear_feedback, per_unit, behind)
    for unit, key in steered_units(params, feedback, rear_feedback):
        name = feedback if unit == 1 else rear_feedbacks(params, feedback, rear_feedback)[unit - 2]
        if camera_units is not None and uses_camera(name) and unit not in camera_units:
            field = "feedback" if unit == 1 else f"rear_feedback[{unit - 2}]"
            raise ValueError(
                f"{field} = {name!r} steers towed unit {unit} on its camera ({key}), but no camera.rigs entry is "
                f"on unit {unit} (the rigs are on units {', '.join(map(str, sorted(camera_units)))})"
            )


def _check_rear(params: VehicleParams, rear_feedback: tuple[str, ...], per_unit: tuple[str, ...], behind: int) -> None:
    """Refuse a ``rear_feedback`` of the wrong length, with an unknown estimate or steering an unsteerable unit."""
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
