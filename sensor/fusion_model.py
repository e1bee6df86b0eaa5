"""The fused VISO-OT filter's model: its state, the propagation with the trailer's signals, and what the
zero-slip kinematics and the camera measure of it (:class:`~sensor.fusion.FusedVisoOt` carries it out; the
zero-slip measurement's noise is :mod:`sensor.fusion_slip`, the off-tracking's std :mod:`sensor.fusion_std`).

Model (trailer frame ISO 8855, origin at the kingpin; docs/design.md §5–6)
--------------------------------------------------------------------------
State, kept relative to the *anchor* (the time of the last camera frame that was committed)::

    x = [Δx, Δy, Δψ, v_s, b_g, b_w, β_ψ]     (and ε_k of (K3) with ``kinematic_error_model: state``,
                                             then s_z and s_f of (3') when they are on)

``(Δx, Δy, Δψ)`` is the kingpin's displacement and the trailer's heading change since the anchor, in the
anchor's trailer frame; ``v_s`` is the lateral *slip velocity* of the kingpin [m/s] (what the trailer's zero-slip
kinematics does not explain); ``b_g`` the gyro bias [rad/s]; ``b_w`` the wheel-speed bias [m/s]; ``β_ψ`` [rad/m]
the visual odometry's systematic yaw error per metre travelled (calibration and lens: docs/field_bias.md).

Kinematics. The trailer yaw rate is ``r = r_m − b_g``; the kingpin's longitudinal velocity is that of every
point on the centre line, so the axle's wheel speed gives ``u = w_m − b_w`` (free-rolling trailer wheels, no
longitudinal slip). Zero lateral force on the trailer's axles at zero slip (docs/vehicle_dynamics.md §2.3, the
stiffness-weighted form: ``Σ C_j (v_k − r L_j − u tan δ_j) = 0``) gives the kingpin's lateral velocity::

    v_k = r·L_c + u·Σ w_j tan δ_j + v_s,     L_c = Σ C_j L_j / Σ C_j,   w_j = C_j / Σ C_j     (1)

(``L_j`` the axle's distance behind the kingpin, ``δ_j`` its measured steer, zero for a fixed axle). Over one
control period the rates are taken constant at the mean of the two samples and the kingpin moves on the
exact arc::

    δψ = r·dt,   δp = M(δψ)·(u, v_k)·dt,   M(θ) = [[sin θ/θ, −(1−cos θ)/θ], [(1−cos θ)/θ, sin θ/θ]]   (2)
    (Δx, Δy) ← (Δx, Δy) + R(Δψ)·δp,   Δψ ← Δψ + δψ

``v_s``, ``b_g`` and ``b_w`` are random walks in time, ``β_ψ`` in distance travelled. The gyro and wheel-speed
noises enter as white noise on the period's mean rate; the covariance propagates with the Jacobian of (2) (first
order in δψ). The gyro is zeroed at standstill (:meth:`FusedVisoOt.zero_gyro`), as a vehicle's stability control
does at every stop: ``b_g`` starts at the mean reading over the stop with the variance of that mean,
``σ_g²/n`` for ``n`` samples, so that the heading comes from the gyro and the odometry's yaw error is found against
it (docs/field_bias.md); a gyro that was not zeroed starts at zero within ``initial_gyro_bias``, the offset a
data sheet leaves (:mod:`sensor.datasheet`).

Zero-slip measurement (every control tick, when the tractor's signals are given). If no tractor tyre slips
sideways, the kingpin moves at ``(u_1, −e·r_1)`` in tractor axes (:func:`vehicle_model.kinematics.
zero_slip_kingpin_velocity`; Cheng 2009): turned by the articulation Γ into trailer axes its lateral component is
``z_c = sin Γ·u_1 + cos Γ·(−e·r_1)`` (``u_1``, ``r_1`` the tractor's wheel speed and yaw rate). For a unit behind
the first the kingpin's velocity is carried down the chain as rigid-body motion, with the measured articulations
and yaw rates of the units ahead, before it is turned into the unit's axes (:class:`ChainSignals`,
:mod:`sensor.unit_kinematics`): the tractor's slip stays the only error. ``e`` is the
kingpin's distance behind the tractor's rear point, which is not fixed: in a steady turn the rear tyres carry the
tractor's lateral acceleration and the trailer's pull at the fifth wheel, and with linear tyres the point without
lateral velocity lies ``L1' = L1 − K·u_1²`` behind the steer axle (``L1`` the equivalent wheelbase, ``K`` from the
masses and the static cornering stiffnesses: :meth:`~vehicle_model.parameters.VehicleParams.tractor_rear_point`,
docs/vehicle_dynamics.md §2.3, §6.6), so ``e = L_5 − L1'`` with ``kinematic_rear_point`` ``speed_compensated``
(default ``axle_mean``: the rear axles' mean station, fixed). That is the steady part of the tractor's slip,
predicted from its speed. With the tractor's lateral accelerometer (``lateral_acceleration``) the rear point is the
equivalent wheelbase moving sideways at ``−K·u_1·f_y`` (``f_y`` the specific force it reads:
:meth:`~vehicle_model.parameters.VehicleParams.tractor_rear_slip_velocity`), which is the same in a level steady
turn (``f_y = u_1·r_1``) and also covers a cross slope's share of gravity. The rest (saturation, a scrubbing
trailer's push, and for the fixed points the camber) is ``ε_k`` below. With ``trailer_lateral_acceleration``
``z_c`` is not the tractor's at all: it is (1) at the slip the unit's own accelerometer asks of its axles, (T2) of
:mod:`sensor.unit_slip_reference`, so ``ε_k`` is that model's error, not the tractor's slip, and the camera's
disagreement is not weighed as evidence of slip against it. With (1) it measures the slip velocity::

    z_c − r_m·L_c − w_m·Σ w_j tan δ_j = v_s + ε_k                                               (K1)

``ε_k`` the slip of the tractor's own tyres: a slowly varying error whose standard deviation follows the evidence of
slip, (K2)–(K4) of :mod:`sensor.fusion_slip`.

Camera measurement. Each frame's camera motion becomes a kingpin increment ``z = (dx, dy, dψ)`` over the frame
interval through the camera's pose on the trailer (eqs (1)–(2), :meth:`VisoOtEstimator.kingpin_increment`). Its
covariance ``R`` is the odometry's ``Σ = (JᵀJ)⁻¹σ̂²`` of the 6 motion parameters mapped through that function
(numerical Jacobian), scaled by ``vo_covariance_scale`` (the Gauss–Newton covariance is a floor of the true one,
:mod:`sensor.vo.quality`) plus a floor; so a frame with few or noisy inliers counts for less. The odometry's
systematic error lies along its weakest direction, the yaw–translation ambiguity of a camera looking along its
motion: a yaw error comes with the translation error that keeps the far features in place. So the motion measures::

    z = (Δx, Δy, Δψ) + d·β_ψ·(κ·c_x, κ·c_y, 1),    (c_x, c_y) = R_{xy,ψ} / R_ψψ                   (3)

``d = Δx`` the distance since the anchor, ``(c_x, c_y)`` the frame's regression of translation on yaw error from
``R``, ``κ`` = ``vo_bias_coupling`` (measured, docs/field_bias.md). A motion whose normalised innovation squared
exceeds ``gate`` is refused (``max_gated`` in a row are accepted with the covariance inflated, so the filter cannot
lock itself out).

A camera that looks across its motion (a side camera) has its weakest direction along its optical axis ``o``, the
off-tracking direction, instead. Two optional states, appended after the others, model the odometry's systematic
error along it: ``s_z`` (``vo_axial_scale`` its start std), a relative error of the camera's displacement along the
axis (a disparity offset scaling the depths), and ``s_f`` [1/m] (``vo_axial_flow``), an error that grows with the
square of the camera's displacement across the axis between two frames (the image's flow through a calibration's
residual: features crossing the image change their disparity error with the distance they move, docs/field_bias.md
§7.4). With ``Δ_c`` the camera's displacement over the frame (the kingpin's plus the lever ``(R(Δψ) − I)·p_c`` of the
camera at ``p_c``) and ``t = (o_y, −o_x)``::

    z_xy = (Δx, Δy) + [eq (3)'s term] + (s_z·(o·Δ_c) + s_f·(t·Δ_c)·|t·Δ_c|)·o                    (3')

Both are random walks in distance (``vo_axial_scale_walk``) and are found against the zero-slip kinematics (K1)
where those are trusted (the disagreement of (K2) is taken less their estimated part): a side camera on a straight
road must report no lateral motion. Both are off by default (no such states).

Eq (3) couples to ``β_ψ`` the translation of the odometry's own yaw–translation ambiguity. A yaw error that is a
rotation of the camera about its own position (a mount's twist, a misaligned or self-calibrated stereo pair) moves
the kingpin's increment by the lever instead: ``ℓ·δψ`` with ``ℓ = (p_c,y, −p_c,x)``, the kingpin's displacement per
radian of a rotation about the camera at ``p_c``. With ``vo_yaw_lever`` the coupled translation's part along the
optical axis ``o`` is the lever's; across the axis it stays eq (3)'s::

    c' = κ·c + (o·ℓ − o·κ·c)·o,    z = (Δx, Δy, Δψ) + d·β_ψ·(c'_x, c'_y, 1)                      (3'')

For a side rig ``o·ℓ`` is the camera's distance behind the kingpin; without it the part of the lever ``o·κ·c`` leaves
out is left to ``s_f`` on a straight road, where the two are not told apart (docs/field_bias.md §7.24). Off by
default (eq (3)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vehicle_model.rigid import invert_rigid

from .fusion_noise import FusionNoise
from .viso_ot import VisoOtEstimator
from .vo.motion import params_to_transform, transform_to_params

__all__ = [
    "BG",
    "BIASES",
    "BPSI",
    "BW",
    "EK",
    "STATES",
    "VS",
    "ProcessModel",
    "StateLayout",
    "apply_rows",
    "camera_displacement",
    "camera_increment",
    "into_frame",
    "relative_pose",
    "yaw_coupling",
]

STATES = 7
"""The always-present states ``[Δx, Δy, Δψ, v_s, b_g, b_w, β_ψ]``."""
VS, BG, BW, BPSI, EK = 3, 4, 5, 6, 7
BIASES = [BG, BPSI]


@dataclass(frozen=True)
class StateLayout:
    """Which optional states are on and where they sit: ``ε_k`` of (K3), then ``s_z`` and ``s_f`` of (3').

    Attributes
    ----------
    error_state : bool
        ``ε_k`` is a state (``kinematic_error_model: state``), at index :data:`EK`.
    sz, sf : int or None
        Indices of ``s_z`` and ``s_f`` (``None``: off).
    size : int
        Number of states.
    """

    error_state: bool
    sz: int | None
    sf: int | None
    size: int

    @classmethod
    def of(cls, noise: FusionNoise) -> StateLayout:
        """The layout ``noise`` asks for (a state is on when its start std is positive)."""
        error_state = noise.kinematic_error_model == "state"
        axial, flow = noise.vo_axial_scale > 0.0, noise.vo_axial_flow > 0.0
        states = STATES + int(error_state)
        sz = states if axial else None
        sf = states + int(axial) if flow else None
        return cls(error_state, sz, sf, states + int(axial) + int(flow))

    @property
    def biases(self) -> list[int]:
        """The states common to every increment, eq (5)'s ``P_b``: ``b_g``, ``β_ψ``, then ``s_z``, ``s_f`` when on."""
        return [*BIASES, *(i for i in (self.sz, self.sf) if i is not None)]

    def start(self, noise: FusionNoise) -> tuple[np.ndarray, np.ndarray]:
        """The state and covariance at the start (no gyro zeroing)."""
        n = noise
        p0 = np.diag(
            [
                *(0.0, 0.0, 0.0),
                *(n.initial_slip_velocity**2, n.initial_gyro_bias**2, n.initial_wheel_speed_bias**2),
                n.vo_yaw_bias**2,
                *((n.tractor_slip**2,) if self.error_state else ()),
                *((n.vo_axial_scale**2,) if self.sz is not None else ()),
                *((n.vo_axial_flow**2,) if self.sf is not None else ()),
            ]
        )
        return np.zeros(self.size), p0


class ProcessModel:
    """One control period of eqs (1)–(2) and its covariance, for a unit with the slip point ``L_c`` [m].

    Parameters
    ----------
    noise
        The filter's noise model.
    slip_point
        ``L_c`` of eq (1) [m].
    layout
        The state layout.
    """

    def __init__(self, noise: FusionNoise, slip_point: float, layout: StateLayout) -> None:
        self.noise = noise
        self.slip_point = slip_point
        self.layout = layout
        n = noise
        self._sample_variance = np.array([n.gyro_noise**2, n.wheel_speed_noise**2])
        self._walk_time = np.diag([n.slip_velocity_walk**2, n.gyro_bias_walk**2, n.wheel_speed_bias_walk**2])
        self._walk_distance = n.vo_yaw_bias_walk**2
        self._f = np.eye(layout.size)  # work arrays of step
        self._g = np.zeros((layout.size, 2))

    def step(
        self,
        x: np.ndarray,
        p: np.ndarray,
        inputs: tuple[float, ...],
        kinematic_variance: float = 0.0,
        extra_slip_walk: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Eqs (1)–(2) over ``inputs = (dt, r_m, w_m, Σ w_j tan δ_j)`` (the period's mean samples), and (K3) with
        ``σ_k²`` = ``kinematic_variance``: the state and covariance at the period's end. ``extra_slip_walk``
        [m/s/√s] widens ``v_s``'s random walk (the scrub demand of (K5), :mod:`sensor.fusion_slip`)."""
        dt, r_m, w_m, tan_steer = inputs
        r = r_m - x[BG]
        u = w_m - x[BW]
        v = r * self.slip_point + u * tan_steer + x[VS]
        th = r * dt
        if abs(th) > 1e-9:
            a, b = math.sin(th) / th, (1.0 - math.cos(th)) / th
        else:
            a, b = 1.0 - th * th / 6.0, 0.5 * th
        dp = np.array([a * u - b * v, b * u + a * v]) * dt  # eq (2)
        c, s = math.cos(x[2]), math.sin(x[2])
        rot = np.array([[c, -s], [s, c]])
        out = x.copy()
        out[:2] += rot @ dp
        out[2] += th
        # Jacobian (first order in δψ) and noise input of the (gyro, wheel) sample noise.
        ex, ey = rot[:, 0], rot[:, 1]
        lever, along = ey * (self.slip_point * dt), (ex + ey * tan_steer) * dt
        f = self._f
        f[:2, 2] = (-(s * dp[0] + c * dp[1]), c * dp[0] - s * dp[1])  # ∂/∂Δψ of R(Δψ)·δp
        f[:2, VS] = ey * dt
        f[:2, BG] = -lever
        f[2, BG] = -dt
        f[:2, BW] = -along
        g = self._g
        g[:2, 0] = lever
        g[2, 0] = dt
        g[:2, 1] = along
        q = (g * self._sample_variance) @ g.T
        q[VS:BPSI, VS:BPSI] += self._walk_time * dt
        q[BPSI, BPSI] += self._walk_distance * abs(u) * dt
        if extra_slip_walk > 0.0:  # (K5): scrubbing tyres change the slip velocity faster
            q[VS, VS] += extra_slip_walk**2 * dt
        if self.layout.error_state:  # (K3): ε_k ← φ·ε_k, its variance relaxing to σ_k² with the correlation time
            phi = math.exp(-dt / self.noise.kinematic_error_time)
            out[EK] = phi * x[EK]
            f[EK, EK] = phi
            q[EK, EK] += kinematic_variance * (1.0 - phi * phi)
        for i in (self.layout.sz, self.layout.sf):  # (3'): s_z and s_f random walks in distance
            if i is not None:
                q[i, i] += self.noise.vo_axial_scale_walk**2 * abs(u) * dt
        return out, f @ p @ f.T + q

    @property
    def transition(self) -> np.ndarray:
        """The Jacobian ``F`` of the last :meth:`step` (its work array: valid until the next step)."""
        return self._f


def camera_displacement(delta: np.ndarray, camera: np.ndarray, axis: np.ndarray) -> tuple[float, float]:
    """The camera's displacement along and across its optical axis ``axis`` over a kingpin increment
    ``(dx, dy, dψ)`` [m] of (3'): the kingpin's, plus the lever ``(R(dψ) − I)·p_c`` of the camera at ``camera``;
    "across" is along ``t = (o_y, −o_x)``, the axis turned a right angle clockwise."""
    ct, st = math.cos(delta[2]), math.sin(delta[2])
    mx = delta[0] + (ct - 1.0) * camera[0] - st * camera[1]
    my = delta[1] + st * camera[0] + (ct - 1.0) * camera[1]
    o = axis
    return float(mx * o[0] + my * o[1]), float(mx * o[1] - my * o[0])


def yaw_coupling(noise: FusionNoise, r: np.ndarray, camera: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The translation coupled to the odometry's yaw error per radian, ``κ·(c_x, c_y)`` of eq (3) from the frame's
    covariance ``r`` (3×3), or with ``noise.vo_yaw_lever`` ``c'`` of (3''): along the optical axis ``axis`` the lever of
    a rotation about the camera at ``camera`` [m] (``axis`` a unit vector in the unit's ground plane)."""
    coupling = noise.vo_bias_coupling * r[:2, 2] / r[2, 2]  # eq (3)
    if not noise.vo_yaw_lever:
        return coupling
    o = np.asarray(axis, dtype=float)
    lever = np.array([camera[1], -camera[0]], dtype=float)  # (R(δψ) − I)·(−p_c) per radian, to first order
    return coupling + (float(o @ lever) - float(o @ coupling)) * o  # (3'')


def camera_increment(
    geometry: VisoOtEstimator,
    noise: FusionNoise,
    camera_motion: np.ndarray,
    covariance: np.ndarray | None,
    tilt: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Kingpin increment ``z = (dx, dy, dψ)`` of one camera motion through the camera's pose (``geometry``, eqs
    (1)–(2) of :mod:`sensor.viso_ot`) and its 3×3 covariance ``R`` (the camera measurement above).

    ``covariance`` is the odometry's 6×6 covariance of ``(rx, ry, rz, tx, ty, tz)`` of Tr_delta, whose inverse is
    ``camera_motion``, mapped through a numerical Jacobian and scaled by ``vo_covariance_scale``; ``None``: the
    floor alone. Off the level road (``geometry.level_reference`` not ``planar``) the increment is in the level
    frame (:meth:`~sensor.viso_ot.VisoOtEstimator.level_increment`, ``tilt`` the unit's at this frame or ``None``
    to integrate it), from the tilt ``geometry`` holds for the frame before.
    """
    n = noise
    if geometry.level_reference == "planar":
        increment = geometry.kingpin_increment
    else:

        def increment(motion: np.ndarray) -> tuple[float, float, float]:
            return geometry.level_increment(motion, tilt)[0]

    z = np.array(increment(camera_motion))
    r = np.diag([n.vo_translation_floor**2, n.vo_translation_floor**2, n.vo_rotation_floor**2])
    if covariance is not None and np.all(np.isfinite(covariance)):
        theta = transform_to_params(invert_rigid(camera_motion))
        jac = np.empty((3, 6))
        h = 1e-7
        for i in range(6):
            d = theta.copy()
            d[i] += h
            jac[:, i] = (np.array(increment(invert_rigid(params_to_transform(d)))) - z) / h
        r = r + n.vo_covariance_scale * (jac @ np.asarray(covariance, dtype=float) @ jac.T)
    return z, r


def apply_rows(
    x: np.ndarray, p: np.ndarray, rows: tuple[tuple[np.ndarray, float, float], ...]
) -> tuple[np.ndarray, np.ndarray]:
    """Sequential scalar Kalman updates with the rows ``(H, z, R)`` (the zero-slip measurement (K1))."""
    for h, z, r in rows:
        ph = p @ h
        s = float(h @ ph) + r
        k = ph / s
        x = x + k * (z - float(h @ x))
        p = p - np.outer(k, ph)
    if rows:
        p = 0.5 * (p + p.T)
    return x, p


def relative_pose(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
    """Increment ``(dx, dy, dψ)`` from pose ``a`` to pose ``b`` (both in one frame), in ``a``'s frame."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return c * dx + s * dy, -s * dx + c * dy, float(b[2] - a[2])


def into_frame(poses: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Poses ``(n, 3)`` re-expressed in the frame of ``origin`` (a pose in their frame)."""
    c, s = math.cos(origin[2]), math.sin(origin[2])
    x = poses[:, 0] - origin[0]
    y = poses[:, 1] - origin[1]
    return np.column_stack([c * x + s * y, -s * x + c * y, poses[:, 2] - origin[2]])


def gated_update(
    x: np.ndarray, p: np.ndarray, h: np.ndarray, innovation: np.ndarray, r: np.ndarray, gate: float, refuse: bool
) -> tuple[np.ndarray, np.ndarray, float, bool]:
    """One Kalman update behind a χ² gate: ``(x, p, nis, used)``.

    ``nis`` is the normalised innovation squared against ``S = H P Hᵀ + R``. Above ``gate`` the measurement is refused
    when ``refuse`` (the state comes back as it was), or else taken with ``R`` inflated by ``nis / gate`` so that it
    sits on the gate (a run of refusals ends in a softened update rather than a filter that stops listening).
    """
    ph = p @ h.T
    s = h @ ph + r
    nis = float(innovation @ np.linalg.solve(s, innovation))
    if nis > gate and refuse:
        return x, p, nis, False
    if nis > gate:
        s = h @ ph + r * (nis / gate)
    k = np.linalg.solve(s, ph.T).T  # P Hᵀ S⁻¹
    x = x + k @ innovation
    p = p - k @ h @ p
    return x, 0.5 * (p + p.T), nis, True
