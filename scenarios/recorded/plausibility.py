"""Whether a recording's camera model and its odometry are plausible: checks before the run and flags after it.

Before any work (:func:`check_baseline`, :func:`check_road_disparity`) a camera model is refused whose baseline no
stereo rig has, or whose disparity on the road below the camera cannot be told from zero. KITTI's ``calib.txt``
holds ``P1[0, 3] = −f·b`` [px·m]; a file holding ``−b`` gives a baseline ``f`` times too small, and every motion the
odometry measures is then that much too short while each frame still passes its checks. The rig's nearest visible
road is on the bottom image row: at height ``h`` with the cameras tilted down by ``θ``, row ``v`` meets the ground
at the depth ``Z = h / ((v − cv)/f·cos θ + sin θ)``, where the disparity is ``f·b/Z`` — for a level rig
``b·(v − cv)/h``, the rule :mod:`scenarios.camera_checks` applies to the simulated camera. Below
:data:`MIN_DISPARITY_PX` a disparity cannot be told from zero (:mod:`scenarios.camera_checks`' notes); a rig file's
``baseline_m`` (the measured one) must agree with the calibration's within :data:`BASELINE_TOLERANCE`.

After the run (:func:`motion_flags`), from its time series, two flags for its verdict:

* ``odometry_scale``: with signals, the distance the accepted motions carried the kingpin against the distance the
  tractor's wheel speed gives over the same frame intervals; a ratio beyond :data:`SCALE_FACTOR` either way is a
  scale error (a calibration's baseline, a speed column in other units), not noise;
* ``camera_against_rig``: the accepted motions carried the kingpin backwards along the trailer's axis (as the rig's
  ``psi_c2v_deg`` puts the camera on it): a camera looking the other way than the rig says — a forward-looking
  recording under a rear-facing rig — or a combination reversing. A trailer driving backwards leaves no path behind
  it, so its off-tracking is undefined.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np

from sensor.recordings.kitti import RectifiedCamera
from vehicle_model.errors import InputError

from .rig import RecordingRig

__all__ = [
    "BASELINE_RANGE",
    "BASELINE_TOLERANCE",
    "MIN_DISPARITY_PX",
    "MIN_TRAVEL",
    "SCALE_FACTOR",
    "check_baseline",
    "check_road_disparity",
    "motion_flags",
    "nearest_road_disparity",
]

BASELINE_RANGE = (0.01, 5.0)
"""Stereo baselines [m] a rig can have: a 1 cm pair (the smallest stereo modules) to the 5 m the paper's baseline
sweep reaches (de Saxe & Cebon 2018, §3)."""
BASELINE_TOLERANCE = 0.1
"""Largest relative difference of the calibration's baseline and a rig file's measured ``baseline_m``."""
MIN_DISPARITY_PX = 1.0
"""Least disparity [px] of the nearest visible road: below it a disparity cannot be told from zero."""
SCALE_FACTOR = 2.0
"""Odometry and wheel distances further apart than this factor either way are flagged."""
MIN_TRAVEL = 1.0
"""Distance [m] a run must cover before its scale or its direction is judged."""


def check_baseline(camera: RectifiedCamera, source: str) -> None:
    """Refuse a baseline outside :data:`BASELINE_RANGE` (one line naming ``source``, the camera model's file)."""
    lo, hi = BASELINE_RANGE
    if not lo <= camera.baseline <= hi:
        raise InputError(
            f"{source}: baseline {camera.baseline:.4g} m; allowed: [{lo:g}, {hi:g}] m (KITTI's P1[0, 3] is −f·b "
            f"in px·m: −{camera.f * 0.5:.4g} for a 0.5 m baseline at f = {camera.f:g} px)"
        )


def nearest_road_disparity(camera: RectifiedCamera, height_px: int, rig: RecordingRig) -> float:
    """Disparity [px] of the ground on the bottom image row (module notes); ≤ 0 when that row sees no ground."""
    mount_height = float(rig.lever_arm[2])
    row = (height_px - 1 - camera.cv) / camera.f
    down = row * math.cos(rig.pitch) + math.sin(rig.pitch)
    return camera.f * camera.baseline * down / mount_height


def check_road_disparity(camera: RectifiedCamera, size: tuple[int, int], rig: RecordingRig, source: str) -> None:
    """Refuse a camera model that sees the road below :data:`MIN_DISPARITY_PX`, or whose baseline disagrees with
    the rig file's ``baseline_m`` (module notes); one line naming ``source`` and what is allowed."""
    measured = rig.baseline
    if measured is not None and not abs(camera.baseline - measured) <= BASELINE_TOLERANCE * measured:
        raise InputError(
            f"{source}: baseline {camera.baseline:.4g} m, the rig file's baseline_m {measured:g} m; allowed: within "
            f"{BASELINE_TOLERANCE:.0%} of each other"
        )
    disparity = nearest_road_disparity(camera, size[1], rig)
    if 0.0 < disparity < MIN_DISPARITY_PX:
        need = camera.baseline * MIN_DISPARITY_PX / disparity
        raise InputError(
            f"{source}: baseline {camera.baseline:.4g} m gives {disparity:.2g} px of disparity on the nearest road "
            f"{float(rig.lever_arm[2]):g} m below the camera; allowed: ≥ {MIN_DISPARITY_PX:g} px, a baseline "
            f"≥ {need:.3g} m (KITTI's P1[0, 3] is −f·b, not −b)"
        )


def _frame_steps(columns: dict[str, np.ndarray]) -> list[tuple[int, int]]:
    """``(row before, row)`` of every accepted motion: consecutive frames with images, the later one accepted."""
    frame = columns.get("camera_frame")
    valid = columns.get("vo_valid")
    missing = columns.get("frame_missing")
    if frame is None or valid is None:
        return []
    seen = (frame > 0.5) & ((missing < 0.5) if missing is not None else True)
    rows = np.flatnonzero(seen)
    return [(int(a), int(b)) for a, b in itertools.pairwise(rows) if valid[b] > 0.5]


def motion_flags(columns: dict[str, np.ndarray]) -> tuple[dict[str, Any], list[dict[str, str]]]:
    """What the accepted motions say about the run's scale and direction (module notes).

    Returns
    -------
    (dict, list of dict)
        ``metrics.json``'s ``motion``: the kingpin's travel forwards and backwards along the trailer's axis [m] and,
        with a wheel speed, the wheel's distance over the same intervals [m] and the ratio; and the verdict's flags
        (``{"flag", "reason"}``) for what is implausible.
    """
    need = ("time", "kingpin_x_viso_ot", "kingpin_y_viso_ot", "trailer_heading_viso_ot")
    steps = _frame_steps(columns)
    if not steps or any(name not in columns for name in need):
        return {}, []
    time = columns["time"]
    x, y, heading = (columns[name] for name in need[1:])
    forward = backward = odometry = 0.0
    for a, b in steps:
        dx, dy = x[b] - x[a], y[b] - y[a]
        along = math.cos(heading[a]) * dx + math.sin(heading[a]) * dy  # the step in the trailer's axes, forwards
        forward += max(along, 0.0)
        backward += max(-along, 0.0)
        odometry += math.hypot(dx, dy)
    summary: dict[str, Any] = {"forward_m": forward, "backward_m": backward, "odometry_m": odometry}
    flags: list[dict[str, str]] = []
    if forward + backward >= MIN_TRAVEL and backward > forward:
        flags.append(
            {
                "flag": "camera_against_rig",
                "reason": f"the camera moved against the rig's facing: the accepted motions carry the kingpin "
                f"{backward:.1f} m backwards and {forward:.1f} m forwards along the trailer, so the off-tracking "
                "is undefined; a camera looking forwards has psi_c2v_deg 0 (docs/real_cameras.md), or the "
                "combination reversed",
            }
        )
    speed = columns.get("wheel_speed")
    if speed is not None:
        wheel = measured = 0.0  # over the steps with a wheel speed throughout
        for a, b in steps:
            t, v = time[a : b + 1], np.abs(speed[a : b + 1])
            if np.all(np.isfinite(v)):
                wheel += float(np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(t)))
                measured += math.hypot(x[b] - x[a], y[b] - y[a])
        summary["wheel_m"] = wheel
        if max(wheel, measured) >= MIN_TRAVEL:
            ratio = measured / wheel if wheel > 0.0 else math.inf
            odometry = measured
            summary["odometry_over_wheel"] = ratio
            if not 1.0 / SCALE_FACTOR <= ratio <= SCALE_FACTOR:
                flags.append(
                    {
                        "flag": "odometry_scale",
                        "reason": f"the odometry's distance is {ratio:.3g}× the wheel speed's ({odometry:.2f} m "
                        f"against {wheel:.2f} m over the accepted frames): check the calibration's baseline "
                        "(KITTI's P1[0, 3] = −f·b) and the signals' speed_m_s",
                    }
                )
    return summary, flags
