"""The README's numbers are the program's: each is read from the README's text and computed here, none written twice.

The vehicle table's lengths and masses against the catalogue (:func:`vehicle_model.combination.combination_summary`),
the Nordic combination's length in every page, the environment variables the program reads, and (slow: three runs of
the roundabout test, model only) the radii the README quotes for the reference combination and the LST, unsteered and
steered. A number is compared at the precision the README prints it (half a unit of its last digit).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from cli_runner import invoke as invoke_offtrack

from scenarios.config import load_scenario
from scenarios.run.runner import run_scenario
from vehicle_model.combination import catalogue_vehicle_names, combination_summary
from vehicle_model.presets import catalogue_vehicle

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
PAGES = {path.name: path.read_text(encoding="utf-8") for path in [ROOT / "README.md", *(ROOT / "docs").glob("*.md")]}
ROW = re.compile(r"^\| `([a-z0-9-]+)` \| (.+) \|$", re.M)
NUMBER = r"(\d+(?:\.\d+)?)"


def _agrees(shown: str, value: float) -> bool:
    """``shown`` (as printed) is ``value`` to its last digit."""
    decimals = len(shown.split(".")[1]) if "." in shown else 0
    return abs(float(shown) - value) <= 0.5 * 10.0**-decimals + 1e-9


def _vehicle_rows() -> dict[str, str]:
    names = set(catalogue_vehicle_names())
    return {name: text for name, text in ROW.findall(README) if name in names}


TRACTOR_SEMI_TRAILERS = ("reference", "reference-unladen", "lst", "lst-unladen", "field")
"""The presets whose README row gives no overall length (a tractor with one semi-trailer)."""


def test_the_vehicle_table_states_the_catalogues_lengths_and_masses() -> None:
    rows = _vehicle_rows()
    assert set(rows) == set(catalogue_vehicle_names())  # every preset has its row
    checked = 0
    for name, text in rows.items():
        spec = catalogue_vehicle(name)
        length, _, _ = combination_summary(spec)
        mass_t = sum(unit.mass for unit in spec.units) / 1000.0
        lengths = re.findall(NUMBER + r" m\b", text)
        if name not in TRACTOR_SEMI_TRAILERS:  # a combination's row
            assert any(_agrees(shown, length) for shown in lengths), (name, lengths, length)
            checked += 1
        for shown in re.findall(NUMBER + r" t\b", text):
            assert _agrees(shown, mass_t), (name, shown, mass_t)
    assert checked == len(rows) - len(TRACTOR_SEMI_TRAILERS)  # every longer combination's row was checked


def test_the_nordic_combination_has_one_length_in_every_page() -> None:
    length, _, _ = combination_summary(catalogue_vehicle("nordic-truck-dolly-semi"))
    found = {page: re.findall(r"Nordic\D{0,60}?" + NUMBER + " m", text) for page, text in PAGES.items()}
    shown = [(page, value) for page, values in found.items() for value in values]
    assert len(shown) >= 2  # the README and docs/vehicles.md
    assert all(_agrees(value, length) for _, value in shown), shown


def test_every_environment_variable_the_program_reads_is_documented() -> None:
    read = set()
    for package in ("scenarios", "sensor", "controller", "vehicle_model"):
        for path in (ROOT / package).rglob("*.py"):
            read |= set(re.findall(r"environ(?:\.get)?\(?\[?\"(OFFTRACK_[A-Z_]+)\"", path.read_text(encoding="utf-8")))
    assert "OFFTRACK_CACHE_DIR" in read
    documented = "".join(PAGES.values()) + (ROOT / "benchmarks" / "README.md").read_text(encoding="utf-8")
    assert sorted(v for v in read if v not in documented) == []
    assert "OFFTRACK_CACHE_DIR" in README and "OFFTRACK_NO_COMPILE" in README


def test_longer_combinations_steer_as_the_readme_says() -> None:
    steerable = {f"vehicle.units[{u}].axles[{a}].steerable": True for u in (1, 2) for a in (1, 2)}
    config = load_scenario(
        "roundabout-test",
        {"vehicle": "au-b-double", **steerable, "feedback": "zero_slip", "rear_feedback": ["zero_slip"]},
    )
    assert config.feedback == "zero_slip" and list(config.rear_feedback) == ["zero_slip"]
    assert "longer combinations run unsteered" not in README and "runs unsteered" not in README
    assert "every towed unit with steerable" in README


@pytest.fixture(scope="module")
def roundabout_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, dict]]:
    runs = {
        "reference": {"feedback": "none"},
        "lst unsteered": {"vehicle": "lst", "feedback": "none"},
        "lst steered": {"vehicle": "lst", "feedback": "zero_slip"},
    }
    out = {}
    for label, overrides in runs.items():
        run_dir = tmp_path_factory.mktemp(label.replace(" ", "-"))
        out[label] = (run_dir, run_scenario(load_scenario("roundabout-test", overrides), run_dir, plots=False))
    return out


@pytest.mark.slow
def test_the_roundabout_numbers_are_the_programs(roundabout_runs) -> None:
    inner = {label: metrics["roundabout_test"]["inner_radius_min"] for label, (_, metrics) in roundabout_runs.items()}
    quoted = {
        "reference": re.search(r"inner radius " + NUMBER + r" m against 5\.30 m", README)[1],
        "lst unsteered": re.search(r"reaches " + NUMBER + r" m and fails", README)[1],
        "lst steered": re.search(r"it passes with " + NUMBER + r" m", README)[1],
    }
    for label, shown in quoted.items():
        assert _agrees(shown, inner[label]), (label, shown, inner[label])
    cut = re.search(r"the trailer cuts " + NUMBER + r" m inside 5\.30 m: FAIL", README)[1]
    assert _agrees(cut, 5.30 - inner["reference"])


@pytest.mark.slow
def test_make_runs_verdict_is_one_everywhere(roundabout_runs) -> None:
    # make run: the reference, unsteered, fails the test: not held in metrics.json, and --check exits 4 on it
    run_dir, metrics = roundabout_runs["reference"]
    assert metrics["verdict"]["held"] is False
    assert [f["flag"] for f in metrics["verdict"]["flags"]] == ["roundabout_test_failed"]
    checked = invoke_offtrack(["report", str(run_dir), "--no-plots", "--check"])
    assert checked.exit_code == 4 and "not held: 1 miss(es)" in checked.stdout, checked.output
