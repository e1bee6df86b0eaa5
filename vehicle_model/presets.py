"""Vehicle presets: the reference 6x2 tractor with a UK 13.6 m tri-axle trailer and the UK longer
semi-trailer (LST), each laden and unladen, and the paper's field-test combination (:func:`field`).

Sources (see ``docs/vehicle_dynamics.md`` §4–5; the § numbers below refer to it):

* Tractor: OpenPBS ``TractorSemitrailer6x2`` — axles at 0, −3.0, −4.37 m (steer, drive, tag), CG
  −1.3647 m, fifth wheel −3.4 m, 9841 kg, 2.991e4 kg·m². Front bumper 1.4 m ahead of the steer
  axle, 2.5 m wide (§5.3).
* 13.6 m trailer: OpenPBS trailer with a UK body — kingpin 6.4 m ahead of the first of three axles
  spaced 1.3 m, CG 4.3344 m behind the kingpin, 33 101 kg, 5.7348e5 kg·m²; body 1.6 m ahead of and
  12.0 m behind the kingpin, 2.55 m wide.
* LST: body 15.65 m, kingpin to rear 14.05 m (STGO 2023 arts. 59–60); tri-axle group moved back to
  8.0/9.3/10.6 m behind the kingpin with the two rear axles steerable; laden yaw inertia from the
  uniform-box estimate ``m(L_b² + W²)/12 + m·d²`` (§4.2).
* Unladen trailers: tare 7.5 t (13.6 m) and 8.5 t (LST) with the CG placed for a ~48 % kingpin
  share, inertia from the box estimate (§4.2: 1.2–1.5e5 kg·m² for an empty 13.6 m box).
* Field combination: de Saxe & Cebon 2018 §4.1, every number and its source in :func:`field`.
"""

from __future__ import annotations

from collections.abc import Callable

from .parameters import AxleParams, TractorParams, TrailerParams, VehicleParams

TRACTOR_6X2 = TractorParams(
    mass=9841.0,
    yaw_inertia=2.991e4,
    cg_x=-1.3647,
    fifth_wheel_x=-3.4,
    front_x=1.4,
    rear_x=-5.2,
    width=2.5,
    axles=(
        AxleParams(name="steer", x=0.0, n_tyres=2, steerable=True, load_group="front"),
        AxleParams(name="drive", x=-3.0, n_tyres=4, driven=True, load_group="rear"),
        AxleParams(name="tag", x=-4.37, n_tyres=2, load_group="rear"),
    ),
)


def _box_inertia(mass: float, front_x: float, rear_x: float, width: float, cg_x: float) -> float:
    """Uniform-box yaw inertia about the CG (docs/vehicle_dynamics.md §4.2)."""
    length = front_x - rear_x
    centre = 0.5 * (front_x + rear_x)
    return mass * (length**2 + width**2) / 12.0 + mass * (cg_x - centre) ** 2


def _trailer_13_6(mass: float, cg_x: float, yaw_inertia: float) -> TrailerParams:
    return TrailerParams(
        mass=mass,
        yaw_inertia=yaw_inertia,
        cg_x=cg_x,
        front_x=1.6,
        rear_x=-12.0,
        width=2.55,
        axles=(
            AxleParams(name="trailer1", x=-6.4),
            AxleParams(name="trailer2", x=-7.7),
            AxleParams(name="trailer3", x=-9.0),
        ),
    )


def _trailer_lst(mass: float, cg_x: float) -> TrailerParams:
    return TrailerParams(
        mass=mass,
        yaw_inertia=_box_inertia(mass, 1.6, -14.05, 2.55, cg_x),
        cg_x=cg_x,
        front_x=1.6,
        rear_x=-14.05,
        width=2.55,
        axles=(
            AxleParams(name="trailer1", x=-8.0),
            AxleParams(name="trailer2", x=-9.3, steerable=True),
            AxleParams(name="trailer3", x=-10.6, steerable=True),
        ),
    )


def reference_laden() -> VehicleParams:
    """6x2 tractor + UK 13.6 m tri-axle trailer, laden (GCW 42.9 t); the default vehicle."""
    return VehicleParams(name="reference", tractor=TRACTOR_6X2, trailer=_trailer_13_6(33_101.0, -4.3344, 5.7348e5))


def reference_unladen() -> VehicleParams:
    """6x2 tractor + UK 13.6 m tri-axle trailer, unladen (tare 7.5 t)."""
    mass, cg = 7_500.0, -4.0
    return VehicleParams(
        name="reference-unladen",
        tractor=TRACTOR_6X2,
        trailer=_trailer_13_6(mass, cg, _box_inertia(mass, 1.6, -12.0, 2.55, cg)),
    )


def lst_laden() -> VehicleParams:
    """6x2 tractor + UK longer semi-trailer (15.65 m, rear two axles steerable), laden."""
    return VehicleParams(name="lst", tractor=TRACTOR_6X2, trailer=_trailer_lst(33_101.0, -5.35))


def lst_unladen() -> VehicleParams:
    """6x2 tractor + UK longer semi-trailer, unladen (tare 8.5 t)."""
    return VehicleParams(name="lst-unladen", tractor=TRACTOR_6X2, trailer=_trailer_lst(8_500.0, -4.9))


TRACTOR_4X2_TAG_LIFTED = TractorParams.model_validate(
    TRACTOR_6X2.model_dump() | {"axles": TRACTOR_6X2.model_dump()["axles"][:2]}
)
"""The 6x2 tractor with its tag axle lifted: a 4x2 (steer and drive axles only)."""


def field() -> VehicleParams:
    """The paper's field-test combination (de Saxe & Cebon 2018, §4.1, Fig 10), unladen.

    "A 3-axle 'B-link' semi-trailer and a Volvo FH12 6×2 tractor. The tag axle of the tractor was
    permanently lifted during testing, as well as the front axle of the semi-trailer, making the
    combination effectively a 4×2 tractor with a 2-axle semi-trailer." The dimensions of Fig 10 are
    not in the text available to this project (the figure is an image), so every number below is a
    documented estimate (§ numbers refer to ``docs/vehicle_dynamics.md`` unless the paper is named):

    ========================  =====================  ================================================
    quantity                  value                  source
    ========================  =====================  ================================================
    tractor axles             steer 0, drive −3.0 m  OpenPBS ``TractorSemitrailer6x2`` (§4.1), the
                                                     tag axle (−4.37 m) lifted: removed,
                                                     as a lifted axle carries no load or side force
    tractor CG, fifth wheel   −1.3647 m, −3.4 m      OpenPBS (fifth wheel 0.40 m behind the drive
                                                     axle, between drive and lifted tag)
    tractor mass, inertia     9841 kg, 2.991e4 kg·m²  OpenPBS (a lifted axle stays on the chassis)
    tractor body              +1.4 / −5.2 m, 2.5 m   as the reference tractor (§5.3)
    trailer body              +1.6 / −12.0 m, 2.55 m  a 13.6 m-class box (§4.2); the
                                                     follow point at its rear, L_fp = 12.0 m
    trailer axles             −7.7, −9.0 m           the tri-axle group 6.4/7.7/9.0 m behind the
                                                     kingpin (OpenPBS, §4.1) with its
                                                     front axle lifted; L_eq ≈ 8.4 m
    trailer mass              7.5 t                  unladen: lift axles are raised only when the
                                                     vehicle runs empty or lightly laden, and the
                                                     test trailer carried only its instruments; tare
                                                     as ``reference-unladen``
    trailer CG                4.0 m behind kingpin   as ``reference-unladen`` (same body; the
                                                     kingpin then carries 52 % of the tare)
    trailer yaw inertia       box estimate           ``m(L_b² + W²)/12 + m·d²`` (§4.2)
    ========================  =====================  ================================================

    Cameras (not vehicle parameters; set in the scenario's ``camera:`` section): 4.2 m above the
    ground on the trailer roof (de Saxe & Cebon 2018, §4.1), rear (ψ_c2v = 180°) or left side (270°),
    baselines 0.5, 0.7 and 0.9 m (ibid.).
    """
    mass, cg = 7_500.0, -4.0
    trailer = TrailerParams(
        mass=mass,
        yaw_inertia=_box_inertia(mass, 1.6, -12.0, 2.55, cg),
        cg_x=cg,
        front_x=1.6,
        rear_x=-12.0,
        width=2.55,
        axles=(AxleParams(name="trailer2", x=-7.7), AxleParams(name="trailer3", x=-9.0)),
    )
    return VehicleParams(name="field", tractor=TRACTOR_4X2_TAG_LIFTED, trailer=trailer)


VEHICLE_PRESETS: dict[str, Callable[[], VehicleParams]] = {
    "reference": reference_laden,
    "reference-unladen": reference_unladen,
    "lst": lst_laden,
    "lst-unladen": lst_unladen,
    "field": field,
}


def vehicle_preset(name: str) -> VehicleParams:
    """Return the named preset.

    Raises
    ------
    ValueError
        With the list of known presets when ``name`` is unknown.
    """
    try:
        return VEHICLE_PRESETS[name]()
    except KeyError:
        raise ValueError(f"unknown vehicle preset {name!r}; choose one of {sorted(VEHICLE_PRESETS)}") from None
