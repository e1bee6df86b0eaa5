"""The rig of a recording (``offtrack estimate --rig RIG.yaml``): where the camera sits on which trailer.

The geometry of de Saxe & Cebon 2018, eqs (1)–(2) — the camera's mounting angle ψ_c2v and the lever arm from the
camera to the kingpin — and the trailer's follow point (eqs (6)–(7)) are all VISO-OT needs; the fused filter and
Cheng's zero-slip estimate also need the combination's axles, so the rig names a vehicle: a preset, a combination
file (docs/vehicles.md, held inline once read, so a recorded run's files describe it) or the combination. A YAML file
(degrees at this edge, metres; read within :mod:`scenarios.yaml_input`'s bounds)::

    vehicle: lst                    # a preset of `offtrack list`: its trailer's axles and the tractor's wheelbase
    psi_c2v_deg: 180                # camera-to-vehicle angle, clockwise from the trailer's forward axis (180: rear)
    lever_arm_m: [-14.05, 0.0, 3.0] # the rig's mount point (midway between the two cameras) from the kingpin,
                                    # trailer axes: x forward, y left, z up from the ground
    follow_point_offset_m: 14.05    # optional: kingpin to follow point (default: the vehicle's, its trailer's rear)
    pitch_deg: 0.0                  # optional: the cameras tilted down about their x axis
    roll_deg: 0.0                   # optional: the cameras rolled about their optical axis
    baseline_m: 0.5                 # optional: the baseline measured on the rig, checked against the calibration's
    unit: 1                         # optional: the towed unit carrying the rig (1 the first, 2 the one it tows, …)

The numbers are those of a scenario's ``camera`` section (``psi_c2v_deg``; ``station``, ``lateral``,
``mount_height`` as the lever arm). On a unit behind the first (``unit`` 2, 3, …: :attr:`sensor.camera.StereoRig.unit`)
the "kingpin" is that unit's front coupling — the fifth wheel of the unit ahead — and the axes, the body, the
follow point and the lever arm are that unit's (VISO-OT holds for any rigid towed unit,
:class:`sensor.viso_ot.VisoOtEstimator`). The left camera — whose motion the odometry reports — sits half the calibrated
baseline to the left of the mount point along the cameras' x axis (:meth:`sensor.camera.StereoRig.camera_in_trailer`).
A lever arm that puts the camera off the trailer is refused naming the field and the body's extent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, ValidationError, field_validator

from sensor.calibration import RectifiedParameters
from sensor.camera import StereoRig
from vehicle_model.combination import CombinationSpec
from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams
from vehicle_model.settings import Real, Settings

from ..config import Vehicle, check_vehicle, field_name, params_of, read_vehicle_file, vehicle_name
from ..yaml_input import MAX_BYTES, load_yaml

__all__ = ["MOUNT_LOW", "MOUNT_REACH", "MOUNT_TOP", "RecordingRig", "RigFile", "load_rig", "rig_from_fields"]

MOUNT_REACH = 1.0
"""How far a camera's mount may reach beyond the trailer's body, forwards, backwards or sideways [m]."""
MOUNT_LOW = 0.2
"""Lowest mount above the ground [m] (:class:`sensor.camera.StereoRig`'s least ``mount_height``)."""
MOUNT_TOP = 6.0
"""Highest mount above the ground [m]: a road vehicle is at most about 4.5 m tall; a mast may add a metre or so."""


class RigFile(Settings):
    """The rig file's fields (module notes), as written: degrees and metres."""

    vehicle: Vehicle = Field(
        "reference", description="a vehicle preset (offtrack list), a combination file NAME.yaml or the combination"
    )
    psi_c2v_deg: Real = Field(description="camera-to-vehicle angle, clockwise from the trailer's forward axis [°]")
    lever_arm_m: tuple[Real, Real, Real] = Field(description="mount point from the kingpin, trailer axes [m]")
    follow_point_offset_m: Real | None = Field(None, gt=0.0, le=30.0, description="kingpin to follow point [m]")
    pitch_deg: Real = Field(0.0, ge=-60.0, le=60.0, description="down-tilt [°]; beyond 60° the road fills the image")
    roll_deg: Real = Field(0.0, ge=-45.0, le=45.0, description="roll about the optical axis [°]")
    baseline_m: Real | None = Field(
        None, gt=0.0, le=5.0, description="the stereo baseline as measured on the rig [m], checked against the camera's"
    )
    unit: int = Field(1, ge=1, le=16, description="the towed unit carrying the rig: 1 the first, 2 the one it tows, …")

    _vehicle_file = field_validator("vehicle", mode="before")(read_vehicle_file)
    _known = field_validator("vehicle")(check_vehicle)


@dataclass(frozen=True)
class RecordingRig:
    """The rig in SI units: the combination and the camera's mounting on its trailer.

    Attributes
    ----------
    params : VehicleParams
        The combination, its follow point as the rig file says.
    psi_c2v : float
        [rad], clockwise from the trailer's forward axis.
    lever_arm : numpy.ndarray
        The mount point from the kingpin, trailer axes [m].
    pitch, roll : float
        The cameras' down-tilt and roll [rad].
    file : dict
        The rig file's fields as given (for the run's record).
    baseline : float or None
        The baseline measured on the rig [m] (None: not given).
    unit : int
        The towed unit carrying the rig (1 the first; :attr:`sensor.camera.StereoRig.unit`).
    """

    params: VehicleParams
    psi_c2v: float
    lever_arm: np.ndarray
    pitch: float
    roll: float
    file: dict[str, Any]
    baseline: float | None = None
    unit: int = 1

    @property
    def follow_point_offset(self) -> float:
        """Front coupling to follow point ``L_fp`` [m] of the rig's unit."""
        return self.params.follow_point_offset_of(self.unit)

    def camera_in_trailer(self, baseline: float, rectification: RectifiedParameters | None = None) -> np.ndarray:
        """``T_trailer←camera`` (4×4) of the frame the odometry's motion is in: the left camera of a pair
        ``baseline`` metres wide, or its rectified frame (``rectification``: ``R1`` of the calibration)."""
        x, y, z = (float(v) for v in self.lever_arm)
        rig = StereoRig(baseline=float(baseline), station=x, lateral=y, mount_height=z, psi_c2v=self.psi_c2v)
        pose = rig.camera_in_trailer("left")
        if self.pitch or self.roll:
            cp, sp = math.cos(self.pitch), math.sin(self.pitch)
            cr, sr = math.cos(self.roll), math.sin(self.roll)
            down = np.array([[1.0, 0.0, 0.0], [0.0, cp, sp], [0.0, -sp, cp]])  # optical axis towards +y (down)
            roll = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])  # about the optical axis
            rotation = rig.mount_rotation() @ down @ roll
            pose[:3, :3] = rotation
            pose[:3, 3] = self.lever_arm - 0.5 * float(baseline) * rotation[:, 0]
        return pose if rectification is None else rectification.rectified_left_in_trailer(pose)


def _params(
    vehicle: str | CombinationSpec, follow_point_offset: float | None, source: str, unit: int = 1
) -> VehicleParams:
    params = params_of(vehicle)
    towed = len(params.trailers)
    if unit > towed:
        raise InputError(f"{source}: unit = {unit}: the {vehicle_name(vehicle)} tows {towed}; allowed: 1 to {towed}")
    if follow_point_offset is None:
        return params
    rear = params.trailers[unit - 1].rear_x
    if not follow_point_offset <= -rear:
        raise InputError(
            f"{source}: follow_point_offset_m = {follow_point_offset:g} m lies behind the {vehicle_name(vehicle)} "
            f"{_unit_name(unit)}'s rear; "
            f"allowed: (0, {-rear:g}] m"
        )
    data = params.model_dump()
    if unit == 1:
        data["trailer"]["follow_point_x"] = -float(follow_point_offset)
    else:
        data["rear_trailers"][unit - 2]["follow_point_x"] = -float(follow_point_offset)
    return VehicleParams.model_validate(data)


def _unit_name(unit: int) -> str:
    """``trailer`` for the first towed unit, ``towed unit k`` behind it."""
    return "trailer" if unit == 1 else f"towed unit {unit}"


def _check_lever_arm(
    arm: tuple[float, float, float], params: VehicleParams, vehicle: str, source: str, unit: int = 1
) -> None:
    trailer = params.trailers[unit - 1]
    lo, hi = trailer.rear_x - MOUNT_REACH, trailer.front_x + MOUNT_REACH
    side = 0.5 * trailer.width + MOUNT_REACH
    x, y, z = arm
    if not (lo <= x <= hi and abs(y) <= side and MOUNT_LOW <= z <= MOUNT_TOP):
        raise InputError(
            f"{source}: lever_arm_m = [{x:g}, {y:g}, {z:g}] puts the camera off the {vehicle} {_unit_name(unit)}; "
            "allowed: "
            f"x in [{lo:g}, {hi:g}] m (the body {trailer.rear_x:g}…{trailer.front_x:g} m from the kingpin, "
            f"{MOUNT_REACH:g} m of bracket), |y| ≤ {side:g} m, z in [{MOUNT_LOW:g}, {MOUNT_TOP:g}] m"
        )


def load_rig(path: Path) -> RecordingRig:
    """Read and check a rig file (module notes).

    Raises
    ------
    InputError
        The file is missing, not YAML within bounds, a field is unknown or out of range, the follow point lies
        off the trailer or the lever arm puts the camera off it — one line naming the file and the field.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"--rig {path}: not found; allowed: a rig YAML file (psi_c2v_deg, lever_arm_m, vehicle)")
    raw = path.read_bytes()
    if len(raw) > MAX_BYTES:
        raise InputError(f"--rig {path}: {len(raw)} bytes; allowed: at most {MAX_BYTES}")
    data = load_yaml(raw, f"rig file {path}")
    if not isinstance(data, dict):
        raise InputError(f"--rig {path}: not a mapping of fields; allowed: psi_c2v_deg, lever_arm_m, vehicle, …")
    return rig_from_fields(data, f"--rig {path}")


def rig_from_fields(data: dict[str, Any], source: str) -> RecordingRig:
    """The rig of a rig file's fields (``source`` names where they come from in the messages)."""
    try:
        rig = RigFile.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        field = field_name(first["loc"]) or "file"
        raise InputError(f"{source}: {field}: {first['msg'].removeprefix('Value error, ')}") from None
    params = _params(rig.vehicle, rig.follow_point_offset_m, source, rig.unit)
    _check_lever_arm(rig.lever_arm_m, params, vehicle_name(rig.vehicle), source, rig.unit)
    fields = rig.model_dump(mode="json")
    if rig.unit == 1 and "unit" not in data:
        del fields["unit"]  # a rig on the first towed unit is written as it was given
    return RecordingRig(
        params,
        math.radians(rig.psi_c2v_deg),
        np.array(rig.lever_arm_m, dtype=float),
        math.radians(rig.pitch_deg),
        math.radians(rig.roll_deg),
        fields,
        rig.baseline_m,
        rig.unit,
    )
