"""VISO-OT in the loop: the trailer's stereo camera, its frames' quality, and its estimate after the latency.

The camera (:class:`scenarios.camera.delivery.CameraFeed`) takes a frame on every camera tick; its estimate
reaches the controller ``camera.latency_s`` later, serial or pipelined alike. What a run records per frame —
whether its motion was accepted, why not and its quality figures — goes in the row of the tick the frame was
taken on, which waits for the frame when a worker still renders it. Between frames those columns are NaN.
Reasons are stored as indices into :data:`sensor.vo.quality.REJECTION_REASONS` (NaN when there is none), so the
Parquet series stays numeric and :func:`scenarios.run.metrics.camera_frame_metrics` can count them by name.

Each rig of the run (``camera.rigs``) is one :class:`VisoOt` on the towed unit it is mounted on: the first towed
unit's records the columns above; a unit ``k`` of the combination behind it records the same columns with ``k``
appended (``offtracking_viso_ot3``, ``vo_valid3``, …; :func:`camera_columns`), through
:class:`~.further_units.FurtherUnitsParticipant`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from sensor.vo.quality import QUALITY_COLUMNS, REJECTION_REASONS
from sensor.vo.self_calibration import SELF_CALIBRATION_COLUMNS
from vehicle_model.offtracking import BUFFER_FILLING, OfftrackingEstimate

from ..camera_schema import rig_units
from .participant import Column, LoopContext, Record, TickInput

__all__ = [
    "CAMERA_COLUMNS",
    "VisoOt",
    "camera_columns",
    "camera_row",
    "column_suffix",
    "reason_code",
    "rig_index_of",
    "viso_ot",
    "viso_ot_unit",
]


def column_suffix(unit: int) -> str:
    """What the columns of towed unit ``unit``'s estimators append to the first's: nothing for the first, the unit's
    number in the combination (``unit + 1``) for the others."""
    return "" if unit == 1 else str(unit + 1)


def camera_columns(unit: int = 1) -> tuple[Column, ...]:
    """The per-frame camera columns of the rig on towed unit ``unit`` (:data:`CAMERA_COLUMNS` for the first)."""
    k = column_suffix(unit)
    camera: dict[str, Any] = {"role": "diagnostic", "estimator": "viso_ot"}
    if unit > 1:  # the first towed unit's are declared as they always were
        camera["vehicle_unit"] = unit + 1
    return (
        Column(f"vo_valid{k}", "-", "1 when the frame's motion was accepted", **{**camera, "role": "flag"}),
        Column(f"vo_reason{k}", "-", "why not: index into sensor.vo.quality.REJECTION_REASONS", **camera),
        Column(f"vo_estimate_reason{k}", "-", "why there is no estimate: index into REJECTION_REASONS", **camera),
        *(
            Column(f"vo_{name}{k}", "-", "the frame's quality figure (sensor.vo.quality)", **camera)
            for name in QUALITY_COLUMNS
        ),
        Column(f"render_ms{k}", "ms", "wall time of the frame's rendering", **camera),
        Column(f"vo_ms{k}", "ms", "wall time of the frame's odometry and VISO-OT", **camera),
        *(
            Column(
                f"selfcal_{name}{k}",
                "-",
                "online self-calibration after the frame (sensor.vo.self_calibration)",
                **camera,
            )
            for name in SELF_CALIBRATION_COLUMNS
        ),
    )


CAMERA_COLUMNS: tuple[Column, ...] = camera_columns(1)
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


def camera_row(frame: Any, unit: int = 1) -> dict[str, float]:
    """The camera columns of one processed frame (:class:`~sensor.frame_odometry.CameraFrame`) of the rig on towed
    unit ``unit`` (:func:`camera_columns`)."""
    calibration = getattr(frame, "self_calibration", None) or {}
    row = {
        "vo_valid": float(frame.valid),
        "vo_reason": reason_code(frame.reason),
        "vo_estimate_reason": reason_code(frame.estimate_reason),
        **{f"vo_{name}": float(frame.quality[name]) for name in QUALITY_COLUMNS},
        "render_ms": 1e3 * frame.render_s,
        "vo_ms": 1e3 * frame.vo_s,
        **{f"selfcal_{name}": float(calibration.get(name, math.nan)) for name in SELF_CALIBRATION_COLUMNS},
    }
    k = column_suffix(unit)
    return row if not k else {f"{name}{k}": value for name, value in row.items()}


class _FrameValues:
    """A tick's camera columns, known once its frame is processed (a :class:`~.participant.PendingValues`)."""

    __slots__ = ("column", "estimate", "shot", "unit")

    def __init__(self, shot: Any, estimate: float, column: str, unit: int) -> None:
        self.shot = shot
        self.estimate = estimate
        self.column = column
        self.unit = unit

    @property
    def ready(self) -> bool:
        return self.shot.frame is not None

    def values(self) -> Mapping[str, float]:
        return {self.column: self.estimate, **camera_row(self.shot.frame, self.unit)}


class VisoOt:
    """The camera estimator: a frame on every camera tick, the latest released frame's VISO-OT estimate.

    Parameters
    ----------
    feed
        The camera (:class:`scenarios.camera.delivery.CameraFeed`).
    unit
        The towed unit its rig is on (1: the first; :func:`camera_columns` for the others' columns).

    Attributes
    ----------
    released : list
        The frames the latency released on the last tick, oldest first (fused VISO-OT reads their motions).
    camera_in_trailer : numpy.ndarray
        4×4 pose of the left camera on its unit, as VISO-OT uses it.
    """

    name = "viso_ot"
    columns: tuple[Column, ...] = (
        Column.estimate("viso_ot", "VISO-OT off-tracking of the latest released frame"),
        *CAMERA_COLUMNS,
    )
    """The first towed unit's columns (an instance on another unit declares its own, :func:`camera_columns`)."""

    def __init__(self, feed: Any, unit: int = 1) -> None:
        self.unit = unit
        if unit != 1:
            self.columns = (
                Column.estimate("viso_ot", "VISO-OT off-tracking of the latest released frame", vehicle_unit=unit + 1),
                *camera_columns(unit),
            )
        self.column = self.columns[0].name
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
        self.shot = feed.capture(tick.index, tick.state, tick.measured) if tick.camera_frame else None
        value = feed.deliver(tick.index)  # released by the latency, then held
        if feed.released:
            latest = feed.released[-1].frame
            reason = "" if value is not None else (latest.estimate_reason or BUFFER_FILLING)
            self.estimate = OfftrackingEstimate.of(value, reason=reason)
        return self.estimate

    def record(self) -> Record:
        """The estimate, and on a frame's tick the frame's columns (pending while it is rendered elsewhere)."""
        if self.shot is None:
            return {self.column: self.estimate.value}
        return _FrameValues(self.shot, self.estimate.value, self.column, self.unit)

    def finish(self) -> None:
        """Process every frame still in flight (their estimates stay unreleased)."""
        self.feed.finish()

    def report(self) -> dict[str, float]:
        """Where the camera's time went (:meth:`scenarios.camera.delivery.CameraFeed.timings`)."""
        return self.feed.timings()  # type: ignore[no-any-return]

    def close(self) -> None:
        """Stop the render workers, if any."""
        self.feed.close()


def rig_index_of(config: Any, params: Any, unit: int) -> int | None:
    """The index of the rig on towed unit ``unit`` (``camera.rigs``, or the defaults), or ``None``: no rig there."""
    units = rig_units(config.camera, params)
    return units.index(unit) if unit in units else None


def _feed(context: LoopContext, rig_index: int) -> Any:
    """The camera of rig ``rig_index`` (:class:`scenarios.camera.delivery.CameraFeed`), rendered here or by
    ``camera_workers`` processes."""
    from ..camera.delivery import CameraFeed  # rendering and OpenGL only when a camera runs

    rig = {"rig_index": rig_index} if rig_index else {}  # rig 0 is the camera's default
    # on a terrain the world is draped on it and VISO-OT runs in the level frame (docs/terrain_camera.md)
    return CameraFeed(context.setup, workers=context.camera_workers, terrain=context.setup.terrain, **rig)


def viso_ot(context: LoopContext) -> VisoOt:
    """The registry's builder of VISO-OT on the first towed unit: the rig mounted on it."""
    setup = context.setup
    index = rig_index_of(setup.config, setup.params, 1)
    return VisoOt(_feed(context, 0 if index is None else index))


def viso_ot_unit(context: LoopContext, unit: int) -> VisoOt | None:
    """The registry's builder of VISO-OT on towed unit ``unit`` ≥ 2: its rig's camera (``None``: no rig on it)."""
    setup = context.setup
    index = rig_index_of(setup.config, setup.params, unit)
    return None if index is None else VisoOt(_feed(context, index), unit)
