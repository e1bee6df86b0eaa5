"""A combination as data: its units in order, each with its body, axles and coupling, read from YAML and validated.

A combination file (``vehicle_model/catalogue/NAME.yaml`` for the presets, or any file given as ``--vehicle
FILE.yaml``) lists its ``units`` front to rear. Each unit is a :class:`UnitSpec`: the fields of the model's own
unit parameters (:class:`~vehicle_model.parameters.TractorParams`, :class:`~vehicle_model.parameters.TrailerParams`,
whose ranges and body checks it inherits, so each is written once), plus its ``kind``, the ``coupling`` by which the
unit ahead tows it (:class:`CouplingSpec`) and, per axle, whether it can be or is lifted (:class:`AxleSpec`).
``yaw_inertia: box`` asks for the uniform-box estimate (:func:`box_yaw_inertia`).

Stations are metres along each unit, positive forward, from any reference point of that unit the file chooses; the
model's own origins (the tractor's front axle, the semi-trailer's kingpin, :mod:`vehicle_model.parameters`) are
found from the axles and the coupling, so a file measured from the front bumper gives the same vehicle. A lifted
axle carries no load and no side force, so the model leaves it out.

The schema names every unit kind of the combinations in use (tractor, rigid truck, semi-trailer, converter dolly,
centre-axle trailer, full trailer) and checks their couplings; :meth:`CombinationSpec.params` then refuses, in one
line naming the field, a combination the model cannot simulate: it has a tractor or rigid truck towing up to three
units (semi-trailers, converter dollies, centre-axle trailers; a full trailer is written as its dolly and a
semi-trailer).
"""

from __future__ import annotations

import functools
from importlib import resources
from typing import Annotated, Any, Literal

import yaml
from pydantic import ConfigDict, Discriminator, Field, Tag, ValidationError, model_validator

from .parameters import (
    AxleParams,
    DragArea,
    Mass,
    Station,
    TractorParams,
    TrailerParams,
    TyreParams,
    VehicleParams,
    YawInertia,
    _Frozen,
    _UnitParams,
)

__all__ = [
    "CATALOGUE_PACKAGE",
    "AxleSpec",
    "CombinationSpec",
    "CouplingSpec",
    "UnitSpec",
    "box_yaw_inertia",
    "catalogue_vehicle_data",
    "catalogue_vehicle_names",
    "combination_summary",
]

CATALOGUE_PACKAGE = "vehicle_model.catalogue"
"""The package whose ``*.yaml`` files are the vehicle presets, one combination a file, named by its file."""

UnitKind = Literal["tractor", "rigid_truck", "semi_trailer", "converter_dolly", "centre_axle_trailer", "full_trailer"]
"""The kinds of unit a combination is made of."""

TOWING_KINDS = ("tractor", "rigid_truck")
"""Kinds that lead a combination (they have the steer axle and the drive); no other unit can lead."""

COUPLING_OF: dict[str, str] = {
    "semi_trailer": "fifth_wheel",
    "converter_dolly": "drawbar",
    "centre_axle_trailer": "drawbar",
    "full_trailer": "drawbar",
}
"""The coupling each towed kind is towed by: a semi-trailer's kingpin sits on a fifth wheel, the others have a
drawbar whose eye hangs on a hitch of the unit ahead."""

SHORT_KIND = {
    "tractor": "tractor",
    "rigid_truck": "truck",
    "semi_trailer": "semi",
    "converter_dolly": "dolly",
    "centre_axle_trailer": "centre-axle",
    "full_trailer": "full",
}
"""Each kind in a word, for a listing's narrow column."""

SUPPORTED = (
    "the model supports a tractor or rigid truck towing up to three semi-trailers, converter dollies and centre-axle "
    "trailers"
)
"""Why :meth:`CombinationSpec.params` refuses any other combination."""


def box_yaw_inertia(mass: float, front_x: float, rear_x: float, width: float, cg_x: float) -> float:
    """Yaw inertia of a uniform box about the CG, ``m(L² + W²)/12 + m·d²`` (docs/vehicle_dynamics.md §4.2).

    Parameters
    ----------
    mass : float
        The unit's mass [kg].
    front_x, rear_x : float
        Front and rear of the body [m]; ``L = front_x − rear_x``.
    width : float
        Body width ``W`` [m].
    cg_x : float
        CG station [m]; ``d`` is its distance from the body's centre.

    Returns
    -------
    float
        The yaw inertia about the CG [kg·m²].
    """
    length = front_x - rear_x
    centre = 0.5 * (front_x + rear_x)
    return mass * (length**2 + width**2) / 12.0 + mass * (cg_x - centre) ** 2


class TyreSpec(TyreParams):
    """An axle's tyre as a combination file gives it: :class:`~vehicle_model.parameters.TyreParams`, every number
    finite."""

    model_config = ConfigDict(allow_inf_nan=False)


class AxleSpec(AxleParams):
    """An axle as a combination file gives it: :class:`~vehicle_model.parameters.AxleParams` and its lift.

    Parameters
    ----------
    liftable
        Whether the axle has a lift (a raised axle saves tyre wear when the unit runs empty).
    lifted
        Whether it is raised for this combination: it then carries no load and no side force, and the model leaves
        it out. Only a liftable axle can be lifted.
    """

    model_config = ConfigDict(allow_inf_nan=False)

    tyre: TyreSpec = TyreSpec()
    liftable: bool = False
    lifted: bool = False

    @model_validator(mode="after")
    def _lift(self) -> AxleSpec:
        if self.lifted and not self.liftable:
            raise ValueError(f"lifted: axle {self.name!r} is not liftable (set liftable: true if it has a lift)")
        return self

    def params(self, origin: float) -> AxleParams:
        """The model's axle, its station measured from ``origin`` [m]."""
        fields = {name: getattr(self, name) for name in AxleParams.model_fields}
        tyre = TyreParams.model_validate(self.tyre.model_dump())
        return AxleParams.model_validate(fields | {"x": self.x - origin, "tyre": tyre})


class CouplingSpec(_Frozen):
    """Where a unit is coupled to the unit ahead.

    Parameters
    ----------
    kind
        ``fifth_wheel`` (a semi-trailer's kingpin on the unit ahead's fifth wheel) or ``drawbar`` (the eye of this
        unit's drawbar on a hitch of the unit ahead).
    ahead_x
        Station of the coupling point on the unit ahead [m], in that unit's stations.
    x
        Station of the coupling point on this unit [m]: the kingpin, or the drawbar eye (ahead of the body).
    """

    model_config = ConfigDict(allow_inf_nan=False)

    kind: Literal["fifth_wheel", "drawbar"]
    ahead_x: Station
    x: Station = 0.0


RoadMass = Annotated[
    Mass, Field(le=100_000.0, description="[kg]; a unit has mass, and one above 100 t is no road vehicle")
]
"""A road unit's mass [kg]."""

_ROAD_INERTIA = "[kg·m²] about the CG, or box; a uniform 100 t box 25 m long has 5.3e6, so 1e7 bounds any road unit"

RoadYawInertia = Annotated[YawInertia, Field(le=1.0e7, description=_ROAD_INERTIA)]
"""A road unit's yaw inertia about its CG [kg·m²]."""


def _inertia_tag(value: Any) -> str:
    """Which form of ``yaw_inertia`` a value is: a ``number`` or the ``box`` estimate."""
    return "box" if isinstance(value, str) else "number"


INERTIA_TAGS = ("number", "box")
"""The tags pydantic puts in the location of an error in ``yaw_inertia`` (which form of it was validated)."""


class UnitSpec(_UnitParams):
    """One unit of a combination: the model's unit parameters, its kind, its coupling and its axles' lift.

    Parameters
    ----------
    kind
        tractor, rigid_truck, semi_trailer, converter_dolly, centre_axle_trailer or full_trailer.
    mass
        Mass [kg].
    yaw_inertia
        Yaw inertia about the CG [kg·m²], or ``box`` for the uniform-box estimate (:func:`box_yaw_inertia`).
    cg_x
        CG station [m].
    front_x, rear_x
        Front and rear of the body [m].
    width
        Overall width [m].
    axles
        Axles, front to rear (:class:`AxleSpec`).
    coupling
        How the unit ahead tows this one (:class:`CouplingSpec`); none on the first unit.
    drag_area
        Aerodynamic ``C_d·A`` of the combination [m²], on the first unit only (default 6 m²).
    follow_point_x
        Station of the follow point whose off-tracking is measured [m], on a towed unit (default: the rear).
    """

    model_config = ConfigDict(allow_inf_nan=False)

    kind: UnitKind
    mass: RoadMass
    yaw_inertia: Annotated[
        Annotated[RoadYawInertia, Tag("number")] | Annotated[Literal["box"], Tag("box")], Discriminator(_inertia_tag)
    ] = Field(description=_ROAD_INERTIA)
    axles: tuple[AxleSpec, ...] = Field((), description="front to rear; a unit rests on at least one axle")
    coupling: CouplingSpec | None = None
    drag_area: DragArea | None = None
    follow_point_x: Station | None = None

    @property
    def inertia(self) -> float:
        """The yaw inertia [kg·m²], the box estimate when ``yaw_inertia`` is ``box``."""
        if self.yaw_inertia == "box":
            return box_yaw_inertia(self.mass, self.front_x, self.rear_x, self.width, self.cg_x)
        return float(self.yaw_inertia)

    @property
    def grounded(self) -> tuple[AxleSpec, ...]:
        """The axles on the ground (not lifted)."""
        return tuple(a for a in self.axles if not a.lifted)


def _unit_checks(i: int, unit: UnitSpec, ahead: UnitSpec | None) -> None:
    """Refuse, naming the field, a unit that cannot be where it is in the combination."""
    at = f"units[{i}]"
    if not unit.axles:
        raise ValueError(f"{at}.axles: a {unit.kind} has no axle; give at least one (a unit rests on its axles)")
    if not unit.grounded:
        raise ValueError(f"{at}.axles: every axle is lifted; at least one must carry the {unit.kind}")
    if ahead is None:
        if unit.kind not in TOWING_KINDS:
            raise ValueError(
                f"{at}.kind = {unit.kind!r}: the first unit leads the combination; it must be a tractor or rigid_truck"
            )
        if unit.coupling is not None:
            raise ValueError(f"{at}.coupling: the first unit is towed by nothing; remove its coupling")
        if unit.follow_point_x is not None:
            raise ValueError(f"{at}.follow_point_x: the follow point is on a towed unit, not the first")
        if not any(a.driven for a in unit.grounded):
            raise ValueError(f"{at}.axles: a {unit.kind} needs a driven axle on the ground (driven: true)")
        return
    if unit.kind in TOWING_KINDS:
        raise ValueError(f"{at}.kind = {unit.kind!r}: only the first unit can be a tractor or rigid_truck")
    if unit.drag_area is not None:
        raise ValueError(f"{at}.drag_area: the combination's drag area is given on its first unit")
    if any(a.driven for a in unit.axles):
        raise ValueError(f"{at}.axles: a {unit.kind} is towed; none of its axles can be driven")
    needed = COUPLING_OF[unit.kind]
    if unit.coupling is None:
        raise ValueError(f"{at}.coupling: a {unit.kind} needs its {needed} (coupling: {{kind: {needed}, ahead_x: …}})")
    coupling = unit.coupling
    if coupling.kind != needed:
        raise ValueError(f"{at}.coupling.kind = {coupling.kind!r}: a {unit.kind} is towed by a {needed}")
    if not ahead.rear_x <= coupling.ahead_x <= ahead.front_x:
        raise ValueError(
            f"{at}.coupling.ahead_x ({coupling.ahead_x} m) lies off units[{i - 1}]'s body "
            f"[{ahead.rear_x}, {ahead.front_x}] m; the {needed} is on the unit ahead"
        )
    if needed == "fifth_wheel":
        if not unit.rear_x <= coupling.x <= unit.front_x:
            raise ValueError(
                f"{at}.coupling.x ({coupling.x} m) lies off the {unit.kind}'s body [{unit.rear_x}, {unit.front_x}] m; "
                "the kingpin is under its body"
            )
        if unit.cg_x >= coupling.x:
            raise ValueError(
                f"{at}.cg_x ({unit.cg_x} m) must lie behind the kingpin (coupling.x = {coupling.x} m): a semi-trailer "
                "rests on the fifth wheel ahead and its axles behind"
            )
    elif coupling.x <= max(a.x for a in unit.axles):
        raise ValueError(
            f"{at}.coupling.x ({coupling.x} m) must lie ahead of the {unit.kind}'s axles: the drawbar eye is at the "
            "drawbar's front end"
        )
    if unit.follow_point_x is not None and not unit.rear_x <= unit.follow_point_x < coupling.x:
        raise ValueError(
            f"{at}.follow_point_x ({unit.follow_point_x} m) must lie on the body behind the coupling "
            f"[{unit.rear_x}, {coupling.x}) m"
        )


class CombinationSpec(_Frozen):
    """A combination: its units front to rear (:class:`UnitSpec`), checked as a whole.

    Parameters
    ----------
    name
        The combination's name (a preset's is its file's).
    description
        One line: what it is (``offtrack list`` shows it).
    source
        Where its numbers come from (citations, or that they are documented estimates).
    units
        The units, front to rear: a tractor or rigid truck first, then the units it tows, each with its coupling.
    """

    model_config = ConfigDict(allow_inf_nan=False)

    name: str = Field("custom", min_length=1)
    description: str = ""
    source: str = ""
    units: tuple[UnitSpec, ...] = Field(
        min_length=1, max_length=8, description="front to rear; 8 units is beyond any road train"
    )

    @model_validator(mode="after")
    def _check_combination(self) -> CombinationSpec:
        for i, unit in enumerate(self.units):
            _unit_checks(i, unit, self.units[i - 1] if i else None)
        names = [a.name for u in self.units for a in u.axles]
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise ValueError(f"units[].axles[].name must be unique in the combination; repeated: {repeated}")
        return self

    def supported(self) -> None:
        """Refuse, in one line naming the field, a combination the model cannot simulate (:data:`SUPPORTED`).

        Raises
        ------
        ValueError
            The combination is not a tractor or rigid truck with one semi-trailer.
        """
        if len(self.units) == 1:
            raise ValueError(f"units: one unit; {SUPPORTED}: add the unit it tows")
        for i, unit in enumerate(self.units[1:], start=1):
            if unit.kind == "full_trailer":
                raise ValueError(
                    f"units[{i}].kind = 'full_trailer': in the yaw plane a full trailer is two bodies; write it as its "
                    "converter_dolly and a semi_trailer on the dolly's fifth wheel"
                )
        if len(self.units) > 4:
            raise ValueError(f"units[4]: {len(self.units)} units; {SUPPORTED}")

    def params(self) -> VehicleParams:
        """The model's parameters of this combination, stations moved to the model's origins.

        Returns
        -------
        VehicleParams
            The tractor's stations from its front axle on the ground, each semi-trailer's from its kingpin; lifted
            axles left out; the box estimate where ``yaw_inertia`` is ``box``.

        Raises
        ------
        ValueError
            One line naming the field: a combination the model cannot simulate (:meth:`supported`), or axle loads
            the statics cannot give (:class:`~vehicle_model.parameters.VehicleParams`).
        """
        self.supported()
        front, *towed = self.units
        origin = max(a.x for a in front.grounded)
        assert towed[0].coupling is not None  # the checks give every towed unit its coupling
        tractor = TractorParams(
            mass=front.mass,
            yaw_inertia=front.inertia,
            cg_x=front.cg_x - origin,
            fifth_wheel_x=towed[0].coupling.ahead_x - origin,
            front_x=front.front_x - origin,
            rear_x=front.rear_x - origin,
            width=front.width,
            axles=tuple(a.params(origin) for a in front.grounded),
            **({} if front.drag_area is None else {"drag_area": front.drag_area}),
        )
        semis = []
        for i, trailer in enumerate(towed):
            assert trailer.coupling is not None
            kingpin = trailer.coupling.x
            behind = towed[i + 1].coupling if i + 1 < len(towed) else None
            semis.append(
                TrailerParams(
                    mass=trailer.mass,
                    yaw_inertia=trailer.inertia,
                    cg_x=trailer.cg_x - kingpin,
                    front_x=trailer.front_x - kingpin,
                    rear_x=trailer.rear_x - kingpin,
                    width=trailer.width,
                    axles=tuple(a.params(kingpin) for a in trailer.grounded),
                    follow_point_x=None if trailer.follow_point_x is None else trailer.follow_point_x - kingpin,
                    fifth_wheel_x=None if behind is None else behind.ahead_x - kingpin,
                    front_load=trailer.kind != "converter_dolly",  # a dolly's drawbar is hinged in pitch
                )
            )
        try:
            return VehicleParams(name=self.name, tractor=tractor, trailer=semis[0], rear_trailers=tuple(semis[1:]))
        except ValidationError as exc:  # the statics: name the units as the file does
            message = exc.errors()[0]["msg"].removeprefix("Value error, ")
            message = message.replace("rear_trailers[0].", "units[2].").replace("rear_trailers[1].", "units[3].")
            message = message.replace("trailer.", "units[1].").replace("tractor.", "units[0].")
            raise ValueError(message.replace("tractor:", "units[0]:")) from None


def catalogue_vehicle_names() -> list[str]:
    """The vehicle presets: the names of the catalogue's files (``vehicle_model/catalogue/NAME.yaml``)."""
    files = resources.files(CATALOGUE_PACKAGE).iterdir()
    return sorted(f.name.removesuffix(".yaml") for f in files if f.name.endswith(".yaml"))


@functools.cache
def _catalogue_text(name: str) -> str:
    entry = resources.files(CATALOGUE_PACKAGE) / f"{name}.yaml"
    if not entry.is_file():
        raise ValueError(f"unknown vehicle preset {name!r}; choose one of {catalogue_vehicle_names()}")
    return entry.read_text(encoding="utf-8")


def catalogue_vehicle_data(name: str) -> dict[str, Any]:
    """The raw mapping of the catalogue's combination ``name``, its ``name`` set to the preset's (a fresh copy).

    Raises
    ------
    ValueError
        ``name`` is not in the catalogue; the message lists the presets.
    """
    data = yaml.safe_load(_catalogue_text(name))
    return {**data, "name": name}


def combination_summary(spec: CombinationSpec) -> tuple[float, str, str]:
    """What ``offtrack list`` shows of a combination: overall length, its units, its steerable axles.

    Parameters
    ----------
    spec : CombinationSpec
        The combination.

    Returns
    -------
    tuple of (float, str, str)
        The overall length [m] from the first unit's front to the last unit's rear along a straight line (each
        coupling joining the stations of the two units it couples), the unit kinds joined by ``+``, and the names of
        the steerable axles on the ground (``–`` for none). The kinds are shortened (:data:`SHORT_KIND`).
    """
    rear = min(_rear_in_first(spec, i) for i in range(len(spec.units)))  # a short unit may end ahead of another
    steerable = [a.name for u in spec.units for a in u.grounded if a.steerable]
    kinds = " + ".join(SHORT_KIND[u.kind] for u in spec.units)
    return spec.units[0].front_x - rear, kinds, ", ".join(steerable) or "–"


def _rear_in_first(spec: CombinationSpec, index: int) -> float:
    """The rear of unit ``index`` in the first unit's stations, the combination straight."""
    offset = 0.0
    for unit in spec.units[1 : index + 1]:
        assert unit.coupling is not None
        offset += unit.coupling.ahead_x - unit.coupling.x
    return spec.units[index].rear_x + offset
