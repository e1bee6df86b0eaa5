"""Vehicles as data: the catalogue's YAML combinations give exactly the presets' numbers, and a combination that is
invalid, impossible or beyond the model is refused before any work in one line naming the field."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from scenarios.config import ConfigError, load_scenario, parse_assignment, validate_config
from vehicle_model.combination import CombinationSpec, catalogue_vehicle_data, combination_summary
from vehicle_model.parameters import AxleParams, TractorParams, TrailerParams, VehicleParams
from vehicle_model.presets import VEHICLE_PRESETS, catalogue_vehicle, vehicle_preset

# -- the presets as Python defined them before they became YAML files: the numbers the catalogue must give ----------

_TRACTOR_6X2 = TractorParams(
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
_TRACTOR_4X2 = TractorParams.model_validate(
    _TRACTOR_6X2.model_dump() | {"axles": _TRACTOR_6X2.model_dump()["axles"][:2]}
)


def _box(mass: float, front_x: float, rear_x: float, width: float, cg_x: float) -> float:
    length, centre = front_x - rear_x, 0.5 * (front_x + rear_x)
    return mass * (length**2 + width**2) / 12.0 + mass * (cg_x - centre) ** 2


def _trailer_13_6(mass: float, cg_x: float, yaw_inertia: float, first: bool = True) -> TrailerParams:
    axles = (AxleParams(name="trailer1", x=-6.4),) if first else ()
    axles += (AxleParams(name="trailer2", x=-7.7), AxleParams(name="trailer3", x=-9.0))
    return TrailerParams(
        mass=mass, yaw_inertia=yaw_inertia, cg_x=cg_x, front_x=1.6, rear_x=-12.0, width=2.55, axles=axles
    )


def _trailer_lst(mass: float, cg_x: float) -> TrailerParams:
    return TrailerParams(
        mass=mass,
        yaw_inertia=_box(mass, 1.6, -14.05, 2.55, cg_x),
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


SEMI_TRAILER_PRESETS = {
    "reference": VehicleParams(
        name="reference", tractor=_TRACTOR_6X2, trailer=_trailer_13_6(33_101.0, -4.3344, 5.7348e5)
    ),
    "reference-unladen": VehicleParams(
        name="reference-unladen",
        tractor=_TRACTOR_6X2,
        trailer=_trailer_13_6(7_500.0, -4.0, _box(7_500.0, 1.6, -12.0, 2.55, -4.0)),
    ),
    "lst": VehicleParams(name="lst", tractor=_TRACTOR_6X2, trailer=_trailer_lst(33_101.0, -5.35)),
    "lst-unladen": VehicleParams(name="lst-unladen", tractor=_TRACTOR_6X2, trailer=_trailer_lst(8_500.0, -4.9)),
    "field": VehicleParams(
        name="field",
        tractor=_TRACTOR_4X2,
        trailer=_trailer_13_6(7_500.0, -4.0, _box(7_500.0, 1.6, -12.0, 2.55, -4.0), first=False),
    ),
}
"""The five tractor–semi-trailer presets written out in code, field by field: each catalogue file must give exactly
its preset."""


LONGER = {
    "au-b-double": (24.45, "tractor + semi + semi"),
    "au-a-double": (34.55, "tractor + semi + dolly + semi"),
    "au-b-double-steered": (24.45, "tractor + semi + semi"),
    "au-a-double-steered": (34.55, "tractor + semi + dolly + semi"),
    "nordic-truck-dolly-semi": (25.05, "truck + dolly + semi"),
    "eu-truck-centre-axle": (18.70, "truck + centre-axle"),
}
"""The catalogue's other combinations: overall length [m] (within 25, 53.5, 25.25 and 18.75 m, their limits) and
units."""


def test_the_steered_doubles_are_the_doubles_with_the_rear_two_axles_of_each_semi_trailer_steerable() -> None:
    for name in ("au-b-double", "au-a-double"):
        plain, steered = VEHICLE_PRESETS[name](), VEHICLE_PRESETS[f"{name}-steered"]()
        flags = [[a.steerable for a in unit.axles] for unit in steered.trailers]
        semi = [unit.front_load for unit in steered.trailers]
        assert flags == [[False, True, True] if s else [False] * len(f) for s, f in zip(semi, flags, strict=True)]
        unsteer = [[a.model_copy(update={"steerable": False}) for a in unit.axles] for unit in steered.trailers]
        assert unsteer == [list(unit.axles) for unit in plain.trailers]  # nothing else differs on the axles
        assert steered.trailers[0].mass == plain.trailers[0].mass and steered.tractor == plain.tractor


def test_the_catalogue_holds_the_five_tractor_semi_trailers_and_the_longer_combinations() -> None:
    assert sorted(VEHICLE_PRESETS) == sorted([*SEMI_TRAILER_PRESETS, *LONGER])


@pytest.mark.parametrize("name", sorted(LONGER))
def test_a_longer_preset_is_within_its_limits_and_carries_its_weight(name: str) -> None:
    length, units = combination_summary(catalogue_vehicle(name))[:2]
    assert length == pytest.approx(LONGER[name][0], abs=1e-9) and units == LONGER[name][1]
    params = vehicle_preset(name)
    assert params.axle_table.static_load.sum() == pytest.approx(sum(u.mass for u in params.units) * 9.81, rel=1e-12)
    assert all(u.width <= 2.55 for u in params.units)


@pytest.mark.parametrize("name", sorted(SEMI_TRAILER_PRESETS))
def test_each_catalogue_file_gives_exactly_its_preset(name: str) -> None:
    params = vehicle_preset(name)
    assert params == SEMI_TRAILER_PRESETS[name]  # every field, bit for bit
    assert params.model_dump_json() == SEMI_TRAILER_PRESETS[name].model_dump_json()
    assert CombinationSpec.model_validate(catalogue_vehicle_data(name)).params() == SEMI_TRAILER_PRESETS[name]


def test_each_preset_file_says_where_its_numbers_come_from() -> None:
    for name in SEMI_TRAILER_PRESETS:
        assert len(CombinationSpec.model_validate(catalogue_vehicle_data(name)).source) > 80, name


def test_a_unit_measured_from_elsewhere_gives_the_same_vehicle() -> None:
    """Stations from the tractor's front bumper and from the trailer's front: moved to the model's origins."""
    data = catalogue_vehicle_data("lst")
    tractor, trailer = data["units"]
    for key in ("cg_x", "front_x", "rear_x"):
        tractor[key] -= 1.4
        trailer[key] -= 1.6
    for axle in tractor["axles"]:
        axle["x"] -= 1.4
    for axle in trailer["axles"]:
        axle["x"] -= 1.6
    trailer["coupling"] = {"kind": "fifth_wheel", "ahead_x": -3.4 - 1.4, "x": -1.6}
    moved = CombinationSpec.model_validate(data).params()
    preset = SEMI_TRAILER_PRESETS["lst"]
    for unit in ("tractor", "trailer"):
        a, b = getattr(moved, unit), getattr(preset, unit)
        for key in ("cg_x", "front_x", "rear_x", "yaw_inertia"):
            assert getattr(a, key) == pytest.approx(getattr(b, key), abs=1e-9), (unit, key)
        assert [x.x for x in a.axles] == pytest.approx([x.x for x in b.axles], abs=1e-12)
    assert moved.tractor.fifth_wheel_x == pytest.approx(-3.4, abs=1e-12)


def test_lifted_axles_are_left_out_and_only_a_liftable_axle_lifts() -> None:
    params = vehicle_preset("field")
    assert [a.name for a in params.tractor.axles] == ["steer", "drive"]
    assert [a.name for a in params.trailer.axles] == ["trailer2", "trailer3"]
    data = catalogue_vehicle_data("reference")
    data["units"][1]["axles"][0]["lifted"] = True
    with pytest.raises(ValueError, match=r"lifted: axle 'trailer1' is not liftable"):
        CombinationSpec.model_validate(data)


# -- faults: each refused in one line naming the field -------------------------------------------------------------


def _units(data: dict) -> list[dict]:
    return data["units"]


def _no_trailer_axle(d: dict) -> None:
    _units(d)[1]["axles"] = []


def _coupling_off_the_tractor(d: dict) -> None:
    _units(d)[1]["coupling"]["ahead_x"] = -9.0


def _kingpin_off_the_trailer(d: dict) -> None:
    _units(d)[1]["coupling"]["x"] = 3.0


def _axle_off_its_body(d: dict) -> None:
    _units(d)[1]["axles"][2]["x"] = -16.0


def _cg_off_the_body(d: dict) -> None:
    _units(d)[0]["cg_x"] = 2.0


def _dolly_without_drawbar(d: dict) -> None:
    dolly = {
        "kind": "converter_dolly",
        "mass": 2500.0,
        "yaw_inertia": "box",
        "cg_x": -1.0,
        "front_x": 0.0,
        "rear_x": -2.0,
        "width": 2.5,
        "axles": [{"name": "dolly1", "x": -1.0}],
    }
    _units(d).insert(1, dolly)


def _trailer_without_coupling(d: dict) -> None:
    del _units(d)[1]["coupling"]


def _negative_mass(d: dict) -> None:
    _units(d)[1]["mass"] = -1.0


def _infinite_inertia(d: dict) -> None:
    _units(d)[0]["yaw_inertia"] = float("inf")


def _nan_tyre(d: dict) -> None:
    _units(d)[1]["axles"][1]["tyre"] = {"pky1": float("nan")}


def _unknown_kind(d: dict) -> None:
    _units(d)[1]["kind"] = "semitrailer"


def _driven_trailer_axle(d: dict) -> None:
    _units(d)[1]["axles"][0]["driven"] = True


def _tractor_second(d: dict) -> None:
    d["units"] = [d["units"][1], d["units"][0]]


FAULTS = [
    (_no_trailer_axle, "units[1].axles", "has no axle"),
    (_coupling_off_the_tractor, "units[1].coupling.ahead_x", "off units[0]'s body"),
    (_kingpin_off_the_trailer, "units[1].coupling.x", "off the semi_trailer's body"),
    (_axle_off_its_body, "units[1].axles[2].x", "lies off the body"),
    (_cg_off_the_body, "units[0].cg_x", "must lie on the body"),
    (_dolly_without_drawbar, "units[1].coupling", "drawbar"),
    (_trailer_without_coupling, "units[1].coupling", "fifth_wheel"),
    (_negative_mass, "units[1].mass", "greater than 0"),
    (_infinite_inertia, "units[0].yaw_inertia", "finite"),
    (_nan_tyre, "units[1].axles[1].tyre.pky1", "finite"),
    (_unknown_kind, "units[1].kind", "semi_trailer"),
    (_driven_trailer_axle, "units[1].axles", "driven"),
    (_tractor_second, "units[0].kind", "tractor or rigid_truck"),
]


@pytest.mark.parametrize(("fault", "field", "words"), FAULTS, ids=[f[0].__name__.strip("_") for f in FAULTS])
def test_a_bad_combination_is_refused_before_any_work_naming_the_field(fault, field: str, words: str) -> None:
    data = catalogue_vehicle_data("reference")
    fault(data)
    with pytest.raises(ConfigError) as info:
        validate_config({"vehicle": data})
    lines = str(info.value).splitlines()[1:]
    assert len(lines) == 1, info.value  # one line
    assert f"vehicle.{field}" in lines[0] and words in lines[0], lines[0]


def test_a_dolly_carries_the_semi_trailer_on_it_and_nothing_on_its_drawbar() -> None:
    data = catalogue_vehicle_data("reference")
    _dolly_without_drawbar(data)
    dolly = _units(data)[1]
    dolly["coupling"] = {"kind": "drawbar", "ahead_x": -5.0, "x": 2.0}
    _units(data)[2]["coupling"]["ahead_x"] = -1.0  # the semi-trailer on the dolly's fifth wheel
    params = CombinationSpec.model_validate(data).params()  # an A-double-like layout: tractor, dolly, semi
    assert params.n_units == 3 and not params.trailer.front_load
    loads, kingpins = params._loads()
    assert kingpins[0] == 0.0  # the drawbar, hinged in pitch, carries no load
    semi_kingpin = kingpins[1]
    assert loads[1].sum() == pytest.approx(2500.0 * 9.81 + semi_kingpin, rel=1e-12)  # the dolly's axle carries both
    weight = sum(u.mass for u in params.units) * 9.81
    assert params.axle_table.static_load.sum() == pytest.approx(weight, rel=1e-12)
    dolly["kind"] = "full_trailer"  # one body for a dolly and a semi-trailer: not the yaw plane's
    with pytest.raises(ValueError, match=r"units\[1\]\.kind = 'full_trailer': .* converter_dolly and a semi_trailer"):
        CombinationSpec.model_validate(data).params()


# -- the vehicle in a run's configuration --------------------------------------------------------------------------


def test_a_vehicle_file_is_run_and_written_into_the_resolved_config(tmp_path: Path) -> None:
    data = catalogue_vehicle_data("reference")
    data["units"][1]["axles"][2]["steerable"] = True
    path = tmp_path / "my-truck.yaml"
    path.write_text(yaml.safe_dump({k: v for k, v in data.items() if k != "name"}))
    config = load_scenario("roundabout-test", {"vehicle": str(path), "feedback": "truth"})
    assert config.vehicle_name == "my-truck"
    assert [a.steerable for a in config.vehicle_params().trailer.axles] == [False, False, True]
    again = validate_config(yaml.safe_load(yaml.safe_dump(config.model_dump(mode="json"))))
    assert again == config and again.vehicle_params() == config.vehicle_params()  # reproduces without the file


def test_set_reaches_an_axle_of_a_preset() -> None:
    key, value = parse_assignment("vehicle.units[1].axles[0].steerable=true")
    config = load_scenario("roundabout-test", {"vehicle": "reference", key: value})
    assert [a.steerable for a in config.vehicle_params().trailer.axles] == [True, False, False]
    assert config.vehicle_params().tractor == vehicle_preset("reference").tractor
    with pytest.raises(ConfigError, match=r"vehicle\.units\[3\]: no item 3; units has 2"):
        load_scenario("roundabout-test", {"vehicle.units[3].mass": 1.0})


def test_steering_feedback_needs_a_steerable_axle_of_the_vehicle_given() -> None:
    with pytest.raises(ConfigError, match="no steerable axle on its first towed unit"):
        load_scenario("roundabout-test", {"vehicle": "reference", "feedback": "truth"})
    config = load_scenario(
        "roundabout-test", {"vehicle": "reference", "vehicle.units[1].axles[2].steerable": True, "feedback": "truth"}
    )
    assert config.feedback == "truth"


def test_a_missing_vehicle_file_is_named() -> None:
    with pytest.raises(ConfigError, match=r"vehicle file nowhere\.yaml does not exist"):
        load_scenario("roundabout-test", {"vehicle": "nowhere.yaml"})


def test_the_listing_summary_gives_length_units_and_steerable_axles() -> None:
    length, units, steerable = combination_summary(CombinationSpec.model_validate(catalogue_vehicle_data("lst")))
    # front bumper 1.4 m ahead of the steer axle, kingpin 3.4 m behind it, trailer rear 14.05 m behind the kingpin
    assert length == pytest.approx(1.4 + 3.4 + 14.05, abs=1e-12)
    assert units == "tractor + semi" and steerable == "steer, trailer2, trailer3"


def test_the_documented_example_is_valid_and_gives_the_lst() -> None:
    """docs/vehicles.md's complete example (stations from the front of each unit) is the ``lst`` preset."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "vehicles.md").read_text(encoding="utf-8")
    block = text.split("```yaml\n", 1)[1].split("```", 1)[0]
    example = CombinationSpec.model_validate(yaml.safe_load(block)).params()
    lst = SEMI_TRAILER_PRESETS["lst"]
    for unit in ("tractor", "trailer"):
        a, b = getattr(example, unit).model_dump(), getattr(lst, unit).model_dump()
        for key, value in b.items():
            if isinstance(value, float):
                assert a[key] == pytest.approx(value, rel=1e-12, abs=1e-12), (unit, key)
        assert [x["x"] for x in a["axles"]] == pytest.approx([x["x"] for x in b["axles"]], abs=1e-12)
        assert [x["steerable"] for x in a["axles"]] == [x["steerable"] for x in b["axles"]]


def test_the_command_line_takes_a_vehicle_file_and_sets_its_axles(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from scenarios.cli import app

    path = tmp_path / "truck.yaml"
    path.write_text(yaml.safe_dump(catalogue_vehicle_data("reference")))
    args = ["config", "roundabout-test", "--vehicle", str(path), "--set", "vehicle.units[1].axles[1].steerable=true"]
    result = CliRunner().invoke(app, args, prog_name="offtrack")
    assert result.exit_code == 0, result.output
    config = validate_config(yaml.safe_load(result.stdout))  # the resolved file holds the vehicle inline
    assert [a.steerable for a in config.vehicle_params().trailer.axles] == [False, True, False]
    bad = CliRunner().invoke(app, [*args[:4], "--set", "vehicle.units[1].axles[0].x=-20"], prog_name="offtrack")
    assert bad.exit_code == 2 and "vehicle.units[1].axles[0].x = -20.0 m" in bad.output


def test_an_exported_run_names_an_inline_vehicle(tmp_path: Path) -> None:
    from scenarios.export.table import _metadata

    config = load_scenario("roundabout-test", {"vehicle.units[1].mass": 30000.0})
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(config.model_dump(mode="json")))
    assert _metadata(tmp_path)["vehicle"] == "reference"


def test_a_recording_rig_takes_a_vehicle_file_and_keeps_it_inline(tmp_path: Path) -> None:
    from scenarios.recorded.rig import rig_from_fields
    from vehicle_model.errors import InputError

    data = catalogue_vehicle_data("lst")
    data["units"][1]["rear_x"] = -13.0
    path = tmp_path / "short-lst.yaml"
    path.write_text(yaml.safe_dump({k: v for k, v in data.items() if k != "name"}))
    rig = rig_from_fields({"vehicle": str(path), "psi_c2v_deg": 180, "lever_arm_m": [-13.0, 0.0, 3.0]}, "--rig r.yaml")
    assert rig.params.trailer.rear_x == -13.0 and rig.params.name == "short-lst"
    assert rig.file["vehicle"]["units"][1]["rear_x"] == -13.0  # what the recorded run writes: the file's content
    with pytest.raises(InputError, match=r"^--rig r\.yaml: vehicle: not a preset; did you mean 'lst'\?$"):
        rig_from_fields({"vehicle": "lts", "psi_c2v_deg": 180, "lever_arm_m": [-13.0, 0.0, 3.0]}, "--rig r.yaml")


def test_an_axle_keeps_its_own_tyre() -> None:
    data = catalogue_vehicle_data("reference")
    data["units"][1]["axles"][2]["tyre"] = {"pky1": 9.0, "fz_nominal": 40000.0}
    params = CombinationSpec.model_validate(data).params()
    tyres = [a.tyre for a in params.trailer.axles]
    assert (tyres[2].pky1, tyres[2].fz_nominal) == (9.0, 40000.0)
    assert tyres[0] == SEMI_TRAILER_PRESETS["reference"].trailer.axles[0].tyre
    assert params.axle_cornering_stiffness()[-1] != params.axle_cornering_stiffness()[-2]  # the model sees it
