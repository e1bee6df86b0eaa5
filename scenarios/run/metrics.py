"""Run metrics: off-tracking of the truth, estimator errors against it, the feedback's fallback and weighting
(:mod:`.feedback_use`), the roundabout-test verdict, the swept-path width (:mod:`.swept_width`) and the run's own
verdict (:mod:`.verdicts`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from vehicle_model.geometry import kingpin_position, radial_extent, towed_outlines, tractor_outline
from vehicle_model.parameters import VehicleParams

from ..loop.participant import estimate_column
from ..loop.schema import FIRST_TOWED_UNIT, RecordedColumns, estimate_columns, estimator_names, schema_of, std_column
from .feedback_use import feedback_fallback, feedback_weighted
from .path_offtracking import combination_offtracking, rear_point_columns
from .swept_width import swept_path_metrics
from .verdicts import run_verdict, with_roundabout_test

ROUNDABOUT_OUTER_RADIUS = 12.50
"""97/27/EC Annex I §7.6.1 / UK C&U regs 13A: outer circle [m]."""
ROUNDABOUT_INNER_RADIUS = 5.30
"""Inner circle [m]."""
FRONT_FITTING_RADIUS = 2.04
"""Largest distance from the kingpin to a semi-trailer's front corner, EU 1230/2012 Annex I Part D [m]: the EU
wheelbase bound puts the kingpin on ``12.50 − 2.04 = 10.46 m`` (docs/vehicle_dynamics.md §5.2)."""


def equivalent_wheelbase_limit(
    kingpin_radius: float, trailer_width: float, inner: float = ROUNDABOUT_INNER_RADIUS
) -> float:
    """Largest equivalent wheelbase [m] of an unsteered trailer whose inner side clears the ``inner`` circle with
    its kingpin on ``kingpin_radius``: ``sqrt(R5² − (R_inner + W/2)²)`` (zero slip, docs/vehicle_dynamics.md §5.2).

    With ``R5 = 12.50 − 2.04`` and ``W = 2.55 m`` it is the EU bound, 8.135 m; NaN when the circle cannot be cleared.
    """
    clear = kingpin_radius**2 - (inner + 0.5 * trailer_width) ** 2
    return float(np.sqrt(clear)) if clear >= 0 else float("nan")


def rms(values: np.ndarray) -> float:
    """Root mean square of the finite values (NaN when there are none)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v**2))) if v.size else float("nan")


def max_abs(values: np.ndarray) -> float:
    """Largest magnitude of the finite values (NaN when there are none)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.max(np.abs(v))) if v.size else float("nan")


def estimator_errors(truth: np.ndarray, estimate: np.ndarray, std: np.ndarray | None = None) -> dict[str, float]:
    """RMS, mean and largest error of ``estimate`` against ``truth`` where both exist, and the fraction of the
    truth's valid samples on which the estimator had an estimate; with the estimator's ``std``, also the share of
    the errors within 2σ (``within_2sigma``) and the mean σ (``mean_std``)."""
    truth = np.asarray(truth, dtype=float)
    estimate = np.asarray(estimate, dtype=float)
    valid_truth = np.isfinite(truth)
    both = valid_truth & np.isfinite(estimate)
    err = estimate[both] - truth[both]
    out = {
        "rms_error": rms(err),
        "max_abs_error": max_abs(err),
        "mean_error": float(np.mean(err)) if err.size else float("nan"),
        "valid_fraction": float(both.sum() / valid_truth.sum()) if valid_truth.any() else 0.0,
    }
    if std is not None:
        sigma = np.asarray(std, dtype=float)[both]
        out["within_2sigma"] = float(np.mean(np.abs(err) <= 2.0 * sigma)) if err.size else float("nan")
        out["mean_std"] = float(np.mean(sigma)) if err.size else float("nan")
    return out


def roundabout_verdict(
    params: VehicleParams,
    x: np.ndarray,
    y: np.ndarray,
    psi1: np.ndarray,
    gamma: np.ndarray,
    centre: tuple[float, float],
    outer: float = ROUNDABOUT_OUTER_RADIUS,
    inner: float = ROUNDABOUT_INNER_RADIUS,
    further: list[np.ndarray] | None = None,
) -> dict[str, Any]:
    """Verdict of the roundabout test over the given poses.

    Pass if no outermost point of the towing vehicle leaves the ``outer`` circle and no point of a
    towed unit enters the ``inner`` circle: the wording of 97/27/EC Annex I §7.6.1 for a combination
    (docs/vehicle_dynamics.md §5.1). The radii are measured from ``centre``; the nearest point of an outline
    may lie on an edge, not a corner. ``further`` holds the articulation angles of the units behind the first
    towed one (``gamma2``, ``gamma3``), for a longer combination; ``inner_unit`` says which unit (2 the first towed
    one) comes nearest.

    It also says where the tractor put the kingpin (``kingpin_radius``, the median over the poses) and what that
    asks of an unsteered trailer (docs/vehicle_dynamics.md §5.2–5.4): ``equivalent_wheelbase_limit``, the largest
    equivalent wheelbase that clears the inner circle from there (:func:`equivalent_wheelbase_limit`), against the
    EU bound's ``eu_equivalent_wheelbase_limit`` (kingpin on ``eu_kingpin_radius = outer − 2.04 m``), the
    trailer's own ``trailer_equivalent_wheelbase`` (every axle, unsteered; :meth:`VehicleParams.equivalent_wheelbase`)
    and the tractor's ``tractor_equivalent_wheelbase`` (its zero-slip rear point behind the steer axle).
    """
    tractor = tractor_outline(params, x, y, psi1)
    tractor_out, _ = radial_extent(tractor, centre)
    towed_in = [
        float(radial_extent(o, centre)[1].min()) for o in towed_outlines(params, x, y, psi1, [gamma, *(further or [])])
    ]
    outer_max = float(tractor_out.max())
    inner_min = min(towed_in)
    kingpin = kingpin_position(params, x, y, psi1)
    kingpin_radius = float(np.median(np.hypot(kingpin[..., 0] - centre[0], kingpin[..., 1] - centre[1])))
    width = params.trailer.width
    return {
        "pass": bool(outer_max <= outer and inner_min >= inner),
        "outer_radius_max": outer_max,
        "inner_radius_min": inner_min,
        "outer_margin": outer - outer_max,
        "inner_margin": inner_min - inner,
        "inner_unit": 2 + int(np.argmin(towed_in)),
        "kingpin_radius": kingpin_radius,
        "equivalent_wheelbase_limit": equivalent_wheelbase_limit(kingpin_radius, width, inner),
        "tractor_equivalent_wheelbase": params.tractor_equivalent_wheelbase(),
        "eu_kingpin_radius": outer - FRONT_FITTING_RADIUS,
        "eu_equivalent_wheelbase_limit": equivalent_wheelbase_limit(outer - FRONT_FITTING_RADIUS, width, inner),
        "trailer_equivalent_wheelbase": params.equivalent_wheelbase(),
    }


def after_warmup(columns: dict[str, np.ndarray], follow_point_offset: float) -> np.ndarray:
    """Mask of the samples after warm-up: the truth is valid and one more trailer length has been driven."""
    truth = columns["offtracking_truth"]
    valid = np.isfinite(truth)
    if not valid.any():
        return valid
    kp = np.column_stack([columns["kingpin_x"], columns["kingpin_y"]])
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(kp, axis=0).T))])
    start = travelled[np.flatnonzero(valid)[0]] + follow_point_offset
    return valid & (travelled >= start)


def trailer_steering_metrics(columns: dict[str, np.ndarray], steerable_trailer_axles: list[str]) -> dict[str, Any]:
    """Largest steer angle [deg] and fraction of time saturated of every steerable trailer axle."""
    out: dict[str, Any] = {}
    for name in steerable_trailer_axles:
        steer = columns.get(f"steer_{name}")
        if steer is None:
            continue
        saturated = columns.get(f"saturated_{name}")
        out[name] = {
            "max_abs_steer_deg": float(np.degrees(np.max(np.abs(steer)))) if steer.size else 0.0,
            "saturated_fraction": float(np.mean(saturated > 0.5)) if saturated is not None and saturated.size else 0.0,
        }
    return out


def steering_reach(columns: dict[str, np.ndarray], settled: np.ndarray) -> dict[str, float] | None:
    """Where the path was beyond the trailer steering's reach, after warm-up: ``share_of_path`` (of the distance
    the kingpin drove) and ``distance_m`` on which the controller's feed-forward needed an axle past its lock
    (``trailer_beyond_reach``, :attr:`controller.path_following.TrailerSteeringController.beyond_reach`); ``None``
    for a run without the column (unsteered)."""
    flag = columns.get("trailer_beyond_reach")
    if flag is None or not settled.any():
        return None
    step = np.hypot(
        np.diff(columns["kingpin_x"], prepend=columns["kingpin_x"][:1]),
        np.diff(columns["kingpin_y"], prepend=columns["kingpin_y"][:1]),
    )
    driven = float(np.sum(step[settled]))
    beyond = float(np.sum(step[settled & (flag > 0.5)]))
    return {"share_of_path": beyond / driven if driven > 0 else 0.0, "distance_m": beyond}


def compute_metrics(
    scenario: str,
    feedback: str,
    params: VehicleParams,
    columns: dict[str, np.ndarray],
    estimator_names: list[str],
    annulus_centre: tuple[float, float] | None,
    turn_span: tuple[float, float],
    *,
    reference: np.ndarray | None = None,
    turn_centre: tuple[float, float] | None = None,
    rear_feedback: tuple[str, ...] = (),
    uncertain_feedback: str | None = None,
) -> dict[str, Any]:
    """The ``metrics.json`` content of a run (without timing and status).

    With the ``reference`` path ``(m, 2)`` it also holds ``swept_path``, the swept-path width over the assessed turn
    (:func:`~scenarios.run.swept_width.swept_path_metrics`): radial about ``turn_centre`` (a roundabout's
    centre), or across the reference path when that is None.

    ``rear_feedback`` is the feedback of each unit behind the first towed one (``none`` where it is not steered,
    :func:`scenarios.unit_feedback.rear_feedbacks`): a steered one is judged by the same verdict as the first, on
    its own off-tracking, and its flags are merged into the run's, each reason naming the unit.

    ``uncertain_feedback`` (``controller.uncertain_feedback``) is written beside ``feedback_weighted``, the ticks
    steered on a weighted-down estimate (:func:`~.feedback_use.feedback_weighted`), which a run records unless it
    is ``drop``.

    ``valid_fraction`` means one thing everywhere: the share of the ticks *on which the truth exists* (it
    starts once the kingpin has driven one trailer length) on which that source had a value; for the truth
    it is therefore 1 whenever it exists at all, and ``truth.defined_fraction`` is the share of all ticks
    with a truth. A run that stopped before its first tick (interrupted during set-up) has empty columns:
    every figure is then NaN.
    """
    columns = _with_required_columns(columns, estimator_names)
    estimates = estimate_columns(columns)
    truth = columns["offtracking_truth"]
    geometric = columns["offtracking_truth_geometric"]
    both = np.isfinite(truth) & np.isfinite(geometric)
    settled = after_warmup(columns, params.follow_point_offset)
    steerable = [a.name for unit in params.trailers for a in unit.axles if a.steerable]
    metrics: dict[str, Any] = {
        "scenario": scenario,
        "feedback": feedback,
        "offtracking": {
            "truth": {
                "rms": rms(truth),
                "max_abs": max_abs(truth),
                "valid_fraction": 1.0 if np.isfinite(truth).any() else 0.0,
                "defined_fraction": float(np.isfinite(truth).mean()) if truth.size else 0.0,
            },
            "truth_after_warmup": {"rms": rms(truth[settled]), "max_abs": max_abs(truth[settled])},
            "truth_methods_max_disagreement": max_abs(truth[both] - geometric[both]) if both.any() else float("nan"),
            "estimators": {
                name: estimator_errors(truth, _estimate(columns, estimates, name), _std(columns, name))
                for name in estimator_names
            },
        },
        "roundabout_test": None,
        "trailer_steering": trailer_steering_metrics(columns, steerable),
    }
    reach = steering_reach(columns, settled)
    if reach is not None:
        metrics["steering_reach"] = reach
    units = further_unit_offtracking(params, columns, settled)
    if units:
        metrics["offtracking"]["units"] = units
    if truth.size and all(name in columns for name in rear_point_columns(params)):
        metrics["offtracking"]["combination"] = combination_offtracking_metrics(params, columns)
    fallback = feedback_fallback(columns, settled) if feedback != "none" else None
    if fallback is not None:
        metrics["feedback_fallback"] = fallback
    weighted = (
        feedback_weighted(columns, settled, uncertain_feedback=uncertain_feedback) if feedback != "none" else None
    )
    if weighted is not None:
        metrics["feedback_weighted"] = weighted
    verdict = run_verdict(
        feedback,
        metrics["offtracking"]["truth_after_warmup"],
        metrics["offtracking"]["estimators"],
        fallback,
        weighted,
    )
    for unit, unit_feedback in enumerate(rear_feedback, start=3):
        unit_metrics = units.get(str(unit))
        if unit_feedback == "none" or unit_metrics is None:
            continue
        unit_fallback = feedback_fallback(columns, settled, f"unit{unit}_estimate_used")
        if unit_fallback is not None:
            unit_metrics["feedback_fallback"] = unit_fallback
        unit_weighted = feedback_weighted(columns, settled, f"unit{unit}_feedback_weight", uncertain_feedback)
        if unit_weighted is not None:
            unit_metrics["feedback_weighted"] = unit_weighted
        settled_truth = {"rms": unit_metrics["rms_after_warmup"], "max_abs": unit_metrics["max_abs_after_warmup"]}
        unit_verdict = run_verdict(
            unit_feedback, settled_truth, unit_metrics["estimators"], unit_fallback, unit_weighted
        )
        unit_metrics["feedback"] = unit_feedback
        unit_metrics["verdict"] = unit_verdict
        verdict["flags"] += [{**f, "reason": f"unit {unit}: {f['reason']}"} for f in unit_verdict["flags"]]
        verdict["held"] = not verdict["flags"]
    metrics["verdict"] = verdict
    if rear_feedback:
        metrics["rear_feedback"] = list(rear_feedback)
    camera = camera_frame_metrics(columns)
    if camera is not None:
        metrics["camera"] = camera
    for unit, unit_metrics in units.items():
        unit_camera = camera_frame_metrics(columns, unit)
        if unit_camera is not None:
            unit_metrics["camera"] = unit_camera
    if annulus_centre is not None and truth.size:
        s = columns["path_progress"]
        in_turn = (s >= turn_span[0]) & (s <= turn_span[1])
        if in_turn.any():
            metrics["roundabout_test"] = roundabout_verdict(
                params,
                columns["X"][in_turn],
                columns["Y"][in_turn],
                columns["psi1"][in_turn],
                columns["gamma"][in_turn],
                annulus_centre,
                further=[columns[name][in_turn] for name in further_angles(params)],
            )
    metrics["verdict"] = with_roundabout_test(verdict, metrics["roundabout_test"])
    if reference is not None and truth.size:
        metrics["swept_path"] = swept_path_metrics(params, columns, reference, turn_centre, turn_span)
    return metrics


def _estimate(
    columns: dict[str, np.ndarray],
    estimates: dict[tuple[str, int], Any],
    name: str,
) -> np.ndarray:
    """The values of estimator ``name``'s estimate of the first towed unit (as the estimator names its column when
    the run did not record it: an empty run's)."""
    column = estimates.get((name, FIRST_TOWED_UNIT))
    return columns[column.name if column is not None else estimate_column(name)]


def _std(columns: dict[str, np.ndarray], name: str) -> np.ndarray | None:
    """The standard deviation of estimator ``name``'s estimate of the first towed unit (``None``: none)."""
    column = std_column(columns, name)
    return None if column is None else columns[column.name]


def combination_offtracking_metrics(params: VehicleParams, columns: dict[str, np.ndarray]) -> dict[str, Any]:
    """``offtracking.combination``: the last unit's rear against the steer axle's path (:mod:`.path_offtracking`).

    Returns
    -------
    dict
        ``unit`` (the last unit's number), ``rms`` and ``max_abs`` [m] over the ticks where it is defined,
        ``defined_fraction``, and ``reference`` / ``point`` saying what was measured.
    """
    values = combination_offtracking(params, columns)
    return {
        "unit": params.n_units,
        "rms": rms(values),
        "max_abs": max_abs(values),
        "defined_fraction": float(np.isfinite(values).mean()) if values.size else 0.0,
        "reference": "path of the steer axle's centre",
        "point": f"unit {params.n_units}'s follow point",
    }


def further_angles(params: VehicleParams) -> list[str]:
    """The recorded articulation columns of the units behind the first towed one (``gamma2``, ``gamma3``)."""
    return [f"gamma{unit - 1}" for unit in range(3, params.n_units + 1)]


def further_unit_offtracking(
    params: VehicleParams, columns: dict[str, np.ndarray], settled: np.ndarray
) -> dict[str, dict[str, float]]:
    """Each further unit's true off-tracking (against its own coupling's path): RMS and largest, over the run and
    after the warm-up of the first towed unit once the unit's own is defined, and the errors of each estimate of
    that unit (``offtracking_<name><k>``) against it — with its standard deviation (``offtracking_<name><k>_std``),
    the share within 2σ — by unit number (``"3"``, ``"4"``)."""
    out: dict[str, dict[str, Any]] = {}
    recorded = estimate_columns(columns)
    for unit in range(3, params.n_units + 1):
        truth_column = recorded.get(("truth", unit))
        truth = np.asarray(columns[truth_column.name] if truth_column else np.zeros(0), dtype=float)
        if truth.shape != settled.shape:
            continue
        after = settled & np.isfinite(truth)
        estimates = {
            name: np.asarray(columns[column.name], dtype=float)
            for (name, of), column in recorded.items()
            if of == unit and name != "truth"
        }
        out[str(unit)] = {
            "rms": rms(truth),
            "max_abs": max_abs(truth),
            "rms_after_warmup": rms(truth[after]),
            "max_abs_after_warmup": max_abs(truth[after]),
            "defined_fraction": float(np.isfinite(truth).mean()) if truth.size else 0.0,
            "estimators": {
                name: estimator_errors(truth, values, _unit_std(columns, name, unit))
                for name, values in estimates.items()
            },
        }
    return out


def _unit_std(columns: dict[str, np.ndarray], name: str, unit: int) -> np.ndarray | None:
    """The standard deviation of estimator ``name``'s estimate of unit ``unit`` (``None``: none recorded)."""
    column = std_column(columns, name, unit)
    return None if column is None else np.asarray(columns[column.name], dtype=float)


_REQUIRED = ("time", "X", "Y", "psi1", "gamma", "kingpin_x", "kingpin_y", "path_progress")


def _with_required_columns(columns: dict[str, np.ndarray], estimator_names: list[str]) -> dict[str, np.ndarray]:
    """``columns`` with every column the metrics read (empty arrays for a run that recorded nothing)."""
    recorded = estimate_columns(columns)
    estimators = (estimate_column(n) for n in estimator_names if (n, FIRST_TOWED_UNIT) not in recorded)
    names = (*_REQUIRED, "offtracking_truth", "offtracking_truth_geometric", *estimators)
    empty = np.zeros(0)
    return RecordedColumns({**{name: empty for name in names}, **columns}, schema_of(columns))


def camera_frame_metrics(columns: dict[str, np.ndarray], suffix: str = "") -> dict[str, Any] | None:
    """Visual-odometry frame statistics of a camera run (``None`` without a camera); ``suffix``: of the rig on unit
    ``k`` of the combination behind the first towed one (``"3"``: its columns ``vo_valid3``, ``vo_reason3``).

    ``frames`` counts the camera frames after the first (which has no previous pair), ``valid_fraction`` the
    share whose motion was accepted, ``rejections`` how many were refused for each reason (the codes of
    :data:`sensor.vo.quality.REJECTION_REASONS`), and ``message`` says in words why there was no valid
    estimate at all when that happened.
    """
    valid = columns.get(f"vo_valid{suffix}")
    if valid is None:
        return None
    from sensor.vo.quality import REJECTION_REASONS  # light: a table of words

    frame = np.isfinite(valid)
    if frame.any():
        frame[np.flatnonzero(frame)[0]] = False  # the first frame has nothing to compare with
    n = int(frame.sum())
    accepted = int((valid[frame] > 0.5).sum())
    codes = list(REJECTION_REASONS)
    reason = columns.get(f"vo_reason{suffix}", np.full(valid.shape, np.nan))
    counts: dict[str, int] = {}
    for value in reason[frame & (valid < 0.5)]:
        code = codes[int(value)] if np.isfinite(value) and 0 <= int(value) < len(codes) else "unknown"
        counts[code] = counts.get(code, 0) + 1
    message = ""
    if n and not accepted:
        worst = max(counts, key=counts.__getitem__) if counts else "unknown"
        words = REJECTION_REASONS.get(worst, "the visual odometry gave no accepted motion")
        message = f"no valid estimate: all {n} camera frames were rejected, most because {words}"
    elif not n:
        message = "no camera frame was processed"
    return {
        "frames": n,
        "valid_frames": accepted,
        "valid_fraction": accepted / n if n else 0.0,
        "rejections": dict(sorted(counts.items(), key=lambda kv: -kv[1])),
        "message": message,
    }


def unit_estimator_names(columns: dict[str, np.ndarray], unit: int) -> list[str]:
    """The estimates of unit ``unit`` (behind the first towed one) recorded in a run's columns, as ``<name><k>``
    (``zero_slip3``: the zero-slip estimate of unit 3)."""
    return [f"{name}{unit}" for name in estimator_names(columns, unit)]


COUPLING_REFERENCE = "coupling_reference"
"""The key of a fused filter's following-camera counts in its participant's report and beside its unit's figures
(:func:`scenarios.loop.following_camera.reference_counts`)."""
_FUSED = "viso_ot_fused"


def with_coupling_references(metrics: dict[str, Any], reports: Mapping[str, Any]) -> dict[str, Any]:
    """``metrics`` with each fused filter's ``coupling_reference`` (``reports``: the loop's participants' reports by
    estimate key, ``viso_ot_fused`` the first towed unit's, ``viso_ot_fused<k>`` unit ``k``'s) beside its unit's
    figures: in ``offtracking`` for the first towed unit, in ``offtracking.units["<k>"]`` for unit ``k`` (left out
    where the run has no figures of that unit). A filter without a reference reports none: nothing is added."""
    for key, report in reports.items():
        if not key.startswith(_FUSED) or not isinstance(report, Mapping) or COUPLING_REFERENCE not in report:
            continue
        unit = key.removeprefix(_FUSED)
        offtracking = metrics["offtracking"]
        section = offtracking if unit == "" else (offtracking.get("units") or {}).get(unit)
        if section is not None:
            section[COUPLING_REFERENCE] = report[COUPLING_REFERENCE]
    return metrics


def coupling_reference_reports(metrics: Mapping[str, Any]) -> dict[str, Any]:
    """The reports :func:`with_coupling_references` placed in a run's ``metrics.json`` (by estimate key), for a
    report rebuilt from the run's files, which cannot count them again."""
    offtracking = metrics.get("offtracking") or {}
    sections = {_FUSED: offtracking, **{f"{_FUSED}{u}": own for u, own in (offtracking.get("units") or {}).items()}}
    return {
        key: {COUPLING_REFERENCE: own[COUPLING_REFERENCE]}
        for key, own in sections.items()
        if isinstance(own, Mapping) and COUPLING_REFERENCE in own
    }
