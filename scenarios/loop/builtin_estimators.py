"""The built-in estimators' declarations: the entries :mod:`scenarios.registry` loads first, in this order.

Each builder imports its estimator's module only when a run builds it (:mod:`.estimators`,
:mod:`.camera_estimator`, the offline adapters of :mod:`.offline`), so reading the registry's names never imports the
odometry or OpenGL. VISO-OT has no offline adapter: ``offtrack estimate`` is its odometry on the recording's frames.
"""

from __future__ import annotations

from typing import Any

from ..registry import TRUTH, EstimatorEntry

__all__ = ["BUILTIN_ESTIMATORS"]


def _zero_slip(context: Any) -> Any:
    from .estimators import zero_slip

    return zero_slip(context)


def _zero_slip_unit(context: Any, unit: int) -> Any:
    from .estimators import zero_slip_unit

    return zero_slip_unit(context, unit)


def _zero_slip_offline(context: Any) -> Any:
    from .offline import zero_slip_offline

    return zero_slip_offline(context)


def _fused_viso_ot_offline(context: Any) -> Any:
    from .offline import fused_viso_ot_offline

    return fused_viso_ot_offline(context)


def _viso_ot(context: Any) -> Any:
    from .camera_estimator import viso_ot

    return viso_ot(context)


def _viso_ot_unit(context: Any, unit: int) -> Any:
    from .camera_estimator import viso_ot_unit

    return viso_ot_unit(context, unit)


def _fused_viso_ot(context: Any) -> Any:
    from .estimators import fused_viso_ot

    return fused_viso_ot(context)


def _fused_viso_ot_unit(context: Any, unit: int) -> Any:
    from .estimators import fused_viso_ot_unit

    return fused_viso_ot_unit(context, unit)


def _ground_truth(context: Any) -> Any:
    from .estimators import ground_truth

    return ground_truth(context)


BUILTIN_ESTIMATORS: tuple[EstimatorEntry, ...] = (
    EstimatorEntry(
        "zero_slip",
        "Cheng's zero-slip estimate from the tractor's signals (blind to tyre slip)",
        _zero_slip,
        colour="tab:orange",
        label="zero-slip (Cheng)",
        per_unit=True,
        build_unit=_zero_slip_unit,
        offline=_zero_slip_offline,
    ),
    EstimatorEntry(
        "viso_ot",
        "VISO-OT: each towed unit's stereo camera, visual odometry and the kingpin path (renders; slow)",
        _viso_ot,
        needs_camera=True,
        colour="tab:green",
        label="VISO-OT",
        per_unit=True,
        build_unit=_viso_ot_unit,
    ),
    EstimatorEntry(
        "viso_ot_fused",
        "fused VISO-OT: a Kalman filter of each unit's gyro, wheel speed and steer with its camera (renders)",
        _fused_viso_ot,
        requires=("viso_ot",),
        needs_camera=True,
        colour="tab:purple",
        label="fused VISO-OT",
        per_unit=True,
        build_unit=_fused_viso_ot_unit,
        offline=_fused_viso_ot_offline,
    ),
    EstimatorEntry(
        TRUTH,
        "ground truth: the exact kingpin path of the simulation (de Saxe & Cebon 2018, eqs (3)–(7))",
        _ground_truth,
        always=True,
        colour="tab:blue",
        label="truth",
        per_unit=True,
    ),
)
"""The built-in estimators, in registration order."""
