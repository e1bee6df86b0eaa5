"""The combination's signals recorded beside a camera: a CSV of time, speed, yaw rate and articulation.

Columns (a header line, units in the names; degrees at this edge, SI inside):

=================================== ==============================================================================
``time_s``                          time on the recording's clock [s], strictly increasing
``speed_m_s``                       the tractor's wheel speed [m/s]
``yaw_rate_deg_s``                  the tractor's yaw rate [°/s] (or ``yaw_rate_rad_s``)
``articulation_deg``                articulation Γ = ψ1 − ψ2 [°] (or ``articulation_rad``; positive in a left turn)
``trailer_yaw_rate_deg_s``          optional: the trailer's gyro [°/s] (or ``_rad_s``)
``trailer_speed_m_s``               optional: a wheel speed on an unsteered trailer axle [m/s]
``lateral_acceleration_m_s2``       optional: the tractor's lateral accelerometer (specific force, left positive)
                                    [m/s²], for the ``lateral_acceleration`` rear point
                                    (:data:`vehicle_model.kinematics.RearPoint`)
``longitudinal_acceleration_m_s2``  optional: the tractor's longitudinal accelerometer (specific force along its
                                    x axis, ``+g·sin θ`` up a grade) [m/s²] (or
                                    ``tractor_longitudinal_acceleration_m_s2``), for the zero-slip estimate's grade
                                    (``--zero-slip-grade accelerometer``, :mod:`controller.grade_estimate`)
``articulation2_deg``, …            optional: the articulation of the couplings behind the first, Γ_k = ψ_k − ψ_{k+1}
                                    [°] (or ``_rad``; ``articulation2`` the coupling of the second towed unit, up to
                                    ``articulation4``), for a rig on a unit behind the first
=================================== ==============================================================================

The signals beside a rig on towed unit ``k`` behind the first (``offtrack estimate --rigs``) are that unit's: the
tractor's three, the articulations ``Γ_1 … Γ_k`` of every coupling down to the unit's own, and the unit's own gyro
and wheel speed in ``trailer_yaw_rate_*`` and ``trailer_speed_m_s`` (required there: the derivation below holds for
the first towed unit only).

The fused filter (:mod:`sensor.fusion`) propagates with the trailer's yaw rate and wheel speed; without their
columns they come from the tractor's signals: ``r2 = r1 − dΓ/dt`` (Γ = ψ1 − ψ2, docs/design.md §5) and the
kingpin's longitudinal speed in trailer axes if no tractor tyre slips, ``u2 = cos Γ·u1 − sin Γ·(−e·r1)`` (Cheng 2009;
:func:`vehicle_model.kinematics.zero_slip_kingpin_velocity`). Cheng's zero-slip estimate takes the tractor's three.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.kinematics import zero_slip_kingpin_velocity
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import STATE_LIMITS

__all__ = ["SIGNAL_COLUMNS", "SIGNAL_LIMITS", "SignalSeries", "read_signals"]

SIGNAL_COLUMNS = {
    "time": ("time_s",),
    "speed": ("speed_m_s",),
    "yaw_rate": ("yaw_rate_deg_s", "yaw_rate_rad_s"),
    "articulation": ("articulation_deg", "articulation_rad"),
    "trailer_yaw_rate": ("trailer_yaw_rate_deg_s", "trailer_yaw_rate_rad_s"),
    "trailer_speed": ("trailer_speed_m_s",),
    "lateral_acceleration": ("lateral_acceleration_m_s2",),
    "longitudinal_acceleration": ("longitudinal_acceleration_m_s2", "tractor_longitudinal_acceleration_m_s2"),
    **{f"articulation{k}": (f"articulation{k}_deg", f"articulation{k}_rad") for k in range(2, 5)},
}
"""Each signal and the column names it may have (the first unit given is the usual one)."""
_REQUIRED = ("time", "speed", "yaw_rate", "articulation")

SIGNAL_LIMITS = {
    "speed": STATE_LIMITS["u"],
    "yaw_rate": STATE_LIMITS["r1"],
    "articulation": STATE_LIMITS["gamma"],
    "trailer_yaw_rate": STATE_LIMITS["r2"],
    "trailer_speed": STATE_LIMITS["u"],
    "lateral_acceleration": 50.0,
    "longitudinal_acceleration": 50.0,
    **{f"articulation{k}": STATE_LIMITS["gamma"] for k in range(2, 5)},
}
"""Largest magnitude of each signal, SI: the vehicle model's state limits
(:data:`vehicle_model.simulator.STATE_LIMITS`: speed, yaw rates, articulation) and 50 m/s² (5 g, an
accelerometer's full scale, several times any tyre's grip) for the lateral and longitudinal accelerations. A value
beyond is a column in other units or a corrupt file, refused before any work."""


@dataclass(frozen=True)
class SignalSeries:
    """The signals of a CSV (module notes), SI units.

    Attributes
    ----------
    time : numpy.ndarray
        [s] on the recording's clock.
    speed, yaw_rate, articulation : numpy.ndarray
        The tractor's wheel speed [m/s], yaw rate [rad/s] and the articulation [rad].
    trailer_yaw_rate, trailer_speed : numpy.ndarray or None
        The trailer's gyro [rad/s] and axle wheel speed [m/s], when recorded.
    lateral_acceleration : numpy.ndarray or None
        The tractor's lateral specific force [m/s²], when recorded.
    source : str
        The file.
    rear_articulations : tuple of numpy.ndarray
        ``Γ_2, Γ_3, …`` [rad] of the couplings behind the first, as far as recorded without a gap.
    longitudinal_acceleration : numpy.ndarray or None
        The tractor's longitudinal specific force [m/s²], when recorded.
    """

    time: np.ndarray
    speed: np.ndarray
    yaw_rate: np.ndarray
    articulation: np.ndarray
    trailer_yaw_rate: np.ndarray | None
    trailer_speed: np.ndarray | None
    lateral_acceleration: np.ndarray | None
    source: str
    rear_articulations: tuple[np.ndarray, ...] = ()
    longitudinal_acceleration: np.ndarray | None = None

    def at(self, times: np.ndarray, params: VehicleParams) -> dict[str, np.ndarray]:
        """The signals at ``times`` (linear interpolation; NaN outside the recorded span): ``speed``, ``yaw_rate``,
        ``articulation``, ``trailer_yaw_rate`` and ``trailer_speed`` (derived as the module notes say when not
        recorded), ``lateral_acceleration`` (NaN when not recorded), ``longitudinal_acceleration`` and
        ``articulation2``, … as recorded."""
        times = np.asarray(times, dtype=float)
        inside = (times >= self.time[0]) & (times <= self.time[-1])

        def sample(values: np.ndarray) -> np.ndarray:
            return np.where(inside, np.interp(times, self.time, values), np.nan)

        out = {name: sample(getattr(self, name)) for name in ("speed", "yaw_rate", "articulation")}
        if self.trailer_yaw_rate is not None:
            out["trailer_yaw_rate"] = sample(self.trailer_yaw_rate)
        else:
            rate = np.gradient(self.articulation, self.time) if self.time.size > 1 else np.zeros(1)
            out["trailer_yaw_rate"] = sample(self.yaw_rate - rate)  # ψ2 = ψ1 − Γ, docs/design.md §5
        if self.trailer_speed is not None:
            out["trailer_speed"] = sample(self.trailer_speed)
        else:
            # Cheng 2009: the kingpin moves at (u1, −e·r1) in tractor axes; turned by Γ into trailer axes.
            _, lateral_per_rate = zero_slip_kingpin_velocity(params, 0.0, 1.0)
            u1, r1, gamma = out["speed"], out["yaw_rate"], out["articulation"]
            out["trailer_speed"] = np.cos(gamma) * u1 - np.sin(gamma) * (lateral_per_rate * r1)
        recorded = self.lateral_acceleration
        out["lateral_acceleration"] = sample(recorded) if recorded is not None else np.full(times.shape, np.nan)
        if self.longitudinal_acceleration is not None:
            out["longitudinal_acceleration"] = sample(self.longitudinal_acceleration)
        for k, values in enumerate(self.rear_articulations, 2):
            out[f"articulation{k}"] = sample(values)
        return out


def read_signals(path: Path) -> SignalSeries:
    """The signals of a CSV (module notes), checked.

    Raises
    ------
    InputError
        The file is missing or unreadable, a required column is missing, a value is not a finite number or lies
        beyond :data:`SIGNAL_LIMITS`, or the times do not increase — one line naming the file, the column and the line.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: not found; allowed: a CSV of time_s, speed_m_s, yaw_rate_deg_s, articulation_deg")
    try:
        with path.open(newline="") as fh:
            reader = csv.reader(fh)
            header = [h.strip() for h in next(reader, [])]
            rows = [row for row in reader if any(cell.strip() for cell in row)]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"{path}: cannot be read as a CSV ({exc})") from None
    columns: dict[str, tuple[int, float]] = {}
    for name, names in SIGNAL_COLUMNS.items():
        for option in names:
            if option in header:
                scale = math.pi / 180.0 if "_deg" in option else 1.0
                columns[name] = (header.index(option), scale)
                break
        else:
            if name in _REQUIRED:
                raise InputError(
                    f"{path}: no column {' or '.join(names)}; allowed: a header with "
                    + ", ".join(SIGNAL_COLUMNS[n][0] for n in _REQUIRED)
                )
    data: dict[str, np.ndarray] = {}
    for name, (index, scale) in columns.items():
        values = []
        for number, row in enumerate(rows, 2):
            try:
                value = float(row[index])
            except (IndexError, ValueError):
                raise InputError(f"{path}: line {number}, column {header[index]}: not a number") from None
            if not math.isfinite(value):
                raise InputError(f"{path}: line {number}, column {header[index]}: {value} is not finite")
            limit = SIGNAL_LIMITS.get(name)
            if limit is not None and not abs(value * scale) <= limit:
                bound = limit / scale
                raise InputError(
                    f"{path}: line {number}, column {header[index]}: {value:g}; allowed: [{-bound:.4g}, {bound:.4g}]"
                )
            values.append(value * scale)
        data[name] = np.array(values, dtype=float)
    time = data["time"]
    if time.size < 2:
        raise InputError(f"{path}: {time.size} rows; allowed: two or more")
    back = np.flatnonzero(np.diff(time) <= 0.0)
    if back.size:
        raise InputError(f"{path}: line {back[0] + 3}: time_s does not increase")
    return SignalSeries(
        time,
        data["speed"],
        data["yaw_rate"],
        data["articulation"],
        data.get("trailer_yaw_rate"),
        data.get("trailer_speed"),
        data.get("lateral_acceleration"),
        str(path),
        tuple(
            data[f"articulation{k}"] for k in range(2, 5) if all(f"articulation{j}" in data for j in range(2, k + 1))
        ),
        data.get("longitudinal_acceleration"),
    )
