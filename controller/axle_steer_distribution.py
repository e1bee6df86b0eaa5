"""Trailer axle steer geometry: virtual-axle angle to per-axle angles, steady-turn steer, kingpin direction, limits.

Virtual axle and distribution
-----------------------------
The trailer is controlled as if it had one steered axle at ``L_v`` behind the kingpin (default: the
equivalent wheelbase ``L_eq = ΣC_j L_j²/ΣC_j L_j`` of all trailer axles, so ``δ_v = 0`` behaves like the
unsteered trailer). For a given ``δ_v`` and kingpin velocity the zero-slip trailer turns about the centre
where the virtual axle's axis meets the normal to the kingpin velocity; its curvature abreast of the trailer
is ``κ_c = 1/y_c = (tan β_k − tan δ_v)/L_v`` (docs/vehicle_dynamics.md §2.3: ``r2 = (v_k2y − v_k2x tan δ_v)/L_v`` and
``y_c = v_k2x/r2``), with ``tan β_k = v_k2y/v_k2x`` the direction of the kingpin velocity in the trailer
frame. Every steerable axle is steered to that centre (docs/vehicle_dynamics.md §7.3, exact form)::

    tan δ_j = tan δ_v + (L_v − L_j)·κ_c

*Fixed axles.* An unsteerable axle cannot point at the centre unless it lies abreast of it; it then slips
by ``α_f = −atan(t_f)`` (``t_f`` the tangent it would need) and its force turns the trailer about another
centre. With ``fixed_axle_compensation`` the steerable axles get a common extra angle ``Δ`` chosen so that
the low-speed yaw-moment balance about the kingpin, ``Σ C_j L_j α_j = 0`` (linear tyres, negligible trailer
inertia), again puts the centre where ``δ_v`` says: ``Δ = Σ_fixed C_f L_f atan(t_f) / Σ_steered C_s L_s``.
With every axle steerable ``Δ = 0`` and the distribution is the exact kinematic one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams

__all__ = [
    "AxleSteerDistribution",
    "axle_velocity_directions",
    "limit_axle_commands",
    "path_following_steer",
    "slip_angle_window",
    "steady_turn_tangents",
    "tan_kingpin_direction",
]


@dataclass(frozen=True)
class AxleSteerDistribution:
    """Steer of every steerable trailer axle from the virtual-axle angle (:mod:`controller.path_following`).

    Parameters
    ----------
    distances : numpy.ndarray
        ``L_j`` of every trailer axle behind the kingpin [m], trailer layout order.
    steerable : numpy.ndarray
        Boolean mask of the steerable trailer axles.
    stiffness : numpy.ndarray
        Cornering stiffness of every trailer axle at its static load [N/rad].
    virtual_axle_distance : float
        ``L_v`` [m].
    fixed_axle_compensation : bool
        Cancel the yaw moment of the unsteerable axles.
    """

    distances: np.ndarray
    steerable: np.ndarray
    stiffness: np.ndarray
    virtual_axle_distance: float
    fixed_axle_compensation: bool = True
    _weights: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not np.any(self.steerable):
            raise InputError("AxleSteerDistribution needs at least one steerable trailer axle")
        cl = self.stiffness * self.distances
        # Δ = Σ_fixed C_f L_f atan(t_f) / Σ_steered C_s L_s (low-speed yaw-moment balance about the kingpin).
        weights = np.where(self.steerable, 0.0, cl) / float(np.sum(cl[self.steerable]))
        object.__setattr__(self, "_weights", weights if self.fixed_axle_compensation else np.zeros_like(cl))

    @classmethod
    def for_vehicle(
        cls,
        params: VehicleParams,
        virtual_axle_distance: float | None = None,
        fixed_axle_compensation: bool = True,
        unit: int = 1,
    ) -> AxleSteerDistribution:
        """Distribution for a towed unit of ``params`` (``unit``: 1 the first; ``L_v`` defaults to the unit's
        equivalent wheelbase)."""
        table = params.axle_table
        trailer = table.unit == unit
        stiffness = params.axle_cornering_stiffness()[trailer]
        lv = params.equivalent_wheelbase(unit=unit) if virtual_axle_distance is None else float(virtual_axle_distance)
        return cls(
            distances=params.trailer_axle_distances(unit),
            steerable=np.asarray(table.steerable[trailer], dtype=bool),
            stiffness=stiffness,
            virtual_axle_distance=lv,
            fixed_axle_compensation=fixed_axle_compensation,
        )

    def centre_curvature(self, tan_virtual: float, tan_kingpin: float) -> float:
        """``κ_c = 1/y_c = (tan β_k − tan δ_v)/L_v`` [1/m] of the centre implied by ``δ_v``.

        Zero-slip kinematics of docs/vehicle_dynamics.md §2.3.
        """
        return (tan_kingpin - tan_virtual) / self.virtual_axle_distance

    def __call__(self, tan_virtual: float, tan_kingpin: float) -> np.ndarray:
        """Steer angles [rad] of the steerable axles, trailer layout order.

        Parameters
        ----------
        tan_virtual
            ``tan δ_v`` of the virtual axle.
        tan_kingpin
            ``tan β_k = v_k2y/v_k2x``: direction of the kingpin velocity in the trailer frame.
        """
        kappa_c = self.centre_curvature(tan_virtual, tan_kingpin)
        # docs/vehicle_dynamics.md §7.3: tan δ_j = tan δ_v + (L_v − L_j)·κ_c for every axle (what each would need)
        needed = np.arctan(tan_virtual + (self.virtual_axle_distance - self.distances) * kappa_c)
        offset = float(self._weights @ needed)
        return needed[self.steerable] + offset


def path_following_steer(
    distribution: AxleSteerDistribution, kingpin_curvature: float, follow_point_offset: float
) -> tuple[float, np.ndarray]:
    """Steady zero-slip path-following steer: virtual angle and axle angles (docs/vehicle_dynamics.md §6.2).

    Parameters
    ----------
    distribution
        Axle distribution (gives ``L_v`` and the axles).
    kingpin_curvature
        ``κ5`` [1/m], positive in a left turn.
    follow_point_offset
        ``L_fp`` [m].

    Returns
    -------
    tuple
        ``(δ_ff, δ_j)`` [rad]: the virtual-axle angle and the steerable axles' angles in a steady turn, the
        kingpin moving at ``tan β_k = (L_fp/2)/y_c``.
    """
    tan_ff, tan_kingpin = steady_turn_tangents(
        kingpin_curvature, follow_point_offset, distribution.virtual_axle_distance
    )
    return math.atan(tan_ff), distribution(tan_ff, tan_kingpin)


def steady_turn_tangents(kappa: float, l_fp: float, l_v: float) -> tuple[float, float]:
    """``(tan δ_ff, tan β_k)`` of the steady path-following turn of kingpin curvature ``kappa``.

    ``tan δ_ff = (L_fp/2 − L_v)/y_c`` and ``tan β_k = (L_fp/2)/y_c`` with ``1/y_c = κ5/sqrt(1 − κ5²L_fp²/4)``
    (docs/vehicle_dynamics.md §6.2, exact form).

    Parameters
    ----------
    kappa
        Kingpin curvature ``κ5`` [1/m], positive in a left turn.
    l_fp
        Follow-point offset ``L_fp`` [m].
    l_v
        Virtual-axle distance ``L_v`` [m].

    Returns
    -------
    tuple of float
        ``(tan δ_ff, tan β_k)``: the virtual axle's steady steer and the kingpin velocity direction in the trailer
        frame.
    """
    half = 0.5 * l_fp
    # κ/sqrt(1 − κ²L_fp²/4) = 1/y_c; clipped where the follow point cannot reach the circle (R5 ≤ L_fp/2).
    q = min((kappa * half) ** 2, 0.99)
    inv_yc = kappa / math.sqrt(1.0 - q)
    return (half - l_v) * inv_yc, half * inv_yc


def tan_kingpin_direction(gamma: float, vx: float, vy: float) -> float:
    """``tan β_k``: direction of the kingpin velocity ``(vx, vy)`` (tractor axes) in the trailer frame, ``R(Γ)``.

    Parameters
    ----------
    gamma
        Articulation angle ``Γ`` [rad].
    vx, vy
        Kingpin velocity in tractor axes [m/s].

    Returns
    -------
    float
        ``v_k2y/v_k2x`` (zero when the kingpin does not move forward in the trailer frame).
    """
    cg, sg = math.cos(gamma), math.sin(gamma)
    vk2x, vk2y = cg * vx - sg * vy, sg * vx + cg * vy
    return vk2y / vk2x if vk2x > 1e-6 else 0.0


def axle_velocity_directions(
    distances: np.ndarray, tan_kingpin: float, yaw_rate: float, kingpin_speed: float
) -> np.ndarray:
    """Direction ``β_j`` [rad] of each axle's ground velocity in the trailer frame (rigid trailer).

    The point ``L_j`` behind the kingpin moves at ``(v_k2x, v_k2y − r2·L_j)``, so
    ``β_j = atan(tan β_k − r2·L_j/v_k2x)`` (docs/vehicle_dynamics.md §2.3); an axle steered to ``δ_j`` slips by
    ``α_j = δ_j − β_j``.

    Parameters
    ----------
    distances
        ``L_j`` [m] of the axles.
    tan_kingpin
        ``tan β_k = v_k2y/v_k2x`` (:func:`tan_kingpin_direction`).
    yaw_rate
        Trailer yaw rate ``r2`` [rad/s].
    kingpin_speed
        ``v_k2x`` [m/s], the kingpin's forward velocity in the trailer frame (> 0).
    """
    return np.arctan(tan_kingpin - yaw_rate * np.asarray(distances, dtype=float) / kingpin_speed)


def axle_directions_above_speed(
    distances: np.ndarray, gamma: float, vx: float, vy: float, yaw_rate: float, min_speed: float
) -> np.ndarray | None:
    """Velocity directions ``β_j`` [rad] of the axles ``distances`` behind the kingpin, or ``None`` at walking pace.

    ``None`` when the kingpin's forward speed in the trailer frame is below ``min_speed`` [m/s] (a slip angle is not
    defined by the kinematics there). ``vx, vy``: kingpin velocity in tractor axes [m/s]; ``gamma``: articulation
    [rad]; ``yaw_rate``: trailer yaw rate [rad/s] (:func:`axle_velocity_directions`).
    """
    forward_speed = math.cos(gamma) * vx - math.sin(gamma) * vy  # v_k2x, as tan_kingpin_direction
    if forward_speed < min_speed:
        return None
    return axle_velocity_directions(distances, tan_kingpin_direction(gamma, vx, vy), yaw_rate, forward_speed)


def slip_angle_window(
    distances: np.ndarray,
    gamma: float,
    vx: float,
    vy: float,
    yaw_rate: float,
    max_slip: float | None,
    min_speed: float,
) -> tuple[np.ndarray, np.ndarray] | None:
    """Steer bounds ``(min(β_j − α_max, 0), max(β_j + α_max, 0))`` [rad] of the slip-angle limit, or ``None``.

    The window always holds straight ahead. ``β_j`` comes from the kingpin velocity the caller passes, which the
    tractor's signals give by zero-slip kinematics; when the tractor itself slides (a wet tight turn) that
    direction is wrong by tens of degrees, and a window wholly on one side of straight ahead would drive every
    axle to the lock on that side, against the command. Held to straight ahead at worst, an axle slips no more
    than the unsteered trailer's.

    Returns ``None`` when ``max_slip`` is ``None`` or the kingpin's forward speed in the trailer frame is below
    ``min_speed`` [m/s] (a slip angle is not defined by the kinematics at walking pace). ``vx, vy``: kingpin
    velocity in tractor axes [m/s]; ``gamma``: articulation [rad]; ``yaw_rate``: trailer yaw rate [rad/s].
    """
    beta = None if max_slip is None else axle_directions_above_speed(distances, gamma, vx, vy, yaw_rate, min_speed)
    if beta is None:
        return None
    # Straight ahead is always inside the window: the limit never steers an axle across it against the command.
    return np.minimum(beta - max_slip, 0.0), np.maximum(beta + max_slip, 0.0)


def limit_axle_commands(
    target: np.ndarray, previous: np.ndarray, max_steer: float, max_steer_rate: float, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per-axle saturation then rate limit: ``(limited, output)`` [rad].

    Parameters
    ----------
    target
        Commanded angles [rad], one per steerable axle.
    previous
        Last tick's output [rad].
    max_steer
        Magnitude limit ``δ_max`` [rad].
    max_steer_rate
        Rate limit ``δ̇_max`` [rad/s].
    dt
        Control period [s].

    Returns
    -------
    tuple of numpy.ndarray
        ``(limited, output)``: the target clipped to ``±δ_max``, then that clipped to ``±δ̇_max·dt`` of
        ``previous``.
    """
    limited = np.clip(target, -max_steer, max_steer)
    step = max_steer_rate * dt
    return limited, np.clip(limited, previous - step, previous + step)
