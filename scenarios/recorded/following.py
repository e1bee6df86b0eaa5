"""A following unit's recorded camera as the reference of a side rig's filter in ``offtrack estimate --rigs``.

In a run, a towed unit whose fused filter has ``coupling_reference`` on (a side rig's, ``fusion.side_rig``) takes the
camera of the nearest unit behind it whose camera looks along its unit, carried forward through the couplings
(:mod:`sensor.fusion_coupling`, :mod:`scenarios.loop.following_camera`). Offline the same filter takes the same
measurement: :func:`scenarios.recorded.rigs.estimate_rigs` estimates the rearmost unit first, and while a unit is
estimated its frames are kept (:class:`FollowerTrace`: each frame's time on the shared clock, its camera motion and
covariance when accepted, and its fused filter's ``β̂_ψ`` and variance once that filter has taken the frame's row).
A unit ahead of it then gets :class:`RecordedFollowingCamera`: each following frame is released on the lead's frame
row of the same instant (within :data:`SYNC_FRACTION` of the lead's median frame interval) and goes through the
loop's :class:`~scenarios.loop.following_camera.FollowingCamera` — the same transport (C1)–(C2), the same (C0) with
the follower's ``β̂_ψ`` at that row, the same (C3) and (C4) with its scrub demand and off-tracking std at that row,
the same rule that a following frame whose interval does not start at the lead
filter's anchor (a follower frame missing or refused, a lead frame missing) gives no measurement.

The articulations ``Γ_1 … Γ_m`` down to the follower's front coupling at each lead row are the lead's signals'
(``articulation``, ``articulation2``, …) where they hold them all, else the follower's signals' at the same instants
(the follower's filter needs them all); without either there is no reference.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sensor.fusion_coupling import CouplingMeasurement, CouplingReference, looks_along

from ..loop.following_camera import FollowingCamera, filter_scrub, filter_yaw_bias, reference_counts
from .inputs import EstimateInputs
from .unit_fusion import chain_signal_keys

__all__ = [
    "NO_SCRUB",
    "SYNC_FRACTION",
    "FollowerFrame",
    "FollowerTrace",
    "RecordedFollowingCamera",
    "coupling_summary",
    "following_reference",
]

NO_SCRUB = (float("nan"), float("nan"))
"""A following frame's scrub demand and off-tracking std where its unit has no fused filter (as
:func:`~scenarios.loop.following_camera.filter_scrub` gives them)."""

SYNC_FRACTION = 0.1
"""A following frame is the lead's frame of the same instant when their times on the shared clock differ by at most
this fraction of the lead's median frame interval (synchronised rigs: one logger's clock, frames of one trigger)."""


@dataclass(frozen=True)
class FollowerMotion:
    """An accepted frame's camera motion (4×4) and its 6×6 odometry covariance (``None``: the default)."""

    camera_motion: np.ndarray
    covariance: np.ndarray | None


@dataclass(frozen=True)
class FollowerFrame:
    """One processed frame of the following unit, as the loop's following camera reads a released frame.

    Attributes
    ----------
    time : float
        The frame's time on the shared clock [s].
    valid : bool
        Its motion was accepted.
    vo : FollowerMotion or None
        The motion and covariance (``None`` when not accepted).
    yaw_bias : (float, float, float) or None
        The follower's fused filter's ``β̂_ψ`` [rad/m], variance and last frame's scrub demand after the frame's row
        (``None``: no filter).
    scrub : (float, float)
        The follower's fused filter's last frame's scrub demand and its off-tracking std [m] after the frame's row,
        as (C3) and (C4) take them (NaN, NaN: no filter).
    """

    time: float
    valid: bool
    vo: FollowerMotion | None
    yaw_bias: tuple[float, ...] | None
    scrub: tuple[float, float] = NO_SCRUB


@dataclass
class FollowerTrace:
    """The processed frames of one rig's unit, kept while it is estimated (module notes).

    Attributes
    ----------
    inputs : EstimateInputs
        The rig's inputs (its unit, camera mounting, signals).
    frames : list of FollowerFrame
        Its processed frames in time order (a frame without images is not among them).
    """

    inputs: EstimateInputs
    frames: list[FollowerFrame] = field(default_factory=list)

    def add(self, time: float, frame: Any, fused: Any) -> None:
        """Keep a processed frame (:class:`sensor.frame_odometry.CameraFrame`) at ``time`` on the shared clock and
        the unit's fused filter (:class:`sensor.fusion.FusedVisoOt`, ``None``: none) after its row."""
        motion = FollowerMotion(np.array(frame.vo.camera_motion), frame.vo.covariance) if frame.valid else None
        self.frames.append(
            FollowerFrame(float(time), bool(frame.valid), motion, filter_yaw_bias(fused), filter_scrub(fused))
        )


@dataclass(frozen=True)
class _Shot:
    tick: int
    frame: FollowerFrame


class RecordedFollowingCamera:
    """The following unit's frames as the loop's following camera releases them, on the lead's rows (module notes).

    Parameters
    ----------
    reference
        The transport from the follower's camera to the lead's kingpin.
    frames
        The follower's frames by the lead's row they are released on.
    articulations
        ``Γ_1 … Γ_m`` at each lead row [rad] (rows × m; NaN: unknown, no measurement over that row).

    Attributes
    ----------
    following : FollowingCamera
        The loop's following camera it feeds.
    follower : int
        The following towed unit.
    matched : int
        The follower's frames released on a lead row.
    """

    def __init__(
        self, reference: CouplingReference, frames: dict[int, FollowerFrame], articulations: np.ndarray
    ) -> None:
        self.released: list[_Shot] = []
        self.follower, self.matched = reference.follower, len(frames)
        self._frames = frames
        self._articulations = articulations
        self._bias: tuple[float, ...] | None = None
        self._scrub: tuple[float, float] = NO_SCRUB
        self.following = FollowingCamera(reference, self, lambda: self._bias, lambda: self._scrub)

    def observe(self, row: int) -> None:
        """Keep the row's articulations; turn the following frame released on it, if any, into a measurement."""
        frame = self._frames.get(row)
        self.released = [] if frame is None else [_Shot(row, frame)]
        self._bias = None if frame is None else frame.yaw_bias
        self._scrub = NO_SCRUB if frame is None else frame.scrub
        gammas = self._articulations[row]
        self.following.observe(row, {"articulation": gammas[:1], "rear_articulation": gammas[1:]})

    def take(self, row: int) -> CouplingMeasurement | None:
        """The measurement of the following frame released on ``row`` (``None``: none)."""
        return self.following.take(row)


def coupling_summary(estimator: Any) -> dict[str, Any] | None:
    """``metrics.json``'s ``coupling_reference`` of a fused adapter (:class:`scenarios.loop.offline.
    OfflineFusedVisoOt`) whose settings take a following unit's camera: the follower's unit (``None``: none was
    estimated), its frames matched to the lead's rows, the measurements made of them and the frames refused by reason
    (:func:`scenarios.loop.following_camera.reference_counts`, a run's shape), and the measurements the filter used
    and rejected (``None`` for a filter whose settings do not take one)."""
    fused = getattr(estimator, "fused", None)
    if fused is None or not fused.noise.coupling_reference:
        return None
    reference = getattr(estimator, "reference", None)
    return {
        "follower_unit": None if reference is None else reference.follower,
        "frames_matched": 0 if reference is None else reference.matched,
        **reference_counts(None if reference is None else reference.following),
        "updates": fused.coupling_updates,
        "rejected": fused.coupling_rejected,
    }


def _articulations(
    lead: EstimateInputs, follower: EstimateInputs, signals: dict[str, np.ndarray] | None, shared: np.ndarray
) -> np.ndarray | None:
    """``Γ_1 … Γ_m`` at the lead's rows (module notes), or ``None`` when neither rig's signals hold them all."""
    keys = chain_signal_keys(follower.rig.unit)
    if signals is not None and all(key in signals for key in keys):
        return np.column_stack([signals[key] for key in keys])
    if follower.signals is not None:
        theirs = follower.signals.at(shared, follower.rig.params)
        if all(key in theirs for key in keys):
            return np.column_stack([theirs[key] for key in keys])
    return None


def following_reference(
    lead: EstimateInputs,
    traces: dict[int, FollowerTrace],
    times: np.ndarray,
    slots: np.ndarray,
    signals: dict[str, np.ndarray] | None,
    noise: Any,
) -> RecordedFollowingCamera | None:
    """The reference of ``lead``'s filter with settings ``noise``: the nearest unit behind with a trace whose camera
    looks along its unit (``traces`` by towed unit), its frames on the lead's rows (``times`` [s since the lead's
    first frame], ``slots``: the frame slot of each row, −1 a signals' row), or ``None`` — no such unit, or no
    articulations down to it."""
    behind = sorted(unit for unit in traces if unit > lead.rig.unit)
    follower = next((traces[u] for u in behind if looks_along(traces[u].inputs.camera_in_trailer)), None)
    if follower is None:
        return None
    shared = times + lead.recording.t0
    articulations = _articulations(lead, follower.inputs, signals, shared)
    if articulations is None:
        return None
    frame_rows = np.flatnonzero(slots >= 0)
    intervals = np.diff(lead.recording.times)
    tolerance = SYNC_FRACTION * (float(np.median(intervals)) if intervals.size else 0.0)
    released: dict[int, FollowerFrame] = {}
    for frame in follower.frames:
        nearest = frame_rows[np.argmin(np.abs(shared[frame_rows] - frame.time))]
        if abs(shared[nearest] - frame.time) <= tolerance:
            released[int(nearest)] = frame
    reference = CouplingReference(
        lead.rig.params,
        lead.rig.unit,
        follower.inputs.rig.unit,
        follower.inputs.camera_in_trailer,
        noise,
        covariance_scale=noise.side_rig.reference_covariance_scale,
        follower_limit=noise.side_rig.coupling_follower_limit,
        scrub_scale=noise.side_rig.reference_scrub_scale,
        follower_share=noise.side_rig.reference_follower_share,
    )
    return RecordedFollowingCamera(reference, released, articulations)
