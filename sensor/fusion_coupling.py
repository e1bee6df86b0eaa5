"""A following unit's camera as a reference for the unit ahead of it: its motion carried forward through the couplings.

A side rig's filter (:class:`~sensor.fusion.FusedVisoOt` with a camera looking across its motion) has states of its
odometry's error along the optical axis (eq (3') of :mod:`sensor.fusion_model`) that it finds against the zero-slip
kinematics; where the tyres slide it learns the slide as that error (docs/field_bias.md §7.6). A coupling is a point
shared by two rigid bodies, so the motion of a unit behind, measured by its own camera, gives the motion of the
coupling it hangs on, and with the measured articulation the motion of the unit ahead, with no assumption about
any tyre (docs/vehicle_dynamics.md §1.1; docs/fusion.md, *A following unit's camera*).

Transport (ground plane, each unit's axes ISO 8855 with the origin at its front coupling). Units ``j`` (the lead,
whose filter takes the reference) to ``m`` (the follower, whose camera moved), ``j < m``. Unit ``i`` has its rear
coupling at ``p_i = (x5_i, 0)`` (its ``fifth_wheel_x``: a fifth wheel, a dolly's, or a tow hitch), which is the front
coupling of unit ``i + 1``; ``Γ_{i+1} = ψ_i − ψ_{i+1}`` is the articulation of that coupling, ``Γ⁰`` at the frame's
start and ``Γ¹`` at its end. The follower's front-coupling increment over the frame, ``(d_m, Δψ_m)`` in its axes at
the frame's start (its camera's motion through eqs (1)–(2) of :mod:`sensor.viso_ot`), is carried forward unit by
unit, ``i = m − 1, …, j``::

    r_i  = R(−Γ⁰_{i+1})·d_{i+1}                    (the shared coupling's displacement, in unit i's start axes)
    Δψ_i = Δψ_{i+1} + Γ¹_{i+1} − Γ⁰_{i+1}          (ψ_i = ψ_{i+1} + Γ_{i+1})
    d_i  = r_i − (R(Δψ_i) − I)·p_i                  (rigid body i: its rear coupling is p_i from its front)     (C1)

and ``(d_j, Δψ_j)`` measures the lead's kingpin increment ``(Δx, Δy, Δψ)`` since the frame's start directly
(``H = [I₃ 0]``): it carries neither the lead camera's systematic errors nor the zero-slip assumption, so the
lead's odometry states become observable against it on ice as on a dry road. Its covariance is the follower
motion's 3×3 covariance (:func:`~sensor.fusion_model.camera_increment`, the follower camera's odometry
covariance) and the articulation sensors' white noise ``σ_Γ`` (``articulation_noise``) on each ``Γ⁰``, ``Γ¹``,
mapped through the Jacobian of (C1)::

    R_c = k_c·(J_d·R_m·J_dᵀ + σ_Γ²·J_Γ·J_Γᵀ)                                                               (C2)

``k_c`` (``covariance_scale``, ``fusion.side_rig.coupling_covariance_scale``; 1 by default) widens it where the
follower's odometry errors are correlated over frames: ``R_m`` is each frame's own, and a lateral error that persists
over many frames sums in the lead's path linearly where white errors sum in quadrature, so a filter that takes the
frames as independent weights the reference more than its errors allow (docs/field_bias.md §7.12).

The follower's odometry has its own systematic yaw error ``β_ψ`` per metre, with the translation error that comes
with it (eq (3) of :mod:`sensor.fusion_model`); where the follower's own filter estimates it (against its gyro, which
no slip affects) the follower's increment is taken less that error before (C1), and the estimate's variance
``P_β`` is added to the follower's covariance::

    z_m ← z_m − d·β̂_ψ·g,   R_m ← R_m + d²·P_β·g·gᵀ,   g = s·((1 − D)·κ·c_x, (1 − D)·κ·c_y, 1),   d = z_m,x   (C0)

(``c`` the frame's yaw–translation regression from ``R_m``, ``κ`` = ``vo_bias_coupling``, as the follower's filter
takes them). ``D`` is the follower's scrub demand at its last frame, where its own filter takes the frame's motion with
only the share ``s = 1 − r·D`` of ``β̂_ψ`` ((K6), ``r`` = ``scrub_bias_release``) and the coupled translation at
``(1 − r·D)·(1 − D)`` ((K5)–(K6), :mod:`sensor.fusion_slip`): the reference removes what the follower's filter holds
to be the odometry's error in that motion, not the part it releases to the scrubbing tyres. Without a demand
(``D = 0``) ``g = (κ·c_x, κ·c_y, 1)``.

The follower's odometry may also misjudge its travel along its own optical axis ``o`` (a rear camera's weakest
direction: the far scenery fixes motion across the image better than along it, docs/field_bias.md §7.38); where the
follower's filter holds that error as its state ``s_z`` (eq (3') of :mod:`sensor.fusion_model`, ``z_xy = Δ_xy +
s_z·a(Δ)·o`` with ``a(Δ) = o·Δ_c`` the camera's displacement along ``o``), with ``axial_scale``
(``fusion.side_rig.coupling_axial_scale``; off by default) its estimate ``ŝ`` is taken out of the increment (C0) left,
``f``, before (C1), and its variance ``P_s`` added along the axis. ``a`` is linear in ``Δ_xy`` at a given ``Δψ``
(which ``s_z`` does not move), so ``a(f) = (1 + s_z)·a(Δ)`` and the model inverts exactly::

    f_xy ← f_xy − ŝ/(1 + ŝ)·a(f)·o,   R_m ← R_m + (d/(1 + ŝ))²·P_s·o·oᵀ,   d = a(f)/(1 + ŝ)              (C0'')

(``d`` the camera's travel along its axis as corrected; ``−d/(1 + ŝ)·o`` is the corrected increment's derivative in
``s_z``). (C1) rotates the axis by ``−Γ⁰`` into the lead's axes, so an along-axis error of a follower looking along its
unit lands in the lead's lateral as ``sin Γ⁰`` of it, and (C2)'s Jacobian carries ``P_s`` there by ``sin²Γ⁰``.
Without ``ŝ`` (no follower filter yet) the frame is taken as (C0) leaves it.

Where the follower's own tyres scrub (its axles steered to or near their lock, its scrub demand ``D`` of (K5) at the
frame high, :mod:`sensor.fusion_slip`) its camera's motion and its filter's (C0) carry the follower's own error, which
persists as long as the scrub does and which (C2) does not hold. With ``follower_limit`` (``fusion.side_rig.
coupling_follower_limit``; off by default) a frame whose ``D`` is at or above its ``demand`` is either widened by the
follower's own off-tracking variance ``σ_f²`` (its fused filter's std squared) on the lead's lateral axis, or refused
(the lead takes its own frame alone for that tick)::

    R_c ← R_c + σ_f²·e_y·e_yᵀ   (inflate),     no measurement   (refuse)                                   (C3)

A frame whose ``σ_f`` is not known (the follower's filter without an estimate) is refused under either action.
The follower's own error does not end with its scrub: where its axles pass through straight ahead between two turns
its demand falls below any ``demand`` while the estimate it takes its frames with still carries what the scrub left
(its odometry's coupled correction taken at nearly its full share while ``β̂_ψ`` is learnt again, docs/field_bias.md
§7.18). With ``below: inflate`` every frame under the demand is widened as ``inflate`` widens one above it::

    R_c ← R_c + σ_f²·e_y·e_yᵀ   (D < demand, below: inflate)                                              (C3')

and one whose ``σ_f`` is not known is refused under :data:`FOLLOWER_UNKNOWN`; a frame whose ``D`` is not known
(no follower filter) is taken as (C2) gives it. ``below: take`` (the default) is (C3) alone.

The follower's own scrub in (C2) itself. While the follower's tyres scrub its camera's motion has errors its
odometry covariance ``R_m`` does not hold (the scrubbing turn is not one the coupling of eq (3) was measured on,
docs/field_bias.md §6.8; the lead's reference measured against the truth, docs/field_bias.md §7.37). With
``scrub_scale`` ``k_s`` (``fusion.side_rig.coupling_scrub_scale``; off by default) (C2) grows with the follower's
scrub demand ``D`` at the frame, the one (C0) takes::

    R_c ← (1 + k_s·D)·R_c                                                                                  (C2')

``D = 0`` (or ``k_s = 0``, or no demand known) leaves (C2) as it is; at ``D = 1`` it is ``1 + k_s`` times (C2). It
acts on every frame, unlike (C3)'s threshold, and in proportion to the frame's own covariance, unlike (C3)'s
follower's off-tracking variance.

The follower's scrub in the share its own filter gives it: with ``follower_share``
(``fusion.side_rig.coupling_follower_share``; on by default) each frame's lateral variance takes the follower's
off-tracking variance ``σ_f²`` times its scrub demand ``D``, (C4) of :mod:`sensor.fusion_coupling_share` (the
reasoning there).

A follower camera that looks across its motion has the same axial errors as the lead's, so the follower is the
nearest unit behind whose camera looks along its unit (a rear or front rig, :func:`looks_along`).

Off the level road (``level_reference="accelerometer"``, :mod:`sensor.level_reference`) the lead's filter takes its
increments in its **level frame** (its heading about the vertical, :meth:`~sensor.viso_ot.VisoOtEstimator.
level_increment`), and so does the reference: the follower's camera motion is made horizontal exactly as its own
filter makes it, from the follower's accelerometer tilt at the frame's start and end, and (C1) carries that
horizontal increment forward unchanged. (C1) holds in the level frame when each ``Γ`` is the difference of the two
units' headings about the vertical and each ``p_i`` is the rear coupling's horizontal station, as the yaw-plane model
places them (:mod:`vehicle_model.terrain_pose`: every unit's heading is horizontal, its supports lifted onto the
ground). A real articulation sensor turns about the coupling's axis, the units' common normal on a grade of
inclination ``α``; a direction at an angle ``β`` in that plane from the fall line has the horizontal azimuth
``atan2(sin β, cos β·cos α)``, whose slope in ``β`` lies within ``[cos α, 1/cos α]``, so the angle measured about the
normal differs from its horizontal projection by at most ``(1/cos α − 1)·|Γ|`` (1.1 % of ``Γ`` on a 15 % grade).
With the odometry's integrated tilt (``level_reference="odometry"``) the follower's tilt is its own filter's running
state, which the reference does not reproduce: it is refused there.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams

from .fusion_coupling_share import follower_shared
from .fusion_model import camera_displacement, camera_increment, gated_update
from .fusion_noise import FollowerLimit, FusionNoise
from .fusion_slip import scrub_bias_share
from .viso_ot import VisoOtEstimator

__all__ = [
    "FOLLOWER_SCRUBBING",
    "FOLLOWER_UNKNOWN",
    "CouplingMeasurement",
    "CouplingReference",
    "coupled_update",
    "follower_limited",
    "looks_along",
    "transport_increment",
]

FOLLOWER_SCRUBBING = "follower scrubbing"
"""The reason a frame is refused under (C3)."""
FOLLOWER_UNKNOWN = "follower without an estimate"
"""The reason a frame below the demand is refused under (C3'): the follower's std is not known."""


@dataclass(frozen=True)
class CouplingMeasurement:
    """The lead unit's kingpin increment over one frame from a following unit's camera, (C1)–(C2).

    Attributes
    ----------
    start_tick : int
        The control tick of the frame's start (the follower's previous frame): the filter takes it only where its
        anchor is that tick.
    increment : numpy.ndarray
        ``(dx, dy, dψ)`` [m, m, rad] of the lead's kingpin, in its axes at the frame's start.
    covariance : numpy.ndarray
        Its 3×3 covariance ``R_c``.
    covariance_scale : float
        The ``k_c`` of (C2) it was taken with (1: the covariance as mapped): ``R_c / k_c`` is the reference's own
        per-frame covariance.
    """

    start_tick: int
    increment: np.ndarray
    covariance: np.ndarray
    covariance_scale: float = 1.0


def coupled_update(
    x: np.ndarray, p: np.ndarray, coupling: CouplingMeasurement, gate: float, refuse: bool
) -> tuple[np.ndarray, np.ndarray, float, bool]:
    """The filter's update with a following unit's measurement of ``(Δx, Δy, Δψ)`` ((C1), ``H = [I₃ 0]``), gated as
    the camera's motion (:func:`~sensor.fusion_model.gated_update`): ``(x, p, nis, used)``."""
    h = np.hstack([np.eye(3), np.zeros((3, len(x) - 3))])
    innovation = np.asarray(coupling.increment, dtype=float) - x[:3]
    innovation[2] = math.remainder(innovation[2], 2.0 * math.pi)
    return gated_update(x, p, h, innovation, coupling.covariance, gate, refuse)


def _rotate(angle: float, v: np.ndarray) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def transport_increment(
    increment: Sequence[float],
    rear_couplings: Sequence[float],
    start: Sequence[float],
    end: Sequence[float],
) -> np.ndarray:
    """The lead unit's front-coupling increment ``(dx, dy, dψ)`` from the follower's, (C1) of the module notes.

    Parameters
    ----------
    increment
        The follower's front-coupling increment ``(dx, dy, dψ)`` over the frame, in its axes at the frame's start
        [m, m, rad].
    rear_couplings
        ``x5_i`` [m] of the units from the lead to the one ahead of the follower, front to rear: each one's rear
        coupling station behind its front coupling (negative).
    start, end
        The articulations ``Γ_{j+1} … Γ_m`` [rad] of the couplings from the lead's rear to the follower's front,
        front to rear, at the frame's start and end (one per entry of ``rear_couplings``).

    Returns
    -------
    numpy.ndarray
        ``(dx, dy, dψ)`` of the lead's front coupling, in its axes at the frame's start.
    """
    if not len(rear_couplings) == len(start) == len(end) >= 1:
        raise InputError(
            f"the transport needs one articulation at each end per coupling: {len(rear_couplings)} coupling(s), "
            f"{len(start)} and {len(end)} articulation(s)"
        )
    d = np.array([float(increment[0]), float(increment[1])])
    dpsi = float(increment[2])
    for x5, g0, g1 in zip(reversed(rear_couplings), reversed(start), reversed(end), strict=True):
        r = _rotate(-float(g0), d)
        dpsi = dpsi + float(g1) - float(g0)
        c, s = math.cos(dpsi), math.sin(dpsi)
        d = r - np.array([(c - 1.0) * x5, s * x5])  # (R(Δψ) − I)·(x5, 0)
    return np.array([d[0], d[1], dpsi])


def follower_limited(
    covariance: np.ndarray, limit: FollowerLimit | None, demand: float, follower_std: float
) -> tuple[np.ndarray | None, str | None]:
    """(C3) of the module notes: the reference's covariance ``R_c`` (3×3) for a follower whose scrub demand at the frame
    is ``demand`` and whose off-tracking std is ``follower_std`` [m], and the reason it was refused (``None``: taken).

    Returns ``(R_c, None)`` unchanged without ``limit`` or below its demand; ``(R_c + σ_f²·e_y·e_yᵀ, None)`` for
    ``inflate``; ``(None, FOLLOWER_SCRUBBING)`` for ``refuse``, or where ``follower_std`` is not finite. Below the
    demand with ``limit.below`` ``inflate`` (C3'): widened as ``inflate`` widens, or ``(None, FOLLOWER_UNKNOWN)``
    where ``follower_std`` is not finite."""
    if limit is None or math.isnan(demand):  # NaN: no demand known, taken as (C2) gives it
        return covariance, None
    if not demand >= limit.demand:
        if limit.below == "take":
            return covariance, None
        if not math.isfinite(follower_std):  # (C3')
            return None, FOLLOWER_UNKNOWN
    elif limit.action == "refuse" or not math.isfinite(follower_std):
        return None, FOLLOWER_SCRUBBING
    widened = np.array(covariance, dtype=float)
    widened[1, 1] += follower_std * follower_std
    return widened, None


def looks_along(camera_in_unit: np.ndarray) -> bool:
    """Whether a camera posed ``camera_in_unit`` (4×4, in its unit's frame) looks along its unit (a rear or front rig)
    rather than across it (a side rig): its optical axis's ground-plane part nearer the unit's x axis."""
    axis = np.asarray(camera_in_unit, dtype=float)[:2, 2]
    return bool(abs(axis[1]) <= abs(axis[0]))


class CouplingReference:
    """(C1)–(C2): a following unit's camera motion as a measurement of the lead unit's kingpin increment.

    Parameters
    ----------
    params
        The combination (each unit's rear coupling, the follower's front coupling and camera geometry).
    lead
        The towed unit whose filter takes the measurement (1 the first).
    follower
        The towed unit behind it whose camera moved (``lead < follower``).
    camera_in_follower
        4×4 pose of the follower's left camera in the follower's frame.
    noise
        The covariance scale and floors of the follower's odometry (:func:`~sensor.fusion_model.camera_increment`)
        and ``articulation_noise``.
    level_reference
        How the follower's camera motion is made horizontal, as the lead's filter makes its own: ``planar``
        (default, the level road) or ``accelerometer`` (the follower's tilt at the frame's start and end given to
        :meth:`measurement`; module notes).
    covariance_scale
        ``k_c`` of (C2), the factor on the measurement's covariance (1: as mapped).
    follower_limit
        (C3): the measurement widened or refused while the follower's tyres scrub (``None``: off; :meth:`limited`).
    scrub_scale
        ``k_s`` of (C2'), the covariance widened by ``1 + k_s·D`` at the follower's scrub demand ``D`` (0: off).
    axial_scale
        (C0''): the follower's ``ŝ`` given to :meth:`measurement` taken out along its camera's axis (``False``: off).
    follower_share
        (C4) of :mod:`sensor.fusion_coupling_share`: the lateral variance widened by the follower's off-tracking
        variance in the share of its scrub demand (``False``: off; :meth:`shared`).

    Raises
    ------
    InputError
        ``follower`` not behind ``lead`` within the combination, a unit between them without a rear coupling,
        ``level_reference`` neither ``planar`` nor ``accelerometer``, ``covariance_scale`` not in [1, 100], or
        ``scrub_scale`` not in [0, 100].
    """

    def __init__(
        self,
        params: VehicleParams,
        lead: int,
        follower: int,
        camera_in_follower: np.ndarray,
        noise: FusionNoise,
        level_reference: str = "planar",
        covariance_scale: float = 1.0,
        follower_limit: FollowerLimit | None = None,
        scrub_scale: float = 0.0,
        axial_scale: bool = False,
        follower_share: bool = False,
    ) -> None:
        if not 0.0 <= scrub_scale <= 100.0:  # NaN fails too
            raise InputError(f"scrub_scale = {scrub_scale!r}: allowed 0–100 (k_s of (C2'), a factor per unit of D)")
        if not 1.0 <= covariance_scale <= 100.0:  # NaN fails too
            raise InputError(f"covariance_scale = {covariance_scale!r}: allowed 1–100 (a factor on (C2)'s covariance)")
        if level_reference not in ("planar", "accelerometer"):
            raise InputError(
                f"level_reference = {level_reference!r}: a coupling reference needs 'planar' or 'accelerometer'"
            )
        if not 1 <= lead < follower <= len(params.trailers):
            raise InputError(
                f"a coupling reference needs a follower behind the lead unit within the combination's "
                f"{len(params.trailers)} towed unit(s): lead {lead}, follower {follower}"
            )
        stations = [params.trailers[i - 1].fifth_wheel_x for i in range(lead, follower)]
        if any(x is None for x in stations):
            raise InputError(f"units {lead}–{follower - 1} must each tow the one behind (a rear coupling)")
        self.lead, self.follower = lead, follower
        self.rear_couplings = [float(x) for x in stations if x is not None]
        self.geometry = VisoOtEstimator(params, camera_in_follower, unit=follower, level_reference=level_reference)
        self.noise = noise
        self.covariance_scale = float(covariance_scale)
        self.follower_limit = follower_limit
        self.scrub_scale = float(scrub_scale)
        self.axial_scale = bool(axial_scale)
        self.follower_share = bool(follower_share)
        axis = self.geometry.mount_rotation[:2, 2]  # the follower camera's optical axis in its unit's ground plane
        self.optical_axis = axis / max(float(np.hypot(*axis)), 1e-12)

    def limited(
        self, covariance: np.ndarray, demand: float, follower_std: float
    ) -> tuple[np.ndarray | None, str | None]:
        """(C3) with this reference's ``follower_limit`` (:func:`follower_limited`)."""
        return follower_limited(covariance, self.follower_limit, demand, follower_std)

    def shared(self, covariance: np.ndarray, demand: float, follower_std: float) -> np.ndarray:
        """(C4) with this reference's ``follower_share`` (:func:`~sensor.fusion_coupling_share.follower_shared`);
        ``covariance`` itself where it is off."""
        return follower_shared(covariance, demand, follower_std) if self.follower_share else covariance

    def articulations(self, articulations: Sequence[float]) -> tuple[float, ...]:
        """The articulations (C1) takes, ``Γ_{j+1} … Γ_m``, out of every coupling's from the tractor back
        (:attr:`~sensor.unit_kinematics.ChainSignals.articulations`, ``Γ_1`` first)."""
        if len(articulations) < self.follower:
            raise InputError(f"the coupling reference needs {self.follower} articulations, got {len(articulations)}")
        return tuple(float(g) for g in articulations[self.lead : self.follower])

    def measurement(
        self,
        camera_motion: np.ndarray,
        covariance: np.ndarray | None,
        start: Sequence[float],
        end: Sequence[float],
        yaw_bias: tuple[float, ...] | None = None,
        tilts: tuple[tuple[float, float], tuple[float, float]] | None = None,
        axial: tuple[float, float] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The lead's kingpin increment ``z`` and its 3×3 covariance ``R_c`` (C1)–(C2) from one follower camera
        motion (as :meth:`~sensor.fusion.FusedVisoOt.measure` takes it, with its 6×6 odometry covariance or
        ``None``) and the articulations ``Γ_{j+1} … Γ_m`` at the frame's start and end (:meth:`articulations`);
        ``yaw_bias``: the follower's odometry yaw error ``β̂_ψ`` [rad/m] and its variance as its own filter
        estimates them, and optionally its scrub demand ``D`` at its last frame (0 when not given), taken out by (C0)
        (``None``: none). ``tilts``: the follower's (pitch, roll) [rad] at the
        frame's start and end, required with ``level_reference="accelerometer"`` (the increment is then the lead's
        in its level frame, module notes) and refused without it. ``axial``: the follower's ``ŝ`` (its filter's
        ``s_z``) and its variance ``P_s``, taken out by (C0'') where :attr:`axial_scale` is on (``None``: none)."""
        tilt = None
        demand = 0.0
        if self.geometry.level_reference == "planar":
            if tilts is not None:
                raise InputError(f"tilts = {tilts!r} given with level_reference = 'planar'; allowed: None")
        else:
            if tilts is None or len(tilts) != 2:
                raise InputError(f"tilts = {tilts!r}: level_reference 'accelerometer' needs the start and end tilts")
            start_tilt = self.geometry.given_tilt(tilts[0])
            tilt = self.geometry.given_tilt(tilts[1])
            self.geometry.tilt = start_tilt  # the follower's level frame at the frame's start, as its filter holds it
        follower, r_follower = camera_increment(
            self.geometry, self.noise, np.asarray(camera_motion, dtype=float), covariance, tilt
        )
        if yaw_bias is not None and all(math.isfinite(v) for v in yaw_bias):  # (C0)
            if not 2 <= len(yaw_bias) <= 3 or (len(yaw_bias) == 3 and not 0.0 <= yaw_bias[2] <= 1.0):
                raise InputError(f"yaw_bias = {yaw_bias!r}: allowed (β̂_ψ, P_β) or (β̂_ψ, P_β, D) with D in [0, 1]")
            g = np.array([*(self.noise.vo_bias_coupling * r_follower[:2, 2] / r_follower[2, 2]), 1.0])
            demand = float(yaw_bias[2]) if len(yaw_bias) == 3 else 0.0
            if demand > 0.0:  # (K5)–(K6): the share of β̂_ψ the follower's filter took this motion with
                g[:2] *= 1.0 - demand
                g *= scrub_bias_share(self.noise, demand)
            d = float(follower[0])
            follower = follower - d * yaw_bias[0] * g
            r_follower = r_follower + d * d * yaw_bias[1] * np.outer(g, g)
        if self.axial_scale and axial is not None:
            follower, r_follower = self._axial(follower, r_follower, axial)
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        z = transport_increment(follower, self.rear_couplings, start, end)
        n = len(start)
        jac = np.empty((3, 3 + 2 * n))  # ∂z/∂(follower increment, Γ⁰, Γ¹), numerically
        h = 1e-7
        for i in range(3 + 2 * n):
            args = np.concatenate([follower, start, end])
            args[i] += h
            moved = transport_increment(args[:3], self.rear_couplings, args[3 : 3 + n], args[3 + n :])
            jac[:, i] = (moved - z) / h
        j_d, j_g = jac[:, :3], jac[:, 3:]
        r = j_d @ r_follower @ j_d.T + self.noise.articulation_noise**2 * (j_g @ j_g.T)  # (C2)
        if self.covariance_scale != 1.0:  # k_c of (C2)
            r = self.covariance_scale * r
        if self.scrub_scale > 0.0 and demand > 0.0:  # (C2') of the module notes
            r = (1.0 + self.scrub_scale * demand) * r
        return z, 0.5 * (r + r.T)

    def _axial(
        self, follower: np.ndarray, r_follower: np.ndarray, axial: tuple[float, float]
    ) -> tuple[np.ndarray, np.ndarray]:
        """(C0'') of the module notes: the follower's increment less its along-axis error ``ŝ`` and its covariance
        plus ``P_s`` along the axis."""
        if len(axial) != 2 or not (-1.0 < axial[0] < 1.0 and 0.0 <= axial[1] < math.inf):  # NaN fails too
            raise InputError(f"axial = {axial!r}: allowed (ŝ, P_s) with ŝ in (−1, 1) and P_s finite, at least 0")
        s, variance = float(axial[0]), float(axial[1])
        o = self.optical_axis
        along = camera_displacement(follower, self.geometry.camera_position, o)[0]  # a(f) = (1 + s_z)·a(Δ)
        corrected = np.array(follower, dtype=float)
        corrected[:2] -= s / (1.0 + s) * along * o  # (C0'')
        g = np.array([*(-along / (1.0 + s) ** 2 * o), 0.0])  # ∂f/∂s_z = −d/(1 + ŝ)·o, d = a(f)/(1 + ŝ)
        return corrected, r_follower + variance * np.outer(g, g)
