"""What a camera run records per frame: whether the motion was accepted, why not, and its quality figures.

The columns are NaN between frames. Reasons are stored as indices into
:data:`sensor.vo.quality.REJECTION_REASONS` (NaN when there is none), so the Parquet series stays numeric and
:func:`scenarios.run.metrics.camera_frame_metrics` can count them by name.
"""

from __future__ import annotations

import math
from typing import Any

from sensor.vo.quality import QUALITY_COLUMNS, REJECTION_REASONS
from sensor.vo.self_calibration import SELF_CALIBRATION_COLUMNS

CAMERA_COLUMNS: list[str] = [
    "vo_valid",
    "vo_reason",
    "vo_estimate_reason",
    *(f"vo_{name}" for name in QUALITY_COLUMNS),
    "render_ms",
    "vo_ms",
    *(f"selfcal_{name}" for name in SELF_CALIBRATION_COLUMNS),
]
"""Per camera frame (NaN between frames): whether its motion was accepted, why not and why there is no
estimate (indices into :data:`sensor.vo.quality.REJECTION_REASONS`, NaN when none), its quality figures, and
the online self-calibration after the frame (``selfcal_roll_deg``, ``_pitch_deg``, ``_yaw_deg`` of the right
camera's residual rotation, ``selfcal_sigma_deg`` its worst standard deviation, ``selfcal_residual_px`` the RMS
vertical-disparity residual, ``selfcal_rows``/``selfcal_ground`` the matches and road points used; NaN when
``camera.self_calibration`` is off)."""
_REASON_CODES = {code: float(i) for i, code in enumerate(REJECTION_REASONS)}


def reason_code(reason: str | None) -> float:
    """Index of a rejection reason in :data:`~sensor.vo.quality.REJECTION_REASONS` (NaN: no reason)."""
    return _REASON_CODES.get(reason, float(_REASON_CODES["vo_failed"])) if reason else math.nan


def camera_row(shot: Any) -> dict[str, float]:
    """The camera columns of one tick from a :class:`~scenarios.camera.pipeline.CameraFrame`."""
    calibration = getattr(shot, "self_calibration", None) or {}
    return {
        "vo_valid": float(shot.valid),
        "vo_reason": reason_code(shot.reason),
        "vo_estimate_reason": reason_code(shot.estimate_reason),
        **{f"vo_{name}": float(shot.quality[name]) for name in QUALITY_COLUMNS},
        "render_ms": 1e3 * shot.render_s,
        "vo_ms": 1e3 * shot.vo_s,
        **{f"selfcal_{name}": float(calibration.get(name, math.nan)) for name in SELF_CALIBRATION_COLUMNS},
    }
