"""Typed, validated parameters of a tractor–semi-trailer.

Coordinates
-----------
All lengths are metres, masses kilograms, inertias kg·m², angles radians.

* Tractor stations are measured from the **steer (front) axle**, positive forward (ISO 8855 x).
* Trailer stations are measured from the **kingpin**, positive forward, so trailer axles, the trailer
  CG and the follow point have negative stations.

Static axle loads follow from statics with *load groups*: axles that share one load-sharing
suspension carry equal loads, and the group load acts at the group's mean station. The trailer
must then have exactly one load group (the kingpin is the other support) and the tractor exactly
two (front and rear); any other layout needs explicit ``static_load`` on every axle of that unit.
There is no dynamic load transfer: the model is single-track (yaw plane) and normal loads stay
static apart from the ``cos θ`` factor of a sloped road.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from .settings import no_bool_for_a_number
from .static_loads import solve_loads

GRAVITY = 9.81
"""Standard gravity used throughout [m/s²]."""


STATION_LIMIT_M = 30.0
"""Largest |station| of a point of a unit [m]: the longest road units are under 20 m, so ±30 m from any reference
point on the unit holds them."""

Station = Annotated[
    float,
    Field(
        ge=-STATION_LIMIT_M,
        le=STATION_LIMIT_M,
        description="[m] along the unit, positive forward; ±30 m holds any road unit (the longest are under 20 m)",
    ),
]
"""A station along a unit's centre line [m] (module docstring: where each unit's stations start)."""

Mass = Annotated[float, Field(gt=0, description="[kg]; a unit has mass")]
"""A unit's mass [kg]. Unbounded above: a design model holds the kingpin still with a tractor of 1e6 times its mass
(:mod:`controller.gain_design`); a combination file bounds it to road units (:mod:`vehicle_model.combination`)."""

YawInertia = Annotated[float, Field(gt=0, description="[kg·m²] about the CG; a unit has one")]
"""A unit's yaw inertia about its CG [kg·m²]; unbounded above, as :data:`Mass`."""

DragArea = Annotated[
    float, Field(ge=0, le=20.0, description="[m²] C_d·A; a truck's is 5–7 m², 20 m² is beyond any road vehicle")
]
"""The aerodynamic drag area ``C_d·A`` of a combination [m²]."""


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", validate_default=True)

    @field_validator("*", mode="before")
    @classmethod
    def _strict_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        return no_bool_for_a_number(cls, value, info.field_name)  # `true` is no mass


class TyreParams(_Frozen):
    """Lateral Magic Formula tyre (PAC2002 pure-slip subset, zero camber, shifts dropped).

    Defaults are the 315/80 R22.5 truck tyre of Pacejka's book as shipped in Project Chrono's
    ``CityBus_Pac02Tire.tir`` (docs/vehicle_dynamics.md §3.1), with the sign of ``PKY1`` flipped to this
    project's positive-force slip convention.

    Parameters
    ----------
    fz_nominal
        FNOMIN, nominal tyre load [N].
    unloaded_radius
        Free tyre radius [m], used by the relaxation length.
    pcy1, pdy1, pdy2, pey1, pey2, pky1, pky2
        Magic Formula shape, peak, curvature and cornering-stiffness coefficients [-].
    pty1, pty2
        Relaxation-length coefficients: ``σ = PTY1·sin(2·atan(Fz/(PTY2·FNOMIN)))·R0`` [-].
    rolling_resistance
        Rolling-resistance coefficient ``f_r`` [-] (force ``f_r·Fz`` opposing the wheel's roll).
    low_speed_damping_time
        Time constant ``τ0`` [s] of the carcass damping that keeps the relaxation model damped at
        walking pace and standstill; faded out linearly between ``low_speed_fade`` and twice it.
    low_speed_fade
        Speed [m/s] below which the carcass damping acts fully.
    """

    fz_nominal: float = Field(35_000.0, gt=0)
    unloaded_radius: float = Field(0.548, gt=0)
    pcy1: float = Field(1.5874, gt=0, lt=2)
    pdy1: float = Field(0.73957, gt=0)
    pdy2: float = -0.075004
    pey1: float = Field(0.37562, le=1)
    pey2: float = -0.069325
    pky1: float = Field(10.289, gt=0)
    pky2: float = Field(3.3343, gt=0)
    pty1: float = Field(1.2, gt=0)
    pty2: float = Field(2.5, gt=0)
    rolling_resistance: float = Field(0.006, ge=0, lt=0.1)
    low_speed_damping_time: float = Field(0.05, ge=0)
    low_speed_fade: float = Field(2.0, gt=0)

    def cornering_stiffness(self, fz: float | np.ndarray) -> float | np.ndarray:
        """Cornering stiffness ``K_y`` of one tyre at load ``fz`` [N/rad] (docs/vehicle_dynamics.md §3.1)."""
        return self.pky1 * self.fz_nominal * np.sin(2.0 * np.arctan(fz / (self.pky2 * self.fz_nominal)))

    def relaxation_length(self, fz: float | np.ndarray) -> float | np.ndarray:
        """Lateral relaxation length ``σ`` of one tyre at load ``fz`` [m] (PAC2002 PTY1/PTY2)."""
        return self.pty1 * np.sin(2.0 * np.arctan(fz / (self.pty2 * self.fz_nominal))) * self.unloaded_radius


class AxleParams(_Frozen):
    """One axle of a unit, lumped on the centre line (single-track).

    Parameters
    ----------
    name
        Unique name within the vehicle, used in input and output layouts.
    x
        Station [m] in the unit's coordinates (see module docstring).
    n_tyres
        Tyres on the axle; the axle force is ``n_tyres · f_tyre(α, Fz/n_tyres)``.
    steerable
        Whether the axle has a steer-angle input.
    driven
        Whether the axle carries drive force.
    load_group
        Axles with the same group share their load equally (load-sharing suspension).
    static_load
        Explicit static vertical load [N]; overrides statics when given on every axle of a unit.
    tyre
        Tyre of this axle.
    """

    name: str = Field(min_length=1, description="unique within the vehicle: the axle's columns are named by it")
    x: Station
    n_tyres: int = Field(
        2, ge=1, le=8, description="tyres on the axle; 1 (a single tyre) to 8 (heavy-haulage twin-twins on each end)"
    )
    steerable: bool = False
    driven: bool = False
    load_group: str = "main"
    static_load: float | None = Field(None, gt=0, description="[N]; an axle on the ground carries a load")
    tyre: TyreParams = TyreParams()


class _UnitParams(_Frozen):
    mass: Mass
    yaw_inertia: YawInertia
    cg_x: Station
    front_x: Station
    rear_x: Station
    width: float = Field(
        gt=0, le=4.0, description="[m] overall; 2.55 m is the legal width, above 4 m is an abnormal load, not modelled"
    )
    axles: tuple[AxleParams, ...] = Field(min_length=1)

    @model_validator(mode="after")
    def _check_body(self) -> _UnitParams:
        if self.front_x <= self.rear_x:
            raise ValueError(f"front_x ({self.front_x} m) must lie ahead of rear_x ({self.rear_x} m)")
        if not self.rear_x <= self.cg_x <= self.front_x:
            raise ValueError(f"cg_x ({self.cg_x} m) must lie on the body, between rear_x and front_x")
        for i, axle in enumerate(self.axles):
            if not self.rear_x <= axle.x <= self.front_x:
                raise ValueError(
                    f"axles[{i}].x ({axle.x} m, axle {axle.name!r}) lies off the body "
                    f"[{self.rear_x}, {self.front_x}] m; move the axle or extend the body"
                )
        explicit = [a.static_load is not None for a in self.axles]
        if any(explicit) and not all(explicit):
            raise ValueError("static_load must be given on every axle of a unit or on none")
        return self

    @property
    def length(self) -> float:
        """Body length [m]."""
        return self.front_x - self.rear_x


class TractorParams(_UnitParams):
    """Tractor unit. Stations from the steer axle, positive forward.

    Parameters
    ----------
    mass, yaw_inertia
        Mass [kg] and yaw inertia about the CG [kg·m²].
    cg_x
        CG station [m].
    fifth_wheel_x
        Station of the coupling the first towed unit hangs on [m]: the fifth wheel (kingpin), or a rigid truck's
        drawbar hitch.
    front_x, rear_x
        Front bumper and rear chassis stations [m]; the front corners are the outermost points in
        the roundabout test.
    width
        Overall width [m].
    axles
        Axles, front to rear.
    drag_area
        Aerodynamic ``C_d·A`` of the combination [m²], acting on the tractor.
    """

    fifth_wheel_x: Station
    drag_area: DragArea = 6.0

    @model_validator(mode="after")
    def _check_tractor(self) -> TractorParams:
        if not self.rear_x <= self.fifth_wheel_x <= self.front_x:
            raise ValueError(f"fifth_wheel_x ({self.fifth_wheel_x} m) must lie on the tractor body")
        if not any(a.driven for a in self.axles):
            raise ValueError("axles: the tractor needs at least one driven axle (driven=True)")
        return self


class TrailerParams(_UnitParams):
    """A towed unit: a semi-trailer, a converter dolly or a centre-axle trailer. Stations from its front coupling
    (the kingpin, or the drawbar eye), positive forward (axles negative); "kingpin" below means that coupling.

    Parameters
    ----------
    mass, yaw_inertia
        Mass [kg] and yaw inertia about the CG [kg·m²].
    cg_x
        CG station [m] (negative: behind the kingpin).
    front_x, rear_x
        Front and rear of the body [m]; ``-rear_x`` is the kingpin-to-rear length.
    width
        Body width [m].
    axles
        Axles, front to rear.
    follow_point_x
        Station of the follow point whose off-tracking is measured and controlled [m]; defaults
        to the rear of the body.
    fifth_wheel_x
        Station of the coupling on this unit that tows the next one [m]: a fifth wheel (the lead trailer of a
        B-double, a converter dolly); none on the last unit.
    front_load
        Whether the front coupling carries vertical load: a kingpin on a fifth wheel, a centre-axle trailer's rigid
        drawbar (True); a converter dolly's drawbar, hinged in pitch, carries none, so the dolly's axles carry its
        weight and the load on its fifth wheel (False).
    """

    follow_point_x: Station | None = None
    fifth_wheel_x: Station | None = None
    front_load: bool = True

    @model_validator(mode="after")
    def _check_trailer(self) -> TrailerParams:
        if self.cg_x >= 0:
            raise ValueError(f"cg_x ({self.cg_x} m) must be behind the kingpin (negative)")
        if any(a.driven for a in self.axles):
            raise ValueError("axles: a semi-trailer axle cannot be driven")
        if self.follow_point_x is not None and not self.rear_x <= self.follow_point_x < 0:
            raise ValueError(
                f"follow_point_x ({self.follow_point_x} m) must lie behind the kingpin and on the body "
                f"[{self.rear_x}, 0) m"
            )
        if self.fifth_wheel_x is not None and not self.rear_x <= self.fifth_wheel_x < 0:
            raise ValueError(
                f"fifth_wheel_x ({self.fifth_wheel_x} m) must lie behind the kingpin and on the body "
                f"[{self.rear_x}, 0) m"
            )
        return self

    @property
    def follow_point_offset(self) -> float:
        """Distance ``L_fp`` from the kingpin back to the follow point [m]."""
        return -(self.follow_point_x if self.follow_point_x is not None else self.rear_x)


@dataclass(frozen=True)
class AxleTable:
    """Per-axle arrays of a whole vehicle, the tractor's axles first, then each trailer's (every layout's order)."""

    names: tuple[str, ...]
    unit: np.ndarray  # 0 tractor, 1 the first trailer, 2 the next, …
    x_cg: np.ndarray  # station relative to the unit CG [m]
    n_tyres: np.ndarray
    steerable: np.ndarray
    driven: np.ndarray
    static_load: np.ndarray  # [N]
    tyres: tuple[TyreParams, ...]


class VehicleParams(_Frozen):
    """A tractor or rigid truck towing a chain of up to three units: a tractor–semi-trailer, a B-double, a truck with
    a centre-axle trailer or with a converter dolly and a semi-trailer, an A-double.

    Parameters
    ----------
    name
        Preset or user name.
    tractor, trailer
        The towing unit and the unit it tows.
    rear_trailers
        Further towed units, front to rear, each hanging on the coupling (``fifth_wheel_x``) of the unit ahead.
    """

    name: str = "custom"
    tractor: TractorParams
    trailer: TrailerParams
    rear_trailers: tuple[TrailerParams, ...] = Field(
        (), max_length=2, description="up to four units in all: an A-double (tractor, semi, dolly, semi) has four"
    )

    @model_validator(mode="after")
    def _check_names(self) -> VehicleParams:
        names = [a.name for u in self.units for a in u.axles]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise ValueError(f"axle names must be unique; repeated: {dupes}")
        for i, ahead in enumerate(self.trailers[:-1]):
            if ahead.fifth_wheel_x is None:
                field = "trailer" if i == 0 else f"rear_trailers[{i - 1}]"
                raise ValueError(f"{field}.fifth_wheel_x: a unit tows the next on its fifth wheel; give its station")
        self._loads()  # raise early on an unsolvable load layout
        return self

    # -- the chain of units -----------------------------------------------------------------
    @property
    def trailers(self) -> tuple[TrailerParams, ...]:
        """The semi-trailers, front to rear."""
        return (self.trailer, *self.rear_trailers)

    @property
    def units(self) -> tuple[TractorParams | TrailerParams, ...]:
        """Every unit, front to rear: the tractor, then the semi-trailers."""
        return (self.tractor, *self.trailers)

    @property
    def n_units(self) -> int:
        """Number of units (2 for a tractor–semi-trailer)."""
        return 1 + len(self.trailers)

    def hinge_distances(self) -> tuple[tuple[float, float], ...]:
        """Per unit, the distance from its CG forward to its kingpin and back to its fifth wheel [m] (0 where it
        has none): the ``f_k`` and ``e_k`` of the chain's equations (:mod:`vehicle_model.chain`)."""
        out = []
        for k, unit in enumerate(self.units):
            front = -unit.cg_x if k else 0.0  # a trailer's stations run from its kingpin
            fifth = unit.fifth_wheel_x
            out.append((front, unit.cg_x - fifth if fifth is not None and k < self.n_units - 1 else 0.0))
        return tuple(out)

    # -- derived geometry -------------------------------------------------------------------
    @property
    def h1(self) -> float:
        """Tractor CG to fifth wheel, positive when the fifth wheel is behind the CG [m]."""
        return self.tractor.cg_x - self.tractor.fifth_wheel_x

    @property
    def h2(self) -> float:
        """Kingpin to trailer CG, positive when the CG is behind the kingpin [m]."""
        return -self.trailer.cg_x

    @property
    def follow_point_offset(self) -> float:
        """Kingpin to follow point ``L_fp`` [m]."""
        return self.trailer.follow_point_offset

    def follow_point_offset_of(self, unit: int = 1) -> float:
        """Front coupling to follow point ``L_fp`` [m] of towed unit ``unit`` (1 the first, as
        :attr:`AxleTable.unit`; its front coupling is the kingpin, or the fifth wheel of the unit ahead)."""
        return self._towed(unit).follow_point_offset

    @property
    def kingpin_load(self) -> float:
        """Static vertical load on the (first) fifth wheel [N]."""
        return self._loads()[1][0]

    def _loads(self) -> tuple[list[np.ndarray], list[float]]:
        """Static axle loads per unit and each semi-trailer's kingpin load [N] (:func:`.static_loads.solve_loads`)."""
        return solve_loads(self.tractor, self.trailers, GRAVITY)

    @property
    def axle_table(self) -> AxleTable:
        """Per-axle arrays, the tractor's axles first, then each trailer's."""
        loads, _ = self._loads()
        units = self.units
        return AxleTable(
            names=tuple(a.name for u in units for a in u.axles),
            unit=np.array([k for k, u in enumerate(units) for _ in u.axles]),
            x_cg=np.array([a.x - u.cg_x for u in units for a in u.axles]),
            n_tyres=np.array([a.n_tyres for u in units for a in u.axles], dtype=float),
            steerable=np.array([a.steerable for u in units for a in u.axles]),
            driven=np.array([a.driven for u in units for a in u.axles]),
            static_load=np.concatenate(loads),
            tyres=tuple(a.tyre for u in units for a in u.axles),
        )

    def trailer_axle_distances(self, unit: int = 1) -> np.ndarray:
        """Distances ``L_j`` of a towed unit's axles behind its front coupling [m] (``unit``: 1 the first towed
        unit, 2 the one behind it, as :attr:`AxleTable.unit`)."""
        return -np.array([a.x for a in self._towed(unit).axles])

    def _towed(self, unit: int) -> TrailerParams:
        """The towed unit numbered ``unit`` (1 the first), or ``ValueError`` naming the range."""
        if not 1 <= unit < self.n_units:
            raise ValueError(f"unit {unit} is not a towed unit of {self.name!r} (1..{self.n_units - 1})")
        return self.trailers[unit - 1]

    def axle_cornering_stiffness(self) -> np.ndarray:
        """Static cornering stiffness of every axle [N/rad], in ``axle_table`` order (tyres × per-tyre stiffness)."""
        table = self.axle_table
        return np.array(
            [
                t.cornering_stiffness(fz / n) * n
                for t, fz, n in zip(table.tyres, table.static_load, table.n_tyres, strict=True)
            ]
        )

    def equivalent_wheelbase(self, fixed_only: bool = False, unit: int = 1) -> float:
        """Equivalent wheelbase ``L_eq = ΣC_j L_j² / ΣC_j L_j`` [m] of a towed unit, from its front coupling
        (docs/vehicle_dynamics.md §2.3).

        Uses the static cornering stiffness of each of the unit's axles. With ``fixed_only`` only the
        unsteerable axles count (the zero-slip point of a trailer whose steerable axles are
        held straight still includes them; use ``False`` for an unsteered trailer). ``unit``: 1 the first
        towed unit (the default), 2 the one behind it, as :attr:`AxleTable.unit`.
        """
        towed = self._towed(unit)
        table = self.axle_table
        mask = table.unit == unit
        if fixed_only:
            mask &= ~table.steerable
        stiff = self.axle_cornering_stiffness()[mask]
        lengths = -(table.x_cg[mask] + towed.cg_x)
        return float(np.sum(stiff * lengths**2) / np.sum(stiff * lengths))

    def tractor_wheelbase(self) -> float:
        """Steer axle to the mean station of the rear load group [m] (the geometric wheelbase).

        The point of a multi-axle tractor that has no lateral velocity is :meth:`tractor_equivalent_wheelbase`.
        """
        tr = self.tractor
        rear = [a.x for a in tr.axles if a.x < 0]
        return -float(np.mean(rear)) if rear else math.nan

    def tractor_equivalent_wheelbase(self) -> float:
        """Steer axle to the tractor's zero-slip rear point, ``L1 = ΣC_j L_j² / ΣC_j L_j`` [m].

        The sums run over the axles behind the steer axle (``L_j`` behind it, ``C_j`` their static cornering
        stiffness, :meth:`axle_cornering_stiffness`). Derived (docs/vehicle_dynamics.md §2.3): at low speed, with
        linear tyres, no lateral acceleration and no lateral force at the fifth wheel, a rear axle ``L_j`` behind the
        steer axle of a tractor turning on radius ``R`` about a point ``L1`` behind the steer axle slips by
        ``(L_j − L1)/R`` and carries ``F_j = C_j·(L_j − L1)/R``; the yaw moment of these forces about the steer axle
        must vanish, ``Σ F_j·L_j = 0``, which gives ``L1`` above. It is the low-speed limit of the equivalent
        wheelbase of a truck with non-steering rear axles (Winkler 1998; Williams 2011), the same relation as the
        trailer's :meth:`equivalent_wheelbase`, and the mean station only when the tractor has one rear axle. For
        the 6x2 tractor of the presets (drive 3.0 m, tag 4.37 m, the four-tyre drive axle the stiffer) it is
        about 0.10 m behind the mean station. A lateral force at the fifth wheel (a scrubbing trailer group) or a
        lateral acceleration moves the true zero-slip point away from it: that is tyre slip.
        """
        table = self.axle_table
        stations = -(table.x_cg + self.tractor.cg_x)  # distance behind the steer axle
        rear = (table.unit == 0) & (stations > 0)
        if not rear.any():
            return math.nan
        stiff = self.axle_cornering_stiffness()[rear]
        lengths = stations[rear]
        return float(np.sum(stiff * lengths**2) / np.sum(stiff * lengths))

    @functools.cached_property
    def tractor_rear_point_gradient(self) -> float:
        """``K`` [s²]: how far the tractor's zero-slip rear point moves forwards of
        :meth:`tractor_equivalent_wheelbase` per (m/s)² of speed in a steady turn, ``L1'(u) = L1 − K·u²``.

        Derived (docs/vehicle_dynamics.md §2.3, §6.6): in a steady turn the rear axles carry the yaw moment of the
        tractor's own lateral acceleration and of the trailer's pull at the fifth wheel, ``Σ F_j·L_j = m1·L_cg·a_y −
        L_5·F_5``; with linear tyres (``F_j = C_j·(L_j − L1')/R``, static cornering stiffness) and the trailer's pull
        ``F_5 = −m_5·a_y`` (``m_5`` the coupling's static vertical load over g: the share of the trailer's mass its
        coupling accelerates, exact for a trailer whose axle group sits at its equivalent wheelbase), ``a_y = u²/R``::

            K = (m1·L_cg + m_5·L_5) / Σ C_j·L_j

        (``L_cg``, ``L_5``, ``L_j`` behind the steer axle; the sum over the axles behind it). Linear tyres and
        steady state: it leaves out the push of a scrubbing trailer group at walking pace (§6.6), a camber's
        share of the lateral demand and the tyres' saturation, all of which are slip the signals do not show.
        """
        table = self.axle_table
        stations = -(table.x_cg + self.tractor.cg_x)  # distance behind the steer axle
        rear = (table.unit == 0) & (stations > 0)
        if not rear.any():
            return math.nan
        moment = float(np.sum(self.axle_cornering_stiffness()[rear] * stations[rear]))
        fifth_wheel = -self.tractor.fifth_wheel_x  # behind the steer axle
        return (self.tractor.mass * -self.tractor.cg_x + self.kingpin_load / GRAVITY * fifth_wheel) / moment

    def tractor_rear_point(self, speed: float) -> float:
        """Steer axle to the tractor's zero-slip rear point at ``speed`` [m/s] in a steady turn,
        ``L1' = L1 − K·u²`` [m] (:attr:`tractor_rear_point_gradient`, :meth:`tractor_equivalent_wheelbase`).
        Cheap: the estimators call it every control tick."""
        return self._tractor_rear_point_at_rest - self.tractor_rear_point_gradient * speed * speed

    def tractor_rear_slip_velocity(self, speed: float, lateral_acceleration: float) -> float:
        """Lateral velocity [m/s] of the tractor at :meth:`tractor_equivalent_wheelbase` from its rear tyres' slip,
        ``−K·u·f_y`` (left positive), with ``f_y`` the lateral specific force an accelerometer at the tractor's CG
        reads [m/s²].

        The balance of :attr:`tractor_rear_point_gradient` with the specific force in place of the centripetal
        acceleration (docs/vehicle_dynamics.md §2.3): the rear tyres carry ``Σ F_j·L_j = (m1·L_cg + m_5·L_5)·f_y``
        whatever asks for the force, a turn or a cross slope's share of gravity (the trailer's pull at the fifth
        wheel is ``m_5·f_y`` when the trailer's specific force is the tractor's), so each rear axle slips by
        ``F_j/C_j`` and the equivalent rear point moves sideways at ``u`` times that. In a steady turn on a level
        road ``f_y = u·r`` and it is :meth:`tractor_rear_point`'s shift times the yaw rate. Linear tyres: a tyre
        near its friction limit slips more.
        """
        return -self.tractor_rear_point_gradient * speed * lateral_acceleration

    @functools.cached_property
    def _tractor_rear_point_at_rest(self) -> float:
        """:meth:`tractor_equivalent_wheelbase`, computed once for :meth:`tractor_rear_point`."""
        return self.tractor_equivalent_wheelbase()

    @functools.cached_property
    def kingpin_behind_rear_point(self) -> float:
        """``e5``: the kingpin's distance behind the tractor's rear point (the steer axle minus
        :meth:`tractor_wheelbase`), negative when the kingpin is ahead of it [m].

        The controller's feed-forward and the fused estimator's tractor prior use this point; the zero-slip
        estimator uses :meth:`tractor_equivalent_wheelbase` instead
        (:func:`~vehicle_model.kinematics.zero_slip_kingpin_velocity`).
        """
        return -self.tractor_wheelbase() - self.tractor.fifth_wheel_x
