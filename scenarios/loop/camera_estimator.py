"""VISO-OT in the loop: the trailer's stereo camera, its frames' quality, and its estimate after the latency.

The camera (:class:`scenarios.camera.delivery.CameraFeed`) takes a frame on every camera tick; its estimate
reaches the controller ``camera.latency_s`` later, serial or pipelined alike. What a run records per frame —
whether its motion was accepted, why not and its quality figures — goes in the row of the tick the frame was
taken on, which waits for the frame when a worker still renders it. Between frames those columns are NaN.
Reasons are stored as indices into :data:`sensor.vo.quality.REJECTION_REASONS` (NaN when there is none), so the
Parquet series stays numeric and :func:`scenarios.run.metrics.camera_frame_metrics` can count them by name.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from sensor.vo.quality import QUALITY_COLUMNS, REJECTION_REASONS
from sensor.vo.self_calibration import SELF_CALIBRATION_COLUMNS
from vehicle_model.offtracking import BUFFER_FILLING, OfftrackingEstimate

from .participant import Column, LoopContext, Record, TickInput

__all__ = ["CAMERA_COLUMNS", "VisoOt", "camera_row", "reason_code", "viso_ot"]

_CAMERA = {"role": "diagnostic", "estimator": "viso_ot"}
CAMERA_COLUMNS: tuple[Column, ...] = (
    Column("vo_valid", "-", "1 when the frame's motion was accepted", role="flag", estimator="viso_ot"),
    Column("vo_reason", "-", "why not: index into sensor.vo.quality.REJECTION_REASONS", **_CAMERA),
    Column("vo_estimate_reason", "-", "why there is no estimate: index into REJECTION_REASONS", **_CAMERA),
    *(
        Column(f"vo_{name}", "-", "the frame's quality figure (sensor.vo.quality)", **_CAMERA)
        for name in QUALITY_COLUMNS
    ),
    Column("render_ms", "ms", "wall time of the frame's rendering", **_CAMERA),
    Column("vo_ms", "ms", "wall time of the frame's odometry and VISO-OT", **_CAMERA),
    *(
        Column(
            f"selfcal_{name}", "-", "online self-calibration after the frame (sensor.vo.self_calibration)", **_CAMERA
        )
        for name in SELF_CALIBRATION_COLUMNS
    ),
)
"""Per camera frame (NaN between frames): whether its motion was accepted, why not and why there is no
estimate, its quality figures, its times, and the online self-calibration after the frame (``selfcal_roll_deg``,
``_pitch_deg``, ``_yaw_deg`` of the right camera's residual rotation, ``selfcal_sigma_deg`` its worst standard
deviation, ``selfcal_residual_px`` the RMS vertical-disparity residual, ``selfcal_rows``/``selfcal_ground`` the
matches and road points used; NaN when ``camera.self_calibration`` is off)."""

_REASON_CODES = {code: float(i) for i, code in enumerate(REJECTION_REASONS)}
NO_FRAME_YET = "no_previous_frame"
"""Why there is no estimate before the first frame's is released."""


def reason_code(reason: str | None) -> float:
    """Index of a rejection reason in :data:`~sensor.vo.quality.REJECTION_REASONS` (NaN: no reason)."""
    return _REASON_CODES.get(reason, float(_REASON_CODES["vo_failed"])) if reason else math.nan


def camera_row(frame: Any) -> dict[str, float]:
    """The camera columns of one processed frame (:class:`~sensor.frame_odometry.CameraFrame`)."""
    calibration = getattr(frame, "self_calibration", None) or {}
    return {
        "vo_valid": float(frame.valid),
        "vo_reason": reason_code(frame.reason),
        "vo_estimate_reason": reason_code(frame.estimate_reason),
        **{f"vo_{name}": float(frame.quality[name]) for name in QUALITY_COLUMNS},
        "render_ms": 1e3 * frame.render_s,
        "vo_ms": 1e3 * frame.vo_s,
        **{f"selfcal_{name}": float(calibration.get(name, math.nan)) for name in SELF_CALIBRATION_COLUMNS},
    }


class _FrameValues:
    """A tick's camera columns, known once its frame is processed (a :class:`~.participant.PendingValues`)."""

    __slots__ = ("estimate", "shot")

    def __init__(self, shot: Any, estimate: float) -> None:
        self.shot = shot
        self.estimate = estimate

    @property
    def ready(self) -> bool:
        return self.shot.frame is not None

    def values(self) -> Mapping[str, float]:
        return {"offtracking_viso_ot": self.estimate, **camera_row(self.shot.frame)}


class VisoOt:
    """The camera estimator: a frame on every camera tick, the latest released frame's VISO-OT estimate.

    Parameters
    ----------
    feed
        The camera (:class:`scenarios.camera.delivery.CameraFeed`).

    Attributes
    ----------
    released : list
        The frames the latency released on the last tick, oldest first (fused VISO-OT reads their motions).
    camera_in_trailer : numpy.ndarray
        4×4 pose of the left camera on the trailer, as VISO-OT uses it.
    """

    name = "viso_ot"
    columns: tuple[Column, ...] = (
        Column.estimate("viso_ot", "VISO-OT off-tracking of the latest released frame"),
        *CAMERA_COLUMNS,
    )

    def __init__(self, feed: Any) -> None:
        self.feed = feed
        self.camera_in_trailer = feed.camera_in_trailer
        self.shot: Any = None
        self.estimate = OfftrackingEstimate(math.nan, math.nan, NO_FRAME_YET)

    @property
    def released(self) -> list[Any]:
        """The frames released on the last tick."""
        return self.feed.released  # type: ignore[no-any-return]

    def update(self, tick: TickInput) -> OfftrackingEstimate:
        """Take a frame on a camera tick; release what the latency allows; the held estimate."""
        feed = self.feed
        self.shot = feed.capture(tick.index, tick.state) if tick.camera_frame else None
        value = feed.deliver(tick.index)  # released by the latency, then held
        if feed.released:
            latest = feed.released[-1].frame
            reason = "" if value is not None else (latest.estimate_reason or BUFFER_FILLING)
            self.estimate = OfftrackingEstimate.of(value, reason=reason)
        return self.estimate

    def record(self) -> Record:
        """The estimate, and on a frame's tick the frame's columns (pending while it is rendered elsewhere)."""
        if self.shot is None:
            return {"offtracking_viso_ot": self.estimate.value}
        return _FrameValues(self.shot, self.estimate.value)

    def finish(self) -> None:
        """Process every frame still in flight (their estimates stay unreleased)."""
        self.feed.finish()

    def report(self) -> dict[str, float]:
        """Where the camera's time went (:meth:`scenarios.camera.delivery.CameraFeed.timings`)."""
        return self.feed.timings()  # type: ignore[no-any-return]

    def close(self) -> None:
        """Stop the render workers, if any."""
        self.feed.close()


def viso_ot(context: LoopContext) -> VisoOt:
    """The registry's builder of VISO-OT: the scenario's camera, rendered here or by ``camera_workers`` processes."""
    from ..camera.delivery import CameraFeed  # rendering and OpenGL only when a camera runs

    return VisoOt(CameraFeed(context.setup, workers=context.camera_workers))
