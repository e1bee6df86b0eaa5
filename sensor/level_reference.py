"""Where "level" is for VISO-OT on a road that is not a plane: the unit's tilt, and the camera motion made horizontal.

de Saxe & Cebon 2018's eqs (3)–(7) trace the kingpin's path in the horizontal plane, where off-tracking is measured.
On a grade, a crossfall or an undulating track the camera moves in 3-D and its unit pitches and rolls
(:mod:`vehicle_model.terrain_pose`); VISO-OT then needs each frame's motion expressed in a **level frame** — the
unit's heading about the vertical, its x and y axes horizontal — before the yaw change and the kingpin increment are
taken from it (docs/terrain_camera.md §4). That needs the direction of gravity in the unit's axes, i.e. its tilt
``A = R_y(θ)·R_x(φ)`` (ISO pitch θ and roll φ, ``R_world←unit = R_z(ψ)·A``). Two sources:

* ``"odometry"``: the tilt integrated from the odometry's own rotations, starting from a known tilt (a level start):
  ``A_prev·ΔR = R_z(Δψ)·A_curr`` splits each frame's rotation ``ΔR`` (unit axes) into the yaw change and the new
  tilt. No other sensor; its error is the random walk of the odometry's rotation noise (a per-frame pitch/roll
  noise σ grows to σ·√n after n frames), and it does not recover after a lost frame (the tilt is held over it).
* ``"accelerometer"``: the tilt each frame from a trailer-mounted accelerometer (a real trailer's EBS or telematics
  unit has one), its kinematic acceleration (the speed change along the path and the centripetal ``v·r``, both from
  the odometry) removed so that what remains is gravity. Its error does not grow: it is the accelerometer's bias and
  noise over g (a bias of 0.05 m/s² tilts the level frame by 0.29°) plus what is left of the kinematic acceleration
  (an error of 0.1 m/s in speed at a yaw rate of 0.2 rad/s is 0.02 m/s², 0.12°). :class:`AccelerometerTilt` models
  it as the true tilt plus a constant bias and white noise.

A tilt error ``δ`` moves the horizontal camera path by ``h·δ`` for a camera ``h`` above the unit's frame: a constant
error shifts the whole path and cancels in the increments eqs (3)–(7) use; only its changes from frame to frame
enter the estimate.

On a level road with zero tilt both reduce to the planar eqs (1)–(2) exactly (:meth:`sensor.viso_ot.VisoOtEstimator`
computes the same floating-point operations).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vehicle_model.errors import InputError

__all__ = [
    "LEVEL_REFERENCES",
    "TRAILER_TILT_BIAS",
    "TRAILER_TILT_NOISE",
    "AccelerometerTilt",
    "horizontal_speed",
    "split_yaw",
    "tilt_angles",
    "tilt_rotation",
    "trailer_accelerometer",
]

TRAILER_TILT_BIAS = 0.005
"""Assumed residual tilt error of a trailer accelerometer [rad], in pitch and in roll: an offset of about 5 mg
(0.05 m/s²) left after the unit's mounting is calibrated, plus what the kinematic acceleration's removal leaves."""

TRAILER_TILT_NOISE = 0.001
"""Assumed white noise of each tilt reading [rad] (the accelerometer averaged over one camera period)."""

LEVEL_REFERENCES: tuple[str, ...] = ("planar", "odometry", "accelerometer")
"""How VISO-OT finds the level: ``planar`` (the paper's level road: no tilt), or a source of the unit's tilt."""


def tilt_rotation(pitch: float, roll: float) -> np.ndarray:
    """``A = R_y(pitch)·R_x(roll)`` (3×3): the unit's axes in its level frame (ISO: pitch nose down, roll left up)."""
    cp, sp = math.cos(pitch), math.sin(pitch)
    cr, sr = math.cos(roll), math.sin(roll)
    return np.array([[cp, sp * sr, sp * cr], [0.0, cr, -sr], [-sp, cp * sr, cp * cr]])


def tilt_angles(tilt: np.ndarray) -> tuple[float, float]:
    """Pitch and roll [rad] of a tilt ``A = R_y(pitch)·R_x(roll)``."""
    return -math.asin(max(-1.0, min(1.0, float(tilt[2, 0])))), math.atan2(float(tilt[2, 1]), float(tilt[2, 2]))


def horizontal_speed(speed: float, tilt: np.ndarray) -> float:
    """A speed along the unit's x axis (a wheel's, along the ground) made horizontal with the unit's tilt ``A``:
    ``u·cos θ``, the norm of the x axis's horizontal part (``A = R_y(θ)·R_x(φ)``: its first column ``(cos θ, 0,
    −sin θ)``, so the roll does not enter). A level tilt gives ``speed`` unchanged, bit for bit."""
    return speed * math.sqrt(max(0.0, 1.0 - float(tilt[2, 0]) ** 2))


def split_yaw(rotation: np.ndarray) -> tuple[float, np.ndarray]:
    """A rotation ``M = R_z(ψ)·A`` split into the yaw ψ [rad] and the tilt ``A`` (pitch and roll only)."""
    yaw = math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))
    pitch, roll = tilt_angles(_rz(-yaw) @ rotation)
    return yaw, tilt_rotation(pitch, roll)


def _rz(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass
class AccelerometerTilt:
    """The tilt a trailer accelerometer gives once its kinematic acceleration is removed (module docstring).

    Parameters
    ----------
    bias_pitch, bias_roll : float
        Constant errors [rad] (an accelerometer bias b over g: ``b/g``).
    noise : float
        Standard deviation of the white noise on each angle per reading [rad].
    seed : int
        Seed of the noise.
    """

    bias_pitch: float = 0.0
    bias_roll: float = 0.0
    noise: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name, limit in (("bias_pitch", 0.1), ("bias_roll", 0.1), ("noise", 0.1)):
            value = getattr(self, name)
            if not (math.isfinite(value) and abs(value) <= limit):
                raise InputError(f"accelerometer_tilt.{name} = {value!r} rad is out of range; allowed: ±{limit} rad")
        if self.noise < 0.0:
            raise InputError(f"accelerometer_tilt.noise = {self.noise!r} rad is out of range; allowed: [0, 0.1] rad")
        self._rng = np.random.default_rng([int(self.seed), 0xACC])

    def read(self, pitch: float, roll: float) -> tuple[float, float]:
        """The measured (pitch, roll) [rad] for the true ones."""
        if self.noise > 0.0:
            n = self.noise * self._rng.standard_normal(2)
            return pitch + self.bias_pitch + float(n[0]), roll + self.bias_roll + float(n[1])
        return pitch + self.bias_pitch, roll + self.bias_roll


def trailer_accelerometer(seed: int) -> AccelerometerTilt:
    """The accelerometer a camera run assumes on its unit: :data:`TRAILER_TILT_BIAS` in pitch and roll and
    :data:`TRAILER_TILT_NOISE`, seeded by ``seed``."""
    return AccelerometerTilt(TRAILER_TILT_BIAS, TRAILER_TILT_BIAS, TRAILER_TILT_NOISE, seed=int(seed))
