"""VISO-OT: trailer off-tracking from the stereo camera's visual odometry (de Saxe & Cebon 2018, §2.2).

Each camera frame the visual odometry gives the left camera's motion since the previous frame,
``camera_motion = T_prev←curr`` (OpenCV camera axes: x right, y down, z forward). The estimator

1. rotates the camera translation into the trailer frame with the camera-to-vehicle mounting
   (eq (1); the paper's ψ_c2v, measured clockwise from the trailer's forward axis, is the special
   case of a level camera: ``R(−ψ_c2v)`` in ISO terms),
2. takes the yaw change of the trailer about the vertical from the camera's rotation,
3. moves the increment from the camera to the kingpin with the lever arm (eq (2):
   ``Δp_kingpin = Δp_camera + (R(Δψ) − I)·(p_kingpin − p_camera)``; for a camera ``a`` behind the
   kingpin on the centre line this is the paper's ``a·[cos Δψ − 1, sin Δψ]`` in ISO order), and
4. feeds the shared :class:`~vehicle_model.offtracking.OfftrackingBuffer` (eqs (3)–(7)).

Eqs (3)–(7) are planar. On a road that is not a plane (a grade, crossfall, undulations) steps 1–3 are taken in the
unit's **level frame** instead (``level_reference``, :mod:`sensor.level_reference`): the motion is turned by the
unit's tilt at the previous frame, the yaw change is the vertical-axis part of the rotation, and the lever arm is the
camera's position turned by each frame's tilt, all projected onto the horizontal. The default ``planar`` is the
paper's level road.

Plausibility (when the frame interval is known): each frame's step is checked against what a
trailer on a road can do (:class:`MotionBounds`) before it enters the buffer; a step that fails is
treated as a failed frame, with a reason code (:data:`PLAUSIBILITY_REASONS`).

Failed frames and lost track: a frame without an accepted motion is bridged with the last accepted
kingpin increment (a constant-velocity prediction over one camera period), at most
``max_consecutive_failures`` frames in a row (3, i.e. 0.3 s at 10 Hz) and at most
``max_bridged_distance`` metres of bridged travel (default a quarter of the trailer length: 3 m on
the reference trailer). A longer gap means the kingpin path has a hole the prediction cannot be
trusted to fill: the buffer is cleared and the estimator reports **no estimate** (``None``, reason
``lost_track``) until the buffer has been rebuilt over one trailer length from accepted motions. The
estimate itself is refused (``None``) when it is not finite or when ``|e_tr| > L_fp`` — no trailer
off-tracks by more than its own length; such a number can only come from a corrupt path, which
flushes out of the buffer within one trailer length. The reason for a missing estimate is
:attr:`VisoOtEstimator.estimate_reason` (:data:`ESTIMATE_REASONS`). No guess is ever fed to the
buffer beyond the bridge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.offtracking import OfftrackingBuffer
from vehicle_model.parameters import VehicleParams

from .level_reference import LEVEL_REFERENCES, split_yaw, tilt_rotation

__all__ = ["ESTIMATE_REASONS", "PLAUSIBILITY_REASONS", "STEP_COLUMNS", "MotionBounds", "VisoOtEstimator"]

#: Names of the step measures of :meth:`VisoOtEstimator.step_measures` (SI units).
STEP_COLUMNS: tuple[str, ...] = (
    "step_speed_m_s",
    "step_lateral_m_s",
    "step_yaw_rate_rad_s",
    "step_tilt_rate_rad_s",
    "step_vertical_m_s",
)


@dataclass(frozen=True)
class MotionBounds:
    """What a trailer on a road can do between two camera frames.

    Parameters
    ----------
    max_speed : float
        Kingpin speed [m/s]. 30 m/s (108 km/h) is above any speed an articulated HGV reaches
        (EU speed limiters: 90 km/h = 25 m/s); the VO's speed noise on ideal frames is ~0.1 m/s.
    max_yaw_rate : float
        Trailer yaw rate [rad/s]. With r = a_y/u and r = u/R the largest yaw rate is
        sqrt(a_y,max/R_min): a_y ≤ μg ≤ 9.81 m/s² and a kingpin path radius ≥ 4.4 m (tighter than
        the 5.30 m inner circle of the UK roundabout test) give 1.5 rad/s (86°/s).
    max_tilt_rate : float
        Rate of pitch and roll combined [rad/s] (the angle between the trailer's vertical before and
        after the step, over the interval). The road vehicle is level to within suspension motion:
        body roll and pitch rates stay below ~0.2 rad/s short of a rollover; 0.5 rad/s (2.9° per
        10 Hz frame) is two orders of magnitude above the VO's rotation noise (~0.03° per frame).
    max_grade : float
        Vertical speed allowed per unit horizontal speed: road grades stay below 15 %.
    max_heave_speed : float
        Vertical speed [m/s] allowed on top of the grade: suspension heave and a camera mount's
        vibration, 0.5 m/s.
    """

    max_speed: float = 30.0
    max_yaw_rate: float = 1.5
    max_tilt_rate: float = 0.5
    max_grade: float = 0.15
    max_heave_speed: float = 0.5

    def violation(self, step: dict[str, float]) -> str:
        """The first bound ``step`` (:data:`STEP_COLUMNS`) breaks, as a :data:`PLAUSIBILITY_REASONS` code, or ""."""
        speed = step["step_speed_m_s"]
        if not abs(speed) <= self.max_speed:
            return "implausible_speed"
        if not abs(step["step_yaw_rate_rad_s"]) <= self.max_yaw_rate:
            return "implausible_yaw_rate"
        if not abs(step["step_tilt_rate_rad_s"]) <= self.max_tilt_rate:
            return "implausible_tilt"
        if not abs(step["step_vertical_m_s"]) <= self.max_grade * abs(speed) + self.max_heave_speed:
            return "implausible_vertical"
        return ""


_BOUNDS = MotionBounds()

#: Why a frame's motion was not fed to the buffer (the camera motion's own failures are the VO's).
PLAUSIBILITY_REASONS: dict[str, str] = {
    "non_finite_motion": "the camera motion contains NaN or infinite values",
    "implausible_speed": f"the step implies a kingpin speed above {_BOUNDS.max_speed:g} m/s",
    "implausible_yaw_rate": f"the step implies a trailer yaw rate above {_BOUNDS.max_yaw_rate:g} rad/s",
    "implausible_tilt": f"the step implies a pitch or roll rate above {_BOUNDS.max_tilt_rate:g} rad/s",
    "implausible_vertical": (
        f"the step implies a vertical speed above {_BOUNDS.max_grade:.0%} of the horizontal speed "
        f"+ {_BOUNDS.max_heave_speed:g} m/s"
    ),
}

#: Why there is no estimate although frames arrive.
ESTIMATE_REASONS: dict[str, str] = {
    "buffer_filling": "less than one trailer length of kingpin path has been measured yet",
    "lost_track": (
        "too many consecutive camera frames (or too much travel) had no accepted motion; the kingpin path "
        "buffer was cleared and is being rebuilt over one trailer length"
    ),
    "estimate_out_of_range": "the off-tracking read from the path exceeds the trailer length",
    "non_finite_estimate": "the off-tracking read from the path is not a finite number",
}


class VisoOtEstimator:
    """Off-tracking from visual odometry of a trailer-mounted camera.

    Parameters
    ----------
    params
        Vehicle parameters (the follow point of the towed unit ``unit``).
    camera_in_trailer
        4×4 pose ``T_trailer←camera`` of the camera whose motion the odometry reports (the left
        camera), in the frame of the towed unit ``unit``: ISO (origin on the ground below the unit's front
        coupling, x forward, y left, z up), camera axes OpenCV.
    max_consecutive_failures
        Failed frames bridged by prediction before the buffer is cleared.
    frame_interval
        Time between camera frames [s]; ``None`` disables the plausibility check (no rates without it).
    bounds
        Physical limits of a step (default :class:`MotionBounds`).
    max_bridged_distance
        Kingpin travel [m] that may be bridged by prediction in one gap (default ``L_fp/4``).
    unit
        The towed unit the camera is mounted on and whose off-tracking is estimated: 1 the first (default), 2 the
        one it tows, … Its "kingpin" is its front coupling (for ``unit > 1`` the fifth wheel of the unit ahead)
        and ``L_fp`` its own follow point (:meth:`~vehicle_model.parameters.VehicleParams.follow_point_offset_of`):
        eqs (1)–(7) hold for any rigid towed unit.
    level_reference
        ``planar`` (default): the road is level, eqs (1)–(2) as the paper has them. ``odometry``: the unit's tilt
        integrated from the odometry's rotations from ``initial_tilt``; ``accelerometer``: the tilt given with each
        frame (:meth:`update`'s ``tilt``). Either projects the motion onto the horizontal
        (:mod:`sensor.level_reference`).
    initial_tilt
        The unit's (pitch, roll) [rad] at the first frame for ``odometry`` (default level).

    Attributes
    ----------
    last_reason : str
        Why the last frame's motion was not fed to the buffer ("" when it was): a key of
        :data:`PLAUSIBILITY_REASONS` or ``"no_motion"`` for a frame without a motion.
    last_step : dict[str, float]
        The last frame's :data:`STEP_COLUMNS` (NaN without a motion).
    estimate_reason : str
        Why the last estimate is ``None`` ("" when it is a number): a key of :data:`ESTIMATE_REASONS`.
    """

    def __init__(
        self,
        params: VehicleParams,
        camera_in_trailer: np.ndarray,
        max_consecutive_failures: int = 3,
        frame_interval: float | None = None,
        bounds: MotionBounds | None = None,
        max_bridged_distance: float | None = None,
        unit: int = 1,
        level_reference: str = "planar",
        initial_tilt: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        t = np.asarray(camera_in_trailer, dtype=float)
        if t.shape != (4, 4) or not np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-9):
            raise InputError("camera_in_trailer must be a 4×4 rigid transform (orthonormal rotation)")
        if max_consecutive_failures < 0:
            raise InputError("max_consecutive_failures must be ≥ 0")
        if frame_interval is not None and not (math.isfinite(frame_interval) and frame_interval > 0.0):
            raise InputError(f"frame_interval = {frame_interval!r} must be a finite time > 0 s")
        if unit != int(unit) or not 1 <= unit < params.n_units:
            raise InputError(f"unit = {unit!r}: a towed unit of {params.name!r}, 1 to {params.n_units - 1}")
        if level_reference not in LEVEL_REFERENCES:
            raise InputError(f"level_reference = {level_reference!r}; allowed: {', '.join(LEVEL_REFERENCES)}")
        self.unit = int(unit)
        self.level_reference = level_reference
        self.mount_rotation = t[:3, :3]
        self.camera_position = t[:2, 3].copy()  # camera in the unit's axes, its front coupling at the origin
        self.camera_position_3d = t[:3, 3].copy()
        self.tilt = tilt_rotation(*initial_tilt)  # the unit's tilt at the last frame (level_reference not planar)
        l_fp = params.follow_point_offset_of(unit)
        self.buffer = OfftrackingBuffer(l_fp)
        self.max_consecutive_failures = max_consecutive_failures
        self.frame_interval = frame_interval
        self.bounds = bounds if bounds is not None else MotionBounds()
        self.max_bridged_distance = 0.25 * l_fp if max_bridged_distance is None else float(max_bridged_distance)
        if not self.max_bridged_distance >= 0.0:
            raise InputError(f"max_bridged_distance = {max_bridged_distance!r} must be ≥ 0 m")
        self.failures_in_a_row = 0
        self.frames = 0
        self.failed_frames = 0
        self.last_reason = ""
        self.last_step = dict.fromkeys(STEP_COLUMNS, math.nan)
        self.estimate_reason = "buffer_filling"
        self._last_increment: tuple[float, float, float] | None = None
        self._bridged = 0.0
        self._lost = False

    def reset(self) -> None:
        """Forget the path and the failure history."""
        self.buffer.reset()
        self.failures_in_a_row = 0
        self._last_increment = None
        self._bridged = 0.0
        self._lost = False
        self.estimate_reason = "buffer_filling"

    def kingpin_increment(self, camera_motion: np.ndarray) -> tuple[float, float, float]:
        """Kingpin increment ``(dx, dy, dψ)`` in the previous trailer frame from one camera motion."""
        m = np.asarray(camera_motion, dtype=float)
        r_mount = self.mount_rotation
        # de Saxe & Cebon 2018, eq (1), generalised to any mounting: camera-frame translation into trailer axes.
        d_camera = (r_mount @ m[:3, 3])[:2]
        # Trailer rotation over the frame, in trailer axes; its yaw about the vertical is Δψ.
        rot = r_mount @ m[:3, :3] @ r_mount.T
        dpsi = math.atan2(rot[1, 0], rot[0, 0])
        # de Saxe & Cebon 2018, eq (2): lever arm from the camera to the kingpin (at the origin).
        c, s = math.cos(dpsi), math.sin(dpsi)
        lever = -self.camera_position
        d_kingpin = d_camera + np.array([c * lever[0] - s * lever[1], s * lever[0] + c * lever[1]]) - lever
        return float(d_kingpin[0]), float(d_kingpin[1]), dpsi

    def set_tilt(self, pitch: float, roll: float) -> None:
        """Take the unit's (pitch, roll) [rad] as its tilt at the last frame (e.g. the first frame's reading, before
        any motion)."""
        self.tilt = tilt_rotation(float(pitch), float(roll))

    def level_increment(self, camera_motion: np.ndarray, tilt: np.ndarray | None = None) -> tuple[tuple, np.ndarray]:
        """Kingpin increment ``(dx, dy, dψ)`` in the previous **level** frame from one camera motion, and the unit's
        tilt at this frame: ``tilt`` (3×3, :func:`~sensor.level_reference.tilt_rotation`) when given, else split
        off the odometry's rotation (:mod:`sensor.level_reference`). The previous tilt is :attr:`tilt`."""
        m = np.asarray(camera_motion, dtype=float)
        r_mount = self.mount_rotation
        a_prev = self.tilt
        rot = r_mount @ m[:3, :3] @ r_mount.T  # the unit's rotation over the frame, in its previous axes
        if tilt is None:
            dpsi, a_curr = split_yaw(a_prev @ rot)
        else:
            a_curr = tilt
            level = a_prev @ rot @ a_curr.T
            dpsi = math.atan2(level[1, 0], level[0, 0])
        # de Saxe & Cebon 2018, eq (1), in the level frame: the camera's displacement made horizontal.
        d_camera = (a_prev @ (r_mount @ m[:3, 3]))[:2]
        # eq (2) with the lever arm made horizontal by each frame's tilt.
        lever_prev = -(a_prev @ self.camera_position_3d)[:2]
        lever = -(a_curr @ self.camera_position_3d)[:2]
        c, s = math.cos(dpsi), math.sin(dpsi)
        d_kingpin = d_camera + np.array([c * lever[0] - s * lever[1], s * lever[0] + c * lever[1]]) - lever_prev
        return (float(d_kingpin[0]), float(d_kingpin[1]), dpsi), a_curr

    def step_measures(self, camera_motion: np.ndarray, dt: float) -> dict[str, float]:
        """Rates implied by one camera motion over ``dt`` seconds (:data:`STEP_COLUMNS`).

        Kingpin speed (horizontal), its lateral component in the trailer's axes at the frame's start, trailer
        yaw rate, tilt rate (the angle between the trailer's
        vertical axis before and after the step: pitch and roll together) and the camera's vertical
        speed (trailer z).
        """
        m = np.asarray(camera_motion, dtype=float)
        dx, dy, dpsi = self.kingpin_increment(m)
        rot = self.mount_rotation @ m[:3, :3] @ self.mount_rotation.T
        tilt = math.acos(min(1.0, max(-1.0, float(rot[2, 2]))))
        dz = float((self.mount_rotation @ m[:3, 3])[2])
        return {
            "step_speed_m_s": math.hypot(dx, dy) / dt,
            "step_lateral_m_s": dy / dt,
            "step_yaw_rate_rad_s": dpsi / dt,
            "step_tilt_rate_rad_s": tilt / dt,
            "step_vertical_m_s": dz / dt,
        }

    def update(self, camera_motion: np.ndarray | None, tilt: tuple[float, float] | None = None) -> float | None:
        """Feed one camera frame's motion (``None`` for a failed frame); return the estimate or ``None``.

        The motion is checked for plausibility (when ``frame_interval`` is set); a refused or missing
        motion is bridged or, after too long a gap, clears the buffer (module notes). The reasons are
        in :attr:`last_reason` and :attr:`estimate_reason`.

        ``tilt``: the unit's (pitch, roll) [rad] at this frame, required with ``level_reference="accelerometer"``
        (e.g. :class:`sensor.level_reference.AccelerometerTilt`), refused otherwise.
        """
        given = self.given_tilt(tilt)
        self.frames += 1
        self.last_step = dict.fromkeys(STEP_COLUMNS, math.nan)
        if camera_motion is None:
            return self._bridge("no_motion", given)
        m = np.asarray(camera_motion, dtype=float)
        if m.shape != (4, 4) or not np.all(np.isfinite(m)):
            return self._bridge("non_finite_motion", given)
        tilt_now = None
        if self.level_reference == "planar":
            increment = self.kingpin_increment(m)
        else:
            increment, tilt_now = self.level_increment(m, given)
        if self.frame_interval is not None:
            self.last_step = self.step_measures(m, self.frame_interval)
            violation = self.bounds.violation(self.last_step)
            if violation:
                return self._bridge(violation, given)
        if tilt_now is not None:
            self.tilt = tilt_now
        self.last_reason = ""
        self.failures_in_a_row = 0
        self._bridged = 0.0
        self._last_increment = increment
        self.buffer.push(*increment)
        return self._read()

    def given_tilt(self, tilt: tuple[float, float] | None) -> np.ndarray | None:
        """The frame's tilt as a rotation (``accelerometer``), after checking it is given exactly when needed."""
        if self.level_reference == "accelerometer":
            if tilt is None or len(tilt) != 2 or not all(math.isfinite(a) for a in tilt):
                raise InputError(f"tilt = {tilt!r}: level_reference 'accelerometer' needs a finite (pitch, roll) [rad]")
            return tilt_rotation(float(tilt[0]), float(tilt[1]))
        if tilt is not None:
            raise InputError(f"tilt given with level_reference = {self.level_reference!r}; allowed: None")
        return None

    def _bridge(self, reason: str, tilt: np.ndarray | None = None) -> float | None:
        """A frame without an accepted motion: predict over it, or clear the buffer after too long a gap. A measured
        tilt is kept; an integrated one is held over the gap."""
        if tilt is not None:
            self.tilt = tilt
        self.last_reason = reason
        self.failed_frames += 1
        self.failures_in_a_row += 1
        last = self._last_increment
        step = math.hypot(last[0], last[1]) if last is not None else math.inf
        if (
            last is None
            or self.failures_in_a_row > self.max_consecutive_failures
            or self._bridged + step > self.max_bridged_distance
        ):
            lost = self._lost or last is not None or len(self.buffer) > 1
            self.reset()
            self._lost = lost
            self.estimate_reason = "lost_track" if self._lost else "buffer_filling"
            return None
        self._bridged += step
        self.buffer.push(*last)  # constant-velocity bridge over one frame
        return self._read()

    def _read(self) -> float | None:
        """The buffer's off-tracking if it is a plausible number, else ``None`` with :attr:`estimate_reason`."""
        value = self.buffer.offtracking()
        if value is None:
            self.estimate_reason = "lost_track" if self._lost else "buffer_filling"
            return None
        if not math.isfinite(value):
            self.estimate_reason = "non_finite_estimate"
            return None
        if abs(value) > self.buffer.follow_point_offset:
            self.estimate_reason = "estimate_out_of_range"
            return None
        self._lost = False
        self.estimate_reason = ""
        return float(value)
