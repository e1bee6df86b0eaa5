"""A following unit's camera as the reference of a side rig's filter in the loop (:mod:`sensor.fusion_coupling`).

A towed unit whose fused filter has ``coupling_reference`` on (a side rig's, ``fusion.side_rig``) takes the camera of
the nearest unit behind it whose camera looks along its unit (a rear rig: a side rig's motion has the axial errors
the reference is to find). Each of that camera's released frames becomes, through the couplings between the two
units and their measured articulations at the frame's start and end, a measurement of the lead unit's kingpin
increment over the same frame ((C1)–(C2) of :mod:`sensor.fusion_coupling`); the lead's filter takes it with its
own frame of the same tick.

Both cameras take their frames on the loop's one camera clock and release them after the one run-wide latency,
so the two frames of a tick are released on the same tick; the following unit's camera updates before the lead's
filter (:class:`~.further_units.FurtherUnitsParticipant` before the first unit's estimators, and within it every
unit's camera before any unit's fused filter, the registry's order), so its frames of the tick are there when the
lead's filter takes its own. A following frame that failed, was refused, or whose
interval does not start at the lead filter's anchor gives no measurement: the lead takes its own frame alone. With
``fusion.side_rig.coupling_follower_limit`` a frame taken while the follower's tyres scrub is widened by the
follower's own off-tracking variance or refused ((C3) of :mod:`sensor.fusion_coupling`), the refusals counted by
their reason. With ``fusion.side_rig.coupling_follower_share`` every frame's lateral variance takes the follower's
off-tracking variance in the share of its scrub demand ((C4) of :mod:`sensor.fusion_coupling_share`). With
``fusion.side_rig.coupling_axial_scale`` the follower's filter's estimate of its odometry's error
along its optical axis is taken out of each frame ((C0'') of :mod:`sensor.fusion_coupling`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from sensor.fusion import CouplingMeasurement
from sensor.fusion_coupling import CouplingReference, looks_along
from sensor.fusion_model import BPSI, StateLayout
from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams

from ..unit_feedback import estimate_key

__all__ = [
    "FollowingCamera",
    "filter_axial_scale",
    "filter_scrub",
    "filter_yaw_bias",
    "following_camera",
    "measured_articulations",
    "reference_counts",
]


def measured_articulations(measured: Mapping[str, np.ndarray]) -> tuple[float, ...]:
    """Every coupling's measured articulation from the tractor's fifth wheel back, ``Γ_1`` first [rad]
    (``articulation``, then ``rear_articulation``)."""
    rear = measured.get("rear_articulation")
    return (float(measured["articulation"][0]), *(map(float, rear) if rear is not None else ()))


def filter_yaw_bias(fused: Any) -> tuple[float, float, float] | None:
    """A fused filter's (:class:`sensor.fusion.FusedVisoOt`) estimate of its odometry's yaw error ``β̂_ψ`` [rad/m],
    its variance now and the scrub demand ``D`` of its last frame, as (C0) of :mod:`sensor.fusion_coupling` takes
    them (``None``: no filter)."""
    if fused is None:
        return None
    return float(fused.state[BPSI]), float(fused.covariance[BPSI, BPSI]), float(fused.frame_scrub_demand)


def filter_axial_scale(fused: Any) -> tuple[float, float] | None:
    """A fused filter's estimate ``ŝ`` of its odometry's relative error along its optical axis (``s_z`` of eq (3') of
    :mod:`sensor.fusion_model`) and its variance now, as (C0'') of :mod:`sensor.fusion_coupling` takes them
    (``None``: no filter). A filter without the state is refused: its settings' ``vo_axial_scale`` is 0."""
    if fused is None:
        return None
    sz = StateLayout.of(fused.noise).sz
    if sz is None:
        raise InputError(
            f"fusion.side_rig.coupling_axial_scale needs the following unit {fused.unit}'s filter to hold s_z: "
            f"its vo_axial_scale is {fused.noise.vo_axial_scale:g}, allowed (0, 0.5]"
        )
    return float(fused.state[sz]), float(fused.covariance[sz, sz])


def filter_scrub(fused: Any) -> tuple[float, float]:
    """A fused filter's scrub demand ``D`` at its last frame and its off-tracking std [m] now, as (C3) of
    :mod:`sensor.fusion_coupling` takes them (NaN, NaN: no filter)."""
    if fused is None:
        return math.nan, math.nan
    return float(fused.frame_scrub_demand), float(fused.std)


class FollowingCamera:
    """The measurements a following unit's camera gives the lead unit's filter, frame by frame (module notes).

    Parameters
    ----------
    reference
        The transport from the follower's camera to the lead's kingpin (:class:`~sensor.fusion_coupling.
        CouplingReference`).
    camera
        The follower's VISO-OT participant (:class:`~.camera_estimator.VisoOt`): its released frames.
    yaw_bias
        Gives the follower's fused filter's estimate of its odometry's yaw error and its variance when there is one
        (:func:`filter_yaw_bias`; ``None`` or a ``None`` result: none; asked on every frame, since the follower's
        filter may be built after the lead's): taken out of each following frame ((C0) of
        :mod:`sensor.fusion_coupling`).
    scrub
        Gives the follower's fused filter's scrub demand at its last frame and its off-tracking std
        (:func:`filter_scrub`), asked only where the reference has a ``follower_limit`` ((C3)) or ``follower_share``
        ((C4) of :mod:`sensor.fusion_coupling_share`, applied before (C3)).
    axial
        Gives the follower's fused filter's ``ŝ`` and its variance (:func:`filter_axial_scale`), asked on every frame
        where the reference has ``axial_scale`` on ((C0'')).

    Attributes
    ----------
    measurements : int
        Following frames turned into a measurement so far.
    refused : dict[str, int]
        Following frames refused by (C3), by their reason.
    """

    def __init__(
        self,
        reference: CouplingReference,
        camera: Any,
        yaw_bias: Callable[[], tuple[float, ...] | None] | None = None,
        scrub: Callable[[], tuple[float, float]] | None = None,
        axial: Callable[[], tuple[float, float] | None] | None = None,
    ) -> None:
        self.reference = reference
        self.camera = camera
        self.yaw_bias = yaw_bias
        self.scrub = scrub
        self.axial = axial
        self.measurements = 0
        self.refused: dict[str, int] = {}
        self._articulations: dict[int, tuple[float, ...]] = {}  # Γ_{j+1} … Γ_m by tick, from the last frame on
        self._last_frame: int | None = None  # the tick of the follower's last released frame
        self._last_tilt: tuple[float, float] | None = None  # the follower's tilt at that frame (off the level road)
        self._pending: dict[int, CouplingMeasurement] = {}  # by the tick of the frame's end

    def observe(self, tick: int, measured: Mapping[str, np.ndarray]) -> None:
        """Keep this tick's articulations; turn the follower's frames released on it into measurements."""
        self._articulations[tick] = self.reference.articulations(measured_articulations(measured))
        level = self.reference.geometry.level_reference != "planar"
        for shot in self.camera.released:
            start, self._last_frame = self._last_frame, int(shot.tick)
            start_tilt, self._last_tilt = self._last_tilt, getattr(shot, "tilt", None)
            frame = shot.frame
            if start is None or frame is None or not frame.valid:
                continue
            before, after = self._articulations.get(start), self._articulations.get(int(shot.tick))
            if before is None or after is None:
                continue
            tilts = None
            if level:  # the follower's level frame at the frame's start and end, as its own filter takes them
                if start_tilt is None or self._last_tilt is None:
                    continue
                tilts = (start_tilt, self._last_tilt)
            z, r = self.reference.measurement(
                frame.vo.camera_motion,
                frame.vo.covariance,
                before,
                after,
                self.yaw_bias() if self.yaw_bias else None,
                tilts,
                self.axial() if self.axial and self.reference.axial_scale else None,
            )
            limit, share = self.reference.follower_limit is not None, self.reference.follower_share
            demand, follower_std = self.scrub() if self.scrub and (limit or share) else (math.nan, math.nan)
            if share:  # (C4) of sensor.fusion_coupling_share
                r = self.reference.shared(r, demand, follower_std)
            if limit:  # (C3)
                limited, reason = self.reference.limited(r, demand, follower_std)
                if limited is None:
                    self.refused[str(reason)] = self.refused.get(str(reason), 0) + 1
                    continue
                r = limited
            if np.all(np.isfinite(z)) and np.all(np.isfinite(r)):
                self._pending[int(shot.tick)] = CouplingMeasurement(start, z, r, self.reference.covariance_scale)
                self.measurements += 1
        if self._last_frame is not None:  # the next frame's interval starts at the last frame
            for old in [t for t in self._articulations if t < self._last_frame]:
                del self._articulations[old]

    def take(self, tick: int) -> CouplingMeasurement | None:
        """The measurement of the frame that ended on tick ``tick`` (``None``: none), forgetting older ones."""
        found = self._pending.pop(tick, None)
        for old in [t for t in self._pending if t < tick]:
            del self._pending[old]
        return found


def reference_counts(following: FollowingCamera | None) -> dict[str, Any]:
    """``metrics.json``'s counts of a following unit's camera as a filter's reference: ``measurements``, the
    following frames turned into a measurement, and ``refused``, those refused by (C3), by reason (in the reasons'
    order; empty: none). ``None``: no following camera was found, zero of both. One shape for a run and a recorded
    replay (:func:`scenarios.recorded.following.coupling_summary`)."""
    if following is None:
        return {"measurements": 0, "refused": {}}
    return {"measurements": following.measurements, "refused": dict(sorted(following.refused.items()))}


def following_camera(
    params: VehicleParams, unit: int, unit_estimators: Mapping[str, Any], noise: Any, level: str
) -> FollowingCamera | None:
    """The reference of towed unit ``unit``'s filter: the nearest unit behind with a camera that looks along its unit
    (``unit_estimators``, the loop's per-unit estimators by key), or ``None`` — no such camera, or one whose motion
    is made horizontal otherwise than the lead's (``level``), or with the odometry's integrated tilt, which the
    reference does not reproduce. Off the level road with the accelerometer's tilt the follower's motion is made
    horizontal with its own tilt readings and (C1) carries it in the level frame (:mod:`sensor.fusion_coupling`).
    The follower's fused filter, where it has one, gives its odometry's yaw error ((C0))."""
    if level not in ("planar", "accelerometer"):
        return None
    for follower in range(unit + 1, len(params.trailers) + 1):
        camera = unit_estimators.get(estimate_key("viso_ot", follower))
        if camera is None or not looks_along(camera.camera_in_trailer):
            continue
        if getattr(getattr(camera, "feed", None), "level_reference", "planar") != level:
            return None
        side = noise.side_rig
        reference = CouplingReference(
            params,
            unit,
            follower,
            camera.camera_in_trailer,
            noise,
            level,
            side.reference_covariance_scale,
            side.coupling_follower_limit,
            side.reference_scrub_scale,
            side.reference_axial_scale,
            side.reference_follower_share,
        )
        key = estimate_key("viso_ot_fused", follower)

        def yaw_bias(key: str = key) -> tuple[float, ...] | None:
            return filter_yaw_bias(getattr(unit_estimators.get(key), "filter", None))

        def scrub(key: str = key) -> tuple[float, float]:
            return filter_scrub(getattr(unit_estimators.get(key), "filter", None))

        def axial(key: str = key) -> tuple[float, float] | None:
            return filter_axial_scale(getattr(unit_estimators.get(key), "filter", None))

        return FollowingCamera(reference, camera, yaw_bias, scrub, axial)
    return None
