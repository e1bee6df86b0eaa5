"""Mount flex: the right camera's rotation relative to the left, frame by frame (de Saxe & Cebon 2018, §4.3–4.4).

de Saxe & Cebon 2018 traced the field tests' systematic errors to right-camera rotations under 0.2°
(φ = −0.15°, ψ = +0.10°, §4.4) and hypothesised that "the trailer structure itself could deform
(twist) as a result of moments in the chassis generated during turning. This may have acted to
correct for these camera rotations in left turns, but amplify them in right turns" (§4.3). The
model here is the sum of three parts, per axis (roll φ about the optical axis, pitch θ about the
camera x axis, yaw ψ about its y axis; the axes and composition of :class:`sensor.camera.Misalignment`,
the paper's eq (9))::

    angle_i(t) = static_i + k_i·a_y(t) + n_i(t)

* ``static_i`` — the quasi-static misalignment of the mount (:class:`~sensor.camera.Misalignment`);
* ``k_i·a_y`` — frame twist proportional to the lateral acceleration ``a_y`` [m/s²] of the unit the rig is on,
  left positive (ISO 8855; :func:`vehicle_model.kinematics.towed_unit_lateral_acceleration`), so a left and a
  right turn twist the mount by opposite amounts: with φ_static = −0.15° a positive ``k_roll``
  reduces the roll in left turns and amplifies it in right turns, the paper's hypothesis;
* ``n_i`` — vibration: white noise through a second-order Butterworth low-pass of cut-off
  ``f_c`` (ζ = 1/√2, ω = 2π·f_c; power spectrum ∝ 1/(ω⁴ + Ω⁴), half power at f_c, −40 dB/decade
  above), scaled to the configured RMS.

The three angles are summed (not composed as rotations): for angles of a few tenths of a degree
the difference is of second order, below 10⁻⁵ rad, and zero flex gives the static misalignment
exactly.

Vibration discretisation
------------------------
In normalised coordinates ``ξ = (x/σ, ẋ/(ω·σ))`` the filter is ``ξ̇ = A·ξ + w`` with
``A = ω·[[0, 1], [−1, −2ζ]]`` and a stationary covariance of the identity. Sampled at an interval
``Δt`` it is exactly (Van Loan; the stationary form of the discrete Lyapunov equation)::

    ξ_{k+1} = Φ·ξ_k + L·n_k,   Φ = exp(A·Δt),   L·Lᵀ = I − Φ·Φᵀ,   n_k ~ N(0, I)

with the closed form ``exp(A·t) = e^{αt}·[cos(βt)·I + sin(βt)/β·(A − α·I)]``, ``α = −ζω``,
``β = ω·√(1 − ζ²)``. The state starts from the stationary distribution, so the RMS holds from the
first frame, at any frame interval (also above the Nyquist rate of the frames: the samples are those
of the continuous process).

Applying it (for the camera pipeline)
-------------------------------------
:class:`FlexSchedule` runs the model frame by frame where the frames are taken, in order, with the trailer's
lateral acceleration between consecutive vehicle states, and hands each frame's rotation to the renderer.
The rotation is about the right camera's optical centre. Re-posing the right camera in the renderer
with the frame's :class:`~sensor.camera.Misalignment` (``StereoRig.replace(misalignment=…)``) is
exact everywhere and costs nothing extra (the right image is rendered every frame anyway). Warping
the ideal right image by ``K·R_misᵀ·K⁻¹`` (:meth:`sensor.camera.StereoRig.misalignment_homography`,
the paper's eq (8)) is exact for every scene point whatever its depth, since a pure rotation about the
optical centre has no parallax; but the rotated camera sees a thin strip the ideal render does
not (a yaw of 0.2° moves the 100° image's side borders by ~5 px, a roll moves the corners by
~2–3 px), which the warp fills with a border value, and the bilinear resampling smooths the image
slightly. Prefer re-posing; with the homography, mask the border strip out of the feature search.
"""

from __future__ import annotations

import math
from typing import Annotated

import numpy as np
from pydantic import Field

from vehicle_model.errors import InputError
from vehicle_model.kinematics import towed_unit_lateral_acceleration
from vehicle_model.parameters import VehicleParams
from vehicle_model.settings import Settings
from vehicle_model.simulator import VehicleState

from .camera import Misalignment

MAX_TWIST_DEG_PER_MPS2 = 1.0
"""Largest |twist| per axis [°/(m/s²)]: 3° at the 3 m/s² a combination can corner with, fifteen times
the paper's whole misalignment (< 0.2°, §4.4)."""

MAX_VIBRATION_RMS_DEG = 2.0
"""Largest vibration RMS per axis [°]: at 2° the right image moves by ~20 px and stereo matching fails."""

BANDWIDTH_RANGE_HZ = (0.01, 100.0)
"""Allowed vibration cut-off [Hz]: below 0.01 Hz it is a slow drift (a static misalignment), above
100 Hz beyond any body or mount resonance that matters."""

DAMPING = 1.0 / math.sqrt(2.0)
"""Damping ratio ζ of the vibration filter (second-order Butterworth: half power at the cut-off)."""


TwistDeg = Annotated[
    float,
    Field(
        ge=-MAX_TWIST_DEG_PER_MPS2,
        le=MAX_TWIST_DEG_PER_MPS2,
        description="[°/(m/s²)] per axis; de Saxe & Cebon 2018, §4.4 saw ~0.1–0.2° at ~1–2 m/s², so ±1 is generous",
    ),
]
VibrationDeg = Annotated[
    float, Field(ge=0.0, le=MAX_VIBRATION_RMS_DEG, description="[°] RMS per axis; 2° shakes any stereo rig apart")
]


class MountFlex(Settings):
    """Settings of the mount flex, degrees at this edge (see the module docstring for the model).

    Parameters
    ----------
    twist_deg_per_mps2 : tuple of 3 float
        Frame twist ``k`` per axis (roll, pitch, yaw) [° per m/s² of trailer lateral acceleration,
        left positive], each within ±:data:`MAX_TWIST_DEG_PER_MPS2`.
    vibration_rms_deg : tuple of 3 float
        Steady-state RMS of the vibration per axis [°], each in [0, :data:`MAX_VIBRATION_RMS_DEG`].
    vibration_bandwidth_hz : float
        Cut-off (−3 dB) frequency of the vibration [Hz], within :data:`BANDWIDTH_RANGE_HZ`.
    """

    twist_deg_per_mps2: tuple[TwistDeg, TwistDeg, TwistDeg] = (0.0, 0.0, 0.0)
    vibration_rms_deg: tuple[VibrationDeg, VibrationDeg, VibrationDeg] = (0.0, 0.0, 0.0)
    vibration_bandwidth_hz: float = Field(
        5.0, ge=BANDWIDTH_RANGE_HZ[0], le=BANDWIDTH_RANGE_HZ[1], description="[Hz] corner of the vibration"
    )

    @property
    def is_zero(self) -> bool:
        """No twist and no vibration: the right camera keeps its static misalignment."""
        return not any(self.twist_deg_per_mps2) and not any(self.vibration_rms_deg)


def vibration_transition(bandwidth_hz: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact one-step transition ``Φ`` and noise factor ``L`` of the normalised vibration filter.

    Parameters
    ----------
    bandwidth_hz
        Cut-off frequency [Hz].
    dt
        Sampling interval [s], ≥ 0.

    Returns
    -------
    tuple of numpy.ndarray
        ``Φ = exp(A·dt)`` (2×2) and ``L`` (2×2) with ``L·Lᵀ = I − Φ·Φᵀ`` (module docstring).
    """
    omega = 2.0 * math.pi * bandwidth_hz
    a = omega * np.array([[0.0, 1.0], [-1.0, -2.0 * DAMPING]])
    alpha = -DAMPING * omega
    beta = omega * math.sqrt(1.0 - DAMPING**2)
    # exp(A·t) for complex eigenvalues α ± iβ (Cayley–Hamilton for 2×2).
    phi = math.exp(alpha * dt) * (
        math.cos(beta * dt) * np.eye(2) + math.sin(beta * dt) / beta * (a - alpha * np.eye(2))
    )
    q = np.eye(2) - phi @ phi.T  # discrete noise covariance of the stationary process
    q = 0.5 * (q + q.T)
    values, vectors = np.linalg.eigh(q)
    factor = vectors * np.sqrt(np.clip(values, 0.0, None))
    return phi, factor


class MountFlexModel:
    """The right camera's misalignment frame by frame: static + twist + vibration (module docstring).

    Parameters
    ----------
    flex : MountFlex
        The settings.
    static : Misalignment
        The quasi-static misalignment of the mount [rad].
    seed : int or numpy.random.Generator or None
        Seed of the vibration, or the generator to draw from (one generator per run: pass a child of
        it). Only vibration draws random numbers.
    """

    def __init__(
        self,
        flex: MountFlex,
        static: Misalignment | None = None,
        seed: int | np.random.Generator | None = 0,
    ) -> None:
        if not isinstance(flex, MountFlex):
            raise InputError("flex must be a MountFlex")
        static = Misalignment() if static is None else static
        if not isinstance(static, Misalignment):
            raise InputError("static must be a Misalignment (use Misalignment.from_degrees)")
        self.flex = flex
        self.static = static
        self._static = np.array([static.roll, static.pitch, static.yaw])
        self._twist = np.radians(flex.twist_deg_per_mps2)  # [rad per m/s²]
        self._sigma = np.radians(flex.vibration_rms_deg)  # [rad]
        self._vibrating = bool(np.any(self._sigma > 0.0))
        self._rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self._transitions: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        # Normalised filter state per axis (rows: roll, pitch, yaw), drawn from the stationary N(0, I).
        self._state = self._rng.standard_normal((3, 2)) if self._vibrating else np.zeros((3, 2))

    def _advance(self, dt: float) -> None:
        if not (isinstance(dt, int | float) and math.isfinite(dt) and dt >= 0.0):
            raise InputError(f"dt = {dt!r} is out of range; allowed: a finite interval ≥ 0 s")
        if not self._vibrating:
            return
        if dt not in self._transitions:
            self._transitions[dt] = vibration_transition(self.flex.vibration_bandwidth_hz, dt)
        phi, factor = self._transitions[dt]
        self._state = self._state @ phi.T + self._rng.standard_normal((3, 2)) @ factor.T

    @property
    def vibration(self) -> np.ndarray:
        """The current vibration angles (roll, pitch, yaw) [rad]."""
        return self._sigma * self._state[:, 0]

    def vibration_series(self, n: int, dt: float) -> np.ndarray:
        """Advance the vibration ``n`` intervals of ``dt`` [s]; the angles after each, ``(n, 3)`` [rad]."""
        out = np.empty((int(n), 3))
        for k in range(int(n)):
            self._advance(dt)
            out[k] = self.vibration
        return out

    def rotation_at(self, lateral_acceleration: float, dt: float) -> Misalignment:
        """The right camera's total misalignment for this frame.

        Parameters
        ----------
        lateral_acceleration
            Trailer lateral acceleration ``a_y`` [m/s²], left positive (ISO 8855).
        dt
            Time since the previous frame [s] (the vibration advances by it; 0 repeats the frame).

        Returns
        -------
        Misalignment
            ``static + k·a_y + vibration`` per axis [rad].

        Raises
        ------
        InputError
            A non-finite ``lateral_acceleration``, a negative or non-finite ``dt``, or a total beyond
            the ±20° that :class:`~sensor.camera.Misalignment` accepts.
        """
        if not math.isfinite(lateral_acceleration):
            raise InputError(f"lateral_acceleration = {lateral_acceleration!r} must be finite [m/s²]")
        self._advance(dt)
        angles = self._static + self._twist * float(lateral_acceleration) + self.vibration
        return Misalignment(*(float(v) for v in angles))


class FlexSchedule:
    """The right camera's mount flex frame by frame, from the lateral acceleration of the rig's own unit.

    The twist needs the acceleration between consecutive frames and the vibration a sequence of draws, so the
    schedule runs where the frames are taken, in order, and hands each frame's rotation to the renderer.

    Parameters
    ----------
    flex : MountFlex
        The settings (zero: no flex, :meth:`rotation` gives ``None``).
    params : VehicleParams
        The combination.
    station : float or None
        Station of the point of the rig's unit whose lateral acceleration twists the mount [m] (from the unit's
        front coupling, negative behind it); None: the unit's CG
        (:func:`vehicle_model.kinematics.towed_unit_lateral_acceleration`).
    frame_interval : float
        Time between frames [s].
    rng : numpy.random.Generator
        The vibration's draws (a child of the run's seed).
    unit : int
        The towed unit the rig is mounted on (1 the first): its own lateral acceleration twists the mount.
    """

    def __init__(
        self,
        flex: MountFlex,
        params: VehicleParams,
        station: float | None,
        frame_interval: float,
        rng: np.random.Generator,
        unit: int = 1,
    ) -> None:
        self.params = params
        self.dt = frame_interval
        self.station = station
        self.unit = unit
        self.model = None if flex.is_zero else MountFlexModel(flex, None, rng)
        self._previous: VehicleState | None = None

    def rotation(self, state: VehicleState) -> Misalignment | None:
        """This frame's flex rotation of the right camera (on top of its static misalignment), or ``None``."""
        if self.model is None:
            return None
        previous, self._previous = self._previous, state
        a_y = 0.0
        if previous is not None and state.time > previous.time:
            a_y = towed_unit_lateral_acceleration(self.params, previous, state, self.unit, station=self.station)
        if not math.isfinite(a_y):
            a_y = 0.0
        return self.model.rotation_at(a_y, self.dt)
