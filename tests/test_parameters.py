"""Parameter objects, presets and validation."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from vehicle_model.parameters import GRAVITY, AxleParams, TractorParams, VehicleParams
from vehicle_model.presets import TRACTOR_6X2, VEHICLE_PRESETS, reference_laden, vehicle_preset
from vehicle_model.surface import FrictionPatch, RadialCamber, UniformFriction, friction_preset


def test_reference_static_loads_match_reference_notes(reference):
    # docs/vehicle_dynamics.md §4.1: steer 7.32 t, drive 8.50 t, tag 8.50 t, trailer 3 × 6.21 t, kingpin 14.47 t.
    loads_t = reference.axle_table.static_load / GRAVITY / 1000.0
    assert loads_t == pytest.approx([7.32, 8.50, 8.50, 6.21, 6.21, 6.21], abs=0.006)
    assert reference.kingpin_load / GRAVITY / 1000.0 == pytest.approx(14.47, abs=0.005)
    # Loads balance the weight of the combination.
    total = (reference.tractor.mass + reference.trailer.mass) * GRAVITY
    assert reference.axle_table.static_load.sum() == pytest.approx(total, rel=1e-12)


def test_reference_geometry(reference):
    # docs/vehicle_dynamics.md §4.1: h1 = 2.0353 m, h2 = 4.3344 m, L_eq = 7.846 m.
    assert reference.h1 == pytest.approx(2.0353, abs=1e-4)
    assert reference.h2 == pytest.approx(4.3344, abs=1e-4)
    assert reference.equivalent_wheelbase() == pytest.approx(7.846, abs=5e-4)
    assert reference.follow_point_offset == pytest.approx(12.0)


@pytest.mark.parametrize("name", sorted(VEHICLE_PRESETS))
def test_presets_are_valid_and_consistent(name):
    p = vehicle_preset(name)
    assert p.kingpin_load > 0 or not p.trailer.front_load  # a dolly's drawbar carries none
    assert (p.axle_table.static_load > 0).all()
    assert p.trailer.follow_point_offset == -p.trailer.rear_x


def test_lst_dimensions():
    lst = vehicle_preset("lst")
    assert lst.trailer.length == pytest.approx(15.65)
    assert -lst.trailer.rear_x == pytest.approx(14.05)
    assert any(a.steerable for a in lst.trailer.axles)


def test_unknown_preset_names_the_choices():
    with pytest.raises(ValueError, match="choose one of"):
        vehicle_preset("road-train")


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"mass": -1.0}, "mass"),
        ({"yaw_inertia": 0.0}, "yaw_inertia"),
        ({"width": -2.0}, "width"),
        ({"fifth_wheel_x": -9.0}, "fifth_wheel_x"),
    ],
)
def test_invalid_tractor_values_name_the_field(change, field):
    data = TRACTOR_6X2.model_dump() | change
    with pytest.raises(ValidationError, match=field):
        TractorParams(**data)


def test_axle_behind_the_body_is_rejected():
    data = TRACTOR_6X2.model_dump()
    data["axles"][2]["x"] = -7.0
    with pytest.raises(ValidationError, match=r"axles\[2\]\.x .*off the body"):
        TractorParams(**data)


def test_bad_tyre_count_names_the_field():
    with pytest.raises(ValidationError, match="n_tyres"):
        AxleParams(name="a", x=0.0, n_tyres=0)


def test_duplicate_axle_names_are_rejected(reference):
    data = reference.model_dump()
    data["trailer"]["axles"][0]["name"] = "steer"
    with pytest.raises(ValidationError, match="unique"):
        VehicleParams(**data)


def test_parameters_are_immutable(reference):
    with pytest.raises(ValidationError):
        reference.tractor.mass = 1.0


@pytest.mark.parametrize("mu", [0.0, -0.3, float("nan"), 3.0])
def test_invalid_friction_is_rejected(mu):
    with pytest.raises(ValueError, match="mu"):
        UniformFriction(mu)
    with pytest.raises(ValueError, match="mu"):
        FrictionPatch(0, 1, 0, 1, mu)


def test_surface_presets():
    assert friction_preset("ice") < friction_preset("snow") < friction_preset("wet") < friction_preset("dry")
    with pytest.raises(ValueError, match="unknown surface"):
        friction_preset("sand")
    with pytest.raises(ValueError, match="direction"):
        RadialCamber((0, 0), 5.0, direction="sideways")  # type: ignore[arg-type]


def test_tractor_equivalent_wheelbase_weights_the_rear_axles_by_cornering_stiffness(reference):
    # docs/vehicle_dynamics.md §2.3: L1 = ΣC_j·L_j² / ΣC_j·L_j over the axles behind the steer axle.
    # Two equal rear axles (same tyres, equal loads) spaced 2s about L: L + s²/L, not the mean station L.
    axles = TRACTOR_6X2.model_dump()["axles"]
    axles[2]["n_tyres"] = axles[1]["n_tyres"]
    equal = VehicleParams(
        name="equal-tandem",
        tractor=TractorParams.model_validate(TRACTOR_6X2.model_dump() | {"axles": axles}),
        trailer=reference.trailer,
    )
    mean, half = (3.0 + 4.37) / 2.0, (4.37 - 3.0) / 2.0
    assert equal.tractor_wheelbase() == pytest.approx(mean, rel=1e-12)
    assert equal.tractor_equivalent_wheelbase() == pytest.approx(mean + half**2 / mean, rel=1e-12)
    # The 6x2 preset: the four-tyre drive axle is the stiffer (§4.1: 499 against 456 kN/rad), so its L1 is
    # 3.783 m, 0.10 m behind the mean station; by hand from the axles' cornering stiffnesses.
    c_drive, c_tag = reference.axle_cornering_stiffness()[1:3]
    by_hand = (c_drive * 3.0**2 + c_tag * 4.37**2) / (c_drive * 3.0 + c_tag * 4.37)
    assert reference.tractor_equivalent_wheelbase() == pytest.approx(by_hand, rel=1e-12)
    assert reference.tractor_equivalent_wheelbase() == pytest.approx(3.783, abs=5e-4)
    # One rear axle: the axle itself.
    assert vehicle_preset("field").tractor_equivalent_wheelbase() == pytest.approx(3.0, rel=1e-12)


def test_reference_preset_is_default_like_design():
    assert reference_laden().name == "reference"


def test_field_combination_is_a_4x2_tractor_with_a_2_axle_trailer():
    # de Saxe & Cebon 2018 §4.1: a 6x2 tractor with its tag axle lifted and a tri-axle semi-trailer with its
    # front axle lifted, i.e. a 4x2 tractor and a 2-axle semi-trailer; unladen (lift axles up).
    p = vehicle_preset("field")
    assert [a.name for a in p.tractor.axles] == ["steer", "drive"]
    assert [a.x for a in p.trailer.axles] == [-7.7, -9.0]
    assert not any(a.steerable for a in p.trailer.axles)
    assert p.tractor_wheelbase() == pytest.approx(3.0)
    assert p.follow_point_offset == pytest.approx(12.0)
    # Equal loads on the two trailer axles: L_eq = (7.7² + 9.0²)/(7.7 + 9.0).
    assert p.equivalent_wheelbase() == pytest.approx((7.7**2 + 9.0**2) / (7.7 + 9.0), rel=1e-9)
    loads_t = p.axle_table.static_load / GRAVITY / 1000.0
    assert loads_t.sum() == pytest.approx((9841.0 + 7500.0) / 1000.0, rel=1e-12)
    # Moments about the axle-group centre, 8.35 m behind the kingpin, with the CG 4.0 m behind it.
    assert p.kingpin_load / (p.trailer.mass * GRAVITY) == pytest.approx(4.35 / 8.35, rel=1e-9)
