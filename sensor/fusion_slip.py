"""The zero-slip measurement's noise in the fused VISO-OT filter: the evidence of slip, (K2)–(K4).

(K1) of :mod:`sensor.fusion_model` measures the kingpin's slip velocity ``v_s`` up to ``ε_k``, the slip of the
tractor's own tyres. It is a slowly varying error (a steady slip in a steady turn), not
white: with a correlation time ``τ_c`` (``kinematic_error_time``) a measurement at every tick ``dt`` carries the
information of one every ``τ_c``, so it is applied with the variance ``σ_k²·τ_c/dt``. Its standard deviation σ_k
follows the evidence of slip, the disagreement between the camera and the kinematics: each camera frame's lateral
kingpin motion (less the odometry's estimated systematic error) against the kinematics' over the same interval
(Cheng's lateral velocity with the gyro's heading), as a velocity ``δv``. Its exponentially weighted mean over
``τ_a`` (``slip_evidence_time``) and the variance that mean would have from the frames' own noise alone give::

    m_k = m_{k−1} + α·(δv_k − m_{k−1}),   α = Δt_frame/τ_a,
    σ_k² = max(σ_0² + (u_C·v_m)², m_k² − V_k·α/(2 − α))                                          (K2)

(``V_k`` the same weighted mean of the frames' lateral variance over Δt²; ``σ_0`` = ``tractor_slip``: the slip of
rolling tyres; ``v_m`` the rear slip velocity the compensated rear points predict, ``K·u_1²·r_1`` or
``K·u_1·f_y``, uncertain by the cornering stiffnesses' relative ``u_C`` = ``tractor_stiffness_uncertainty``).
A persistent disagreement is slip, noise is not (innovation-based adaptive estimation: Mehra 1972; Mohamed &
Schwarz 1999). A slip that changes sign — a change of turn on ice, where the tractor's tyres slip the other way —
takes ``m_k`` through zero, and (K2) would trust the kinematics just as their error flips; with
``slip_evidence_hold`` the evidence falls no faster than it would had the slip stopped (a mean decaying by
``1 − α`` a frame, its square by ``(1 − α)²``)::

    e_k = max(m_k² − V_k·α/(2 − α), (1 − α)²·e_{k−1}),   σ_k² = max(σ_0² + (u_C·v_m)², e_k)           (K2')

A trailer whose own tyres slip sideways — its axles steered hard towards their lock, scrubbing — carries a lateral
force that the kingpin passes to the tractor's rear, so the tractor's rear tyres slip with it and (K1) errs in
proportion to the trailer's slip ``v_s``; that error may lie below what the disagreement can tell from the camera's
noise. With ``trailer_push_share`` ``u_p`` > 0 the estimated slip itself is that evidence::

    σ_k² = max(σ_0² + (u_C·v_m)², e_k, (u_p·v_s)²)                                                 (K4)

(off by default: ``u_p`` = 0).

On a dry road the disagreement stays within the noise, σ_k stays at σ_0 and the
kinematics share the estimate with the camera; where the camera sees slip — ice, a cambered road — σ_k follows the
slip within ``τ_a`` and the camera carries the estimate. σ_k is recorded (:attr:`FusedVisoOt.kinematic_std`): the
run says which source it trusted.

With ``kinematic_error_model: state`` the correlated error is not inflated white noise but an eighth state, the
shaping filter of a time-correlated measurement error (state augmentation: Bryson & Henrikson 1968): a first-order
Gauss–Markov process with the correlation time ``τ_c`` and the standard deviation σ_k of (K2), and (K1) carries only
the white noise ``σ_w`` (``kinematic_white_noise``) of the tractor's sensors and, as in the inflated model, the
evidence of slip beyond its floor ``σ_f² = σ_0² + (u_C·v_m)²``::

    ε_k ← φ·ε_k + w,   φ = exp(−dt/τ_c),   E[w²] = σ_k²·(1 − φ²)
    (K1) = v_s + ε_k + n,   E[n²] = σ_w² + (σ_k² − σ_f²)·τ_c/dt                                    (K3)

The camera measures the kingpin's motion, so ε_k is observed through the difference: the filter learns the
kinematics' steady error (the sensors' offsets, the linear tyre model's residual, a steady crab) from the camera,
and where the disagreement says nothing slips the kinematics carry what changes faster than that; where it says the
tyres slip, the white part de-weights the kinematics at once, before the state has learned the new error (a
figure-of-eight's change of turn on ice; docs/field_bias.md §6.5).

The trailer's own tyres at their limit. Eq (1) holds while every axle of the unit works in its tyres' linear
range. An axle steered towards its lock, or a fixed axle ahead of steered ones in a tight turn, runs at a slip
angle far beyond it: the tyres scrub, carry less force than the linear model says, and the trailer's slip velocity
changes faster than ``v_s``'s random walk allows; the mount and the odometry then see a turn the free-rolling
turns the coupling ``κ`` of eq (3) was measured on do not resemble. The filter sees this from its own signals:
with its estimated rates and slip velocity the kingpin moves at ``(u, v_k)`` of eq (1), so axle ``j`` (steer
``δ_j``, zero for a fixed one) runs at the slip angle::

    α_j = δ_j − atan((v_k − r·L_j) / |u|),    D = clip(max_j |α_j − Σ_i c_i α_i| / α_s − 1, 0, 1)    (K5)

the *scrub demand* ``D`` (``c_i = C_i / Σ C`` the axles' stiffness shares, ``α_s`` = ``scrub_slip_angle``, the
linear range's end; ``|u|`` held to at least 1 m/s, where a slip angle says little). It is the axles' disagreement
about where the unit goes, not their common slip: a trailer sliding sideways on ice has every axle at the same slip
angle, which ``v_s`` and (K2) already carry, and no demand. With ``D`` > 0 the slip velocity's random walk widens by
``D·scrub_slip_walk``, and eq (3)'s coupling gives way to its uncertainty: the motion is taken with ``(1 − D)·κ``
and the off-tracking's std carries the whole coupled correction as uncertain in proportion, eq (5)'s coupling term
``β_ψ·G_κ·√((u_κ·(1 − D))² + D²)`` with ``G_κ`` at the full ``κ`` (:mod:`sensor.fusion_std`; otherwise with (K6)
and (K7) below). A free-rolling unit
in an ordinary turn has slip angles of a degree or two and no demand.

The odometry's systematic error released. While the tyres scrub the camera's motions disagree with the gyro in a way
the odometry's slowly wandering yaw error ``β_ψ`` of eq (3) does not describe, and the filter, finding the
disagreement cheapest to explain by ``β_ψ``, moves it and carries the wrong ``β_ψ`` into the path (and, through its
coupled correction, into the std's coupling term). With ``scrub_bias_release`` ``r`` > 0 the frame's motion is
taken with ``(1 − r·D)`` of the state's ``β_ψ`` — its yaw and its coupled translation alike — so the camera's
turn goes to the heading and ``β_ψ`` learns from the scrub only the ``1 − r·D`` it is still taken with (nothing at
``r`` = 1); with ``scrub_coupling_std`` ``release`` (the default is (K7), below) the std's coupling term carries
the demand's share less by ``r``, ``√((u_κ·(1 − D))² + ((1 − r)·D)²)`` of ``β_ψ·G_κ``::

    H_ψ,β = (1 − r·D)·d,   H_xy,β = (1 − r·D)·d·(1 − D)·κ·(c_x, c_y)                             (K6)

With ``r`` = 0 (the default) the filter is that of (K5) alone; with ``D`` = 0 it is the filter without either.

The coupled correction in the std, ``scrub_coupling_std`` ``uniform``. Of the coupled correction ``β_ψ·G_κ``
(``G_κ`` at the full ``κ``, :mod:`sensor.fusion_std`) a frame taken at the demand ``D`` applies the share
``a = (1 − r·D)·(1 − D)``; how much of it is real, ``k``, the filter cannot tell while the tyres scrub: where
the coupling of eq (3) holds through the scrub (the odometry's error is its geometry's, and ``β_ψ``, held by (K6),
is the one learnt rolling) all of it (``k`` = 1), where the scrubbing turn is not one the coupling was measured
on (docs/field_bias.md §6.8) none. Rolling, ``k`` is 1 known to ``u_κ``; scrubbing, nothing favours any share
between, so ``k`` is taken uniform on [0, 1] (the least informed law on that range). With weights ``1 − D`` and
``D`` the coupling term of eq (5) is the RMS of ``(k − a)·β_ψ·G_κ``::

    σ_κ² = (β_ψ·G_κ)²·((1 − D̄)·((1 − a)² + u_κ²) + D̄·(a² − a + 1/3)),   a = (1 − r·D̄)·(1 − D̄)          (K7)

``D̄`` the demand over the path the std covers: the demands the increments ahead of the follow point (and the
current one) were taken at, weighted by their shares of ``G_κ``, so that the term outlives the demand while the
path still holds what the scrub left out. With ``D̄`` = 0 it is eq (5)'s ``u_κ·β_ψ·G_κ``; at ``D̄`` = 1 it is
``β_ψ·G_κ/√3``, and at every demand twice it is at least the share left out, ``1 − a``, plus ``u_κ``. The term is
larger than ``release``'s wherever the demand is, so the std more often exceeds what a controller that drops an
uncertain estimate accepts (docs/field_bias.md §6.12).
"""

from __future__ import annotations

import math

import numpy as np

from .fusion_model import BG, BW, EK, VS, StateLayout
from .fusion_noise import FusionNoise

__all__ = [
    "ScrubDemand",
    "SlipEvidence",
    "ZeroSlipNoise",
    "coupling_correction_std",
    "kinematic_disagreement",
    "kinematic_floor",
    "kinematic_lateral_step",
    "push_variance",
    "scrub_bias_share",
    "scrub_coupling_applied",
    "scrub_coupling_share",
    "scrub_coupling_yield",
]


def kinematic_floor(noise: FusionNoise, modelled_slip: float) -> float:
    """σ_k²'s floor of (K2), ``σ_0² + (u_C·v_m)²``, with the modelled rear slip ``v_m`` [m/s] → [m²/s²]."""
    modelled = noise.tractor_stiffness_uncertainty * modelled_slip
    return noise.tractor_slip**2 + modelled * modelled


def scrub_bias_share(noise: FusionNoise, demand: float) -> float:
    """(K6): the share ``1 − r·D`` of the odometry's estimated systematic error ``β_ψ`` a frame's motion is taken with
    at the scrub demand ``demand`` (1 without a demand or a release)."""
    return 1.0 - noise.scrub_bias_release * demand


def scrub_coupling_yield(noise: FusionNoise, demand: float) -> float:
    """(K5): the factor ``1 − D`` a frame's coupled translation ``κ·(c_x, c_y)`` of eq (3) is taken with at the scrub
    demand ``demand``; 1 without a demand, and 1 with ``noise.scrub_coupling_kept`` (the coupling kept while the
    tyres scrub, so that only (K6) acts on it)."""
    return 1.0 if noise.scrub_coupling_kept or demand <= 0.0 else 1.0 - demand


def scrub_coupling_applied(noise: FusionNoise, demand: float) -> float:
    """(K5)–(K6): the share ``a = (1 − r·D)·(1 − D)`` of the coupled correction ``β_ψ·G_κ`` a frame's motion is
    taken with at the scrub demand ``demand`` (1 without a demand; ``1 − r·D`` with the coupling kept,
    :func:`scrub_coupling_yield`)."""
    return scrub_bias_share(noise, demand) * scrub_coupling_yield(noise, demand)


def scrub_coupling_share(noise: FusionNoise, demand: float) -> float:
    """The share of the coupled correction ``β_ψ·G_κ`` the std's coupling term carries at the scrub demand
    ``demand`` (``u_κ`` without a demand). ``noise.scrub_coupling_std`` ``release``: ``√((u_κ·(1 − D))² +
    ((1 − r)·D)²)`` of (K5)–(K6); ``uniform``: (K7), the RMS of ``k − a`` with ``a`` the share applied
    (:func:`scrub_coupling_applied`) and the true share ``k`` at ``1 ± u_κ`` with weight ``1 − D`` and uniform on
    [0, 1] with weight ``D``."""
    u = noise.vo_bias_coupling_uncertainty
    if noise.scrub_coupling_std == "release":
        return math.hypot(u * (1.0 - demand), (1.0 - noise.scrub_bias_release) * demand)
    applied = scrub_coupling_applied(noise, demand)
    rolling = (1.0 - applied) ** 2 + u * u  # the coupling holds, known to u_κ
    unknown = applied * applied - applied + 1.0 / 3.0  # E[(k − a)²] for k uniform on [0, 1]
    return math.sqrt((1.0 - demand) * rolling + demand * unknown)


def push_variance(noise: FusionNoise, slip_velocity: float) -> float:
    """(K4): ``(u_p·v_s)²``, the tractor's rear slip a trailer slipping at ``v_s`` [m/s] pushes it into [m²/s²]."""
    push = noise.trailer_push_share * float(slip_velocity)
    return push * push


def kinematic_disagreement(
    noise: FusionNoise, evidence: float, slip_velocity: float, share: float, lever: float
) -> float:
    """Eq (5)'s kinematics term ``s_k·m_k·Λ`` [m]: the disagreement the kinematics' share ``share`` carries into the
    slip velocity, coherent over the window of lateral lever ``lever`` [m·s/m]; ``evidence`` ``e_k`` of (K2) [m²/s²],
    at least the push (K4) a trailer slipping at ``slip_velocity`` [m/s] hides from the kinematics."""
    evidence = max(evidence, 0.0)
    if noise.trailer_push_share > 0.0:  # (K4): the kinematics may err by the push they cannot see
        evidence = max(evidence, push_variance(noise, slip_velocity))
    return share * math.sqrt(evidence) * lever


def coupling_correction_std(
    noise: FusionNoise, bias: float, lever: float, path_demand: float, frame_demand: float
) -> float:
    """Eq (5)'s coupling term ``u_κ·β_ψ·G_κ`` [m]: the coupling is known to ``vo_bias_coupling_uncertainty``, so is the
    correction it applies for the odometry's yaw error ``bias`` (``β_ψ``) through the lever ``lever`` (``G_κ``).
    Taken in part while the tyres scrubbed ((K5)–(K7)), the share of it that is unknown
    (:func:`scrub_coupling_share`) at the frame's demand ``frame_demand``, or with ``scrub_coupling_std: uniform``
    at the demand over the path ``path_demand``."""
    demand = path_demand if noise.scrub_coupling_std == "uniform" else frame_demand
    share = scrub_coupling_share(noise, demand) if demand > 0.0 else noise.vo_bias_coupling_uncertainty
    return share * bias * lever


class SlipEvidence:
    """(K2) and (K2'): the camera's lateral kingpin motion against the kinematics', frame by frame.

    Attributes
    ----------
    evidence : float
        ``e_k`` (``m_k² − V_k·α/(2 − α)``, held by (K2') when on) [m²/s²].
    mean, expected : float
        ``m_k`` [m/s] and ``V_k`` [m²/s²] (NaN before the first frame).
    frame_interval : float
        The last frame's interval [s] (0 before the first).
    """

    def __init__(self, noise: FusionNoise) -> None:
        self.noise = noise
        self.reset()

    def reset(self) -> None:
        """Forget the evidence."""
        self.mean = math.nan
        self.expected = math.nan
        self.evidence = 0.0
        self.frame_interval = 0.0

    def weigh(self, disagreement: float, lateral_variance: float, interval: float) -> None:
        """One frame: the camera's lateral motion less the kinematics' over ``interval`` [s] (``disagreement`` [m]),
        with the camera's lateral variance [m²]."""
        if interval <= 0.0:
            return
        self.frame_interval = interval
        alpha = min(1.0, interval / self.noise.slip_evidence_time)
        velocity, expected = disagreement / interval, lateral_variance / interval**2
        if math.isnan(self.mean):
            self.mean, self.expected = velocity, expected
        else:
            self.mean += alpha * (velocity - self.mean)
            self.expected += alpha * (expected - self.expected)
        # the mean's own variance, had the innovations been white: α/(2 − α) of theirs
        evidence = max(0.0, self.mean**2 - self.expected * alpha / (2.0 - alpha))
        if self.noise.slip_evidence_hold:  # (K2'): no faster down than a slip that stopped
            evidence = max(evidence, (1.0 - alpha) ** 2 * self.evidence)
        self.evidence = evidence


class ZeroSlipNoise:
    """The zero-slip measurement (K1) as the filter applies it, with σ_k from (K2)–(K4).

    Parameters
    ----------
    noise
        The filter's noise model.
    layout
        The state layout (``ε_k`` a state or not).
    slip_point
        ``L_c`` of eq (1) [m].

    Attributes
    ----------
    evidence : SlipEvidence
        (K2)'s disagreement of the camera with the kinematics.
    modelled_slip : float
        ``v_m`` of (K2), the rear slip the compensated rear points predict [m/s].
    residual_variance : float
        ``σ_m²`` of (T3) (:mod:`sensor.unit_slip_reference`): the unit's own reference's linear-tyre residual,
        added to the floor [m²/s²] (0: none).
    rate_sensitivity : tuple of float or None
        ``(∂z/∂r_m, ∂z/∂w_m)`` of (K1) with the unit's own reference: its ``z_c`` is formed from the unit's own
        measured rates, so their biases cancel out of eq (1)'s terms and enter through (T2)'s slip alone
        (:meth:`sensor.fusion_reference.OwnReference.rate_sensitivity`); ``None``: the tractor's kinematics, whose
        ``z_c`` carries no bias of the unit's rates, so they enter through eq (1).
    kinematic_std : float
        σ_k at the last measurement [m/s] (NaN before the first).
    kinematic_share : float
        The share of the lateral information the kinematics carry against the camera's (eq (5)).
    """

    def __init__(self, noise: FusionNoise, layout: StateLayout, slip_point: float) -> None:
        self.noise = noise
        self.layout = layout
        self.slip_point = slip_point
        self.evidence = SlipEvidence(noise)
        self.reset()

    def reset(self) -> None:
        """Forget the evidence and the modelled slip."""
        self.evidence.reset()
        self.modelled_slip = 0.0
        self.residual_variance = 0.0
        self.rate_sensitivity: tuple[float, float] | None = None
        self.kinematic_std = math.nan
        self.kinematic_share = 0.0

    def floor(self) -> float:
        """σ_k²'s floor of (K2), ``σ_0² + (u_C·v_m)²``, and (T3)'s ``σ_m²`` [m²/s²]."""
        return kinematic_floor(self.noise, self.modelled_slip) + self.residual_variance

    def variance(self, x: np.ndarray) -> float:
        """σ_k² of (K2): the slip evidence so far, at least its floor and (K4)'s push of the state ``x`` [m²/s²]."""
        return max(self.floor(), self.evidence.evidence, push_variance(self.noise, float(x[VS])))  # (K2), (K4)

    def rows(
        self, sample: tuple[float, float, float], lateral: float, dt: float, x: np.ndarray
    ) -> tuple[tuple[np.ndarray, float, float], ...]:
        """(K1) of one tick as an ``(H, z, R)`` row, from the tick's ``sample`` ``(r_m, w_m, Σ w_j tan δ_j)``, the
        kingpin's lateral velocity had no tractor tyre slipped ``lateral`` [m/s], the period ``dt`` [s] and the
        predicted state ``x``."""
        r_m, w_m, tan_steer = sample
        h = np.zeros(self.layout.size)
        h[VS] = 1.0
        h[BG] = -self.slip_point  # (K1) is taken with the measured rates: their biases enter it through (1)
        h[BW] = -tan_steer
        if self.rate_sensitivity is not None:  # the own reference's z_c has the same rates: through (T2) alone
            h[BG], h[BW] = self.rate_sensitivity  # z = v̂_s(r + b_g, u + b_w), docs/field_bias.md §7.32
        z = lateral - (r_m * self.slip_point + w_m * tan_steer)  # (K1): the slip velocity the tractor implies
        n = self.noise
        variance = self.variance(x)
        self.kinematic_std = math.sqrt(variance)
        if self.layout.error_state:  # (K3): ε_k is a state, the tick's own noise white
            h[EK] = 1.0
            # the evidence of slip beyond the floor also as (K2)'s correlated white error: seen slip de-weights the
            # kinematics at once, while the state learns their steady error
            excess = (variance - self.floor()) * n.kinematic_error_time / max(dt, 1e-6)
            return ((h, z, n.kinematic_white_noise**2 + excess),)
        evidence = self.evidence
        if math.isfinite(evidence.expected) and evidence.frame_interval > 0.0:  # information per second, eq (5)
            camera = 1.0 / (evidence.expected * evidence.frame_interval)
            self.kinematic_share = (1.0 / (variance * n.kinematic_error_time)) / (
                1.0 / (variance * n.kinematic_error_time) + camera
            )
        return ((h, z, variance * n.kinematic_error_time / max(dt, 1e-6)),)  # a time-correlated error


class ScrubDemand:
    """(K5): the scrub demand ``D`` of a unit's axles from its own signals and the filter's state.

    Parameters
    ----------
    noise
        The filter's noise model (``scrub_slip_angle`` ``α_s``; 0: ``D`` is always 0).
    distances
        ``L_j`` of every axle of the unit behind its front coupling [m].
    steerable
        Which axles are steerable (the measured steer angles are theirs, in order).
    shares
        Every axle's share ``c_j`` of the unit's cornering stiffness.
    slip_point, steer_weights
        ``L_c`` and ``w_j`` of eq (1).
    """

    MIN_SPEED = 1.0
    """The least ``|u|`` [m/s] a slip angle is taken at."""

    def __init__(
        self,
        noise: FusionNoise,
        distances: np.ndarray,
        steerable: np.ndarray,
        shares: np.ndarray,
        slip_point: float,
        steer_weights: np.ndarray,
    ) -> None:
        self.onset = noise.scrub_slip_angle
        self.distances = np.asarray(distances, dtype=float)
        self.steerable = np.asarray(steerable, dtype=bool)
        self.shares = np.asarray(shares, dtype=float)
        self.slip_point = slip_point
        self.steer_weights = np.asarray(steer_weights, dtype=float)

    def __call__(self, yaw_rate: float, speed: float, steer: np.ndarray | None, slip_velocity: float) -> float:
        """``D`` of (K5) for the unit's yaw rate [rad/s] and speed [m/s] (biases removed), its measured steer [rad]
        (``None``: none) and the slip velocity ``v_s`` [m/s]."""
        if self.onset <= 0.0:
            return 0.0
        delta = np.zeros(self.distances.size)
        tan_steer = 0.0
        if steer is not None and self.steer_weights.size:
            angles = np.asarray(steer, dtype=float).reshape(-1)
            delta[self.steerable] = angles
            tan_steer = float(np.dot(self.steer_weights, np.tan(angles)))
        lateral = yaw_rate * self.slip_point + speed * tan_steer + slip_velocity  # eq (1)
        alpha = delta - np.arctan((lateral - yaw_rate * self.distances) / max(abs(speed), self.MIN_SPEED))
        spread = alpha - float(np.dot(self.shares, alpha))  # less the common slip
        return float(np.clip(np.max(np.abs(spread)) / self.onset - 1.0, 0.0, 1.0))


def kinematic_lateral_step(ticks: list[tuple[tuple[float, ...], float]], x: np.ndarray) -> float | None:
    """(K2)'s kinematic side: the kingpin's lateral displacement over ``ticks`` (each its inputs ``(dt, r_m, w_m,
    …)`` and the kingpin's lateral velocity had no tractor tyre slipped) in the frame of their start, with the
    biases of the state ``x``: Cheng's lateral velocity with the trailer's speed and the gyro (``None``: no tractor
    signals on some tick)."""
    heading = y = 0.0
    for inputs, tractor_lateral in ticks:
        dt, r_m, w_m = inputs[0], inputs[1], inputs[2]
        if math.isnan(tractor_lateral):
            return None
        mid = heading + 0.5 * (r_m - x[BG]) * dt
        y += (math.sin(mid) * (w_m - x[BW]) + math.cos(mid) * tractor_lateral) * dt
        heading += (r_m - x[BG]) * dt
    return y
