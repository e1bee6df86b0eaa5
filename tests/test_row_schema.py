"""The row schema: a participant records exactly its declared columns, each with its role in the file, and the
metrics find their columns by role — also in a run written before columns had roles."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import yaml

from scenarios.config import load_scenario
from scenarios.loop.cosimulation import CoSimulation
from scenarios.loop.participant import ROLES, Column, SchemaError
from scenarios.loop.recording import RowRecorder
from scenarios.loop.schema import (
    RecordedColumns,
    command_columns,
    estimate_columns,
    roles_from_names,
    schema_of,
    std_column,
)
from scenarios.run.drive import simulate
from scenarios.run.metrics import compute_metrics, estimator_names, unit_estimator_names
from scenarios.run.report import rebuild_report
from scenarios.run.results import (
    ESTIMATOR_KEY,
    ROLE_KEY,
    TIMESERIES_FILE,
    VEHICLE_UNIT_KEY,
    TimeSeriesWriter,
    read_timeseries,
)
from scenarios.run.runner import run_scenario
from scenarios.setup.build import build_scenario
from vehicle_model.offtracking import OfftrackingEstimate

QUARTER = {"vehicle": "lst", "path.turns": 0.25, "path.entry_length": 15.0, "path.exit_length": 5.0}
B_DOUBLE = Path(__file__).parent / "data" / "combinations" / "b-double.yaml"


class Fake:
    """A participant that records what it is told."""

    def __init__(self, name: str, columns: tuple[Column, ...]) -> None:
        self.name = name
        self.columns = columns


class Pending:
    """A pending part of a row."""

    def __init__(self, values: dict[str, float], ready: bool) -> None:
        self._values, self.ready = values, ready

    def values(self) -> dict[str, float]:
        return self._values


def _cast() -> list[Fake]:
    return [
        Fake("clock", (Column("time", "s", role="time"),)),
        Fake("probe", (Column("a", "m", role="diagnostic"), Column("b", "m", role="diagnostic"))),
    ]


def test_a_record_with_an_undeclared_key_is_refused_naming_the_participant_and_the_key() -> None:
    recorder = RowRecorder(_cast())
    recorder.add([{"time": 0.0}, {"a": 1.0, "b": 2.0}])
    with pytest.raises(SchemaError, match=r"participant 'probe' recorded 'c', which it does not declare"):
        recorder.add([{"time": 0.1}, {"a": 1.0, "b": 2.0, "c": 3.0}])
    with pytest.raises(SchemaError, match=r"participant 'clock' recorded 'a'"):  # another's column is not its own
        recorder.add([{"time": 0.1, "a": 1.0}, {"a": 1.0, "b": 2.0}])


def test_a_pending_part_with_an_undeclared_key_is_refused_when_it_arrives() -> None:
    recorder = RowRecorder(_cast())
    with pytest.raises(SchemaError, match=r"participant 'probe' recorded 'z'"):
        recorder.add([{"time": 0.0}, Pending({"a": 1.0, "z": 0.0}, ready=True)])


def test_a_declared_column_never_written_in_a_run_is_refused() -> None:
    recorder = RowRecorder(_cast())
    for t in (0.0, 0.1):
        recorder.add([{"time": t}, {"a": 1.0}])  # "b" declared, never written
    with pytest.raises(SchemaError, match=r"participant 'probe' declares 'b' but never wrote it in a run of 2 rows"):
        recorder.check_written()


def test_a_participant_of_the_loop_that_leaves_a_declared_column_unwritten_fails_its_run() -> None:
    class Silent:
        name = "silent"
        columns = (Column.estimate("silent", "declared, never written"),)

        def update(self, tick: object) -> OfftrackingEstimate:
            return OfftrackingEstimate.of(None)

        def record(self) -> dict[str, float]:
            return {}

    setup = build_scenario(load_scenario("roundabout-3", {**QUARTER, "duration_s": 0.5}))
    cosim = CoSimulation(setup)
    cosim.estimators["silent"] = Silent()
    cosim.cast = (*cosim.cast, cosim.estimators["silent"])
    cosim.recorder = RowRecorder(cosim.cast)
    while not cosim.done:
        cosim.step()
    with pytest.raises(SchemaError, match=r"participant 'silent' declares 'offtracking_silent' but never wrote it"):
        cosim.finish()


def test_a_column_written_on_some_ticks_or_as_nan_is_written() -> None:
    recorder = RowRecorder(_cast())
    recorder.add([{"time": 0.0}, {"a": 1.0, "b": math.nan}])
    recorder.add([{"time": 0.1}, {"a": 2.0}])  # "b" unknown on this tick: NaN, and written once already
    recorder.close()
    columns = recorder.arrays()
    assert np.isnan(columns["b"]).all() and columns["a"].tolist() == [1.0, 2.0]
    assert [c.name for c in columns.schema] == ["time", "a", "b"]


def test_a_pending_part_that_never_arrives_is_the_recorders_nan_not_a_fault() -> None:
    recorder = RowRecorder(_cast())
    recorder.add([{"time": 0.0}, Pending({"a": 1.0, "b": 2.0}, ready=False)])
    recorder.check_written()  # still in flight: not judged
    recorder.close()  # a stopped run: the frame never came
    recorder.check_written()
    assert np.isnan(recorder.arrays()["a"]).all()


def test_an_empty_run_has_nothing_to_report() -> None:
    recorder = RowRecorder(_cast())
    recorder.close()
    recorder.check_written()


def test_a_column_without_a_role_or_declared_twice_is_refused() -> None:
    with pytest.raises(SchemaError, match="declares 'x' without a role"):
        RowRecorder([Fake("bare", (Column("x", "m"),))])
    with pytest.raises(SchemaError, match="'time' is declared by 'clock' and by 'again'"):
        RowRecorder([*_cast(), Fake("again", (Column("time", "s", role="time"),))])
    with pytest.raises(ValueError, match="role 'guess' is not one of"):
        Column("x", "m", role="guess")
    with pytest.raises(ValueError, match="names its estimator and vehicle unit"):
        Column("offtracking_x", "m", role="estimate")


def test_the_time_series_writer_refuses_an_undeclared_key_and_names_the_columns_never_written(tmp_path) -> None:
    writer = TimeSeriesWriter(tmp_path / TIMESERIES_FILE, [Column("time", "s", role="time"), "x", "y"])
    writer.append({"time": 0.0, "x": 1.0})
    with pytest.raises(SchemaError, match="has no column 'q'"):
        writer.append({"time": 0.1, "q": 1.0})
    writer.close()
    assert writer.unwritten == ["y"]


# ------------------------------------------------------------------ a real run


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("schema-run")
    config = load_scenario(
        "roundabout-3",
        {**QUARTER, "feedback": "truth", "duration_s": 8.0, "estimators.zero_slip": True},
    )
    run_scenario(config, out, plots=False)
    return out


def test_every_column_of_a_run_carries_its_role_in_the_file(run_dir: Path) -> None:
    schema = pq.read_table(run_dir / TIMESERIES_FILE).schema
    assert len(schema) > 30
    for field in schema:
        metadata = field.metadata or {}
        assert metadata.get(ROLE_KEY, b"").decode() in ROLES, field.name
    truth = schema.field("offtracking_truth").metadata
    assert (truth[ROLE_KEY], truth[VEHICLE_UNIT_KEY], truth[ESTIMATOR_KEY]) == (b"estimate", b"2", b"truth")
    assert schema.field("X").metadata[VEHICLE_UNIT_KEY] == b"1"
    assert schema.field("steer_trailer3").metadata[ROLE_KEY] == b"command"
    columns = read_timeseries(run_dir)
    assert isinstance(columns, RecordedColumns) and [c.name for c in columns.schema] == list(columns)
    assert set(estimate_columns(columns)) == {("truth", 2), ("zero_slip", 2)}


def _without_roles(columns: RecordedColumns) -> dict[str, np.ndarray]:
    return dict(columns)  # names only: what the name grammar makes of them


def test_roles_select_the_columns_the_names_did(run_dir: Path) -> None:
    columns = read_timeseries(run_dir)
    named = _without_roles(columns)
    assert estimator_names(columns) == estimator_names(named) == ["zero_slip"]
    assert list(estimate_columns(columns)) == list(estimate_columns(named))
    assert [c.name for c in command_columns(columns, 2, "rad")] == [c.name for c in command_columns(named, 2, "rad")]
    assert [c.name for c in command_columns(columns, 2, "rad")] == ["steer_trailer2", "steer_trailer3"]


def test_an_older_run_without_roles_is_reported_with_the_same_numbers(run_dir: Path, tmp_path: Path) -> None:
    metrics = json.loads((run_dir / "metrics.json").read_text())
    old = tmp_path / "old"
    old.mkdir()
    for name in ("config.yaml", "metrics.json"):
        (old / name).write_bytes((run_dir / name).read_bytes())
    table = pq.read_table(run_dir / TIMESERIES_FILE)
    fields = [
        pa.field(f.name, f.type, metadata={k: v for k, v in f.metadata.items() if k in (b"unit", b"description")})
        for f in table.schema
    ]
    (old / TIMESERIES_FILE).mkdir()
    pq.write_table(table.cast(pa.schema(fields)), old / TIMESERIES_FILE / "part-000000.parquet")
    assert all(ROLE_KEY not in (f.metadata or {}) for f in pq.read_table(old / TIMESERIES_FILE).schema)
    rebuilt = rebuild_report(old, plots=False)
    for key in ("offtracking", "verdict", "trailer_steering", "roundabout_test", "swept_path"):
        assert json.dumps(rebuilt[key], sort_keys=True) == json.dumps(metrics[key], sort_keys=True), key


def test_the_name_grammar_of_older_runs_gives_the_declared_roles() -> None:
    vehicle = {"name": "b-double", **yaml.safe_load(B_DOUBLE.read_text(encoding="utf-8"))}
    config = load_scenario(
        "roundabout-3", {"vehicle": vehicle, "feedback": "none", "duration_s": 3.0, "estimators.zero_slip": True}
    )
    setup = build_scenario(config)
    _, columns = simulate(setup)
    assert isinstance(columns, RecordedColumns)
    declared = estimate_columns(columns)
    assert set(declared) == {("truth", 2), ("zero_slip", 2), ("truth", 3), ("zero_slip", 3)}
    bare = [dataclasses.replace(c, role="", vehicle_unit=None, estimator=None) for c in columns.schema]
    inferred = {c.name: c for c in roles_from_names(bare)}
    for key, column in declared.items():
        assert (inferred[column.name].estimator, inferred[column.name].vehicle_unit) == key
    assert unit_estimator_names(columns, 3) == unit_estimator_names(dict(columns), 3) == ["zero_slip3"]
    same = compute_metrics("b", "none", setup.params, columns, estimator_names(columns), None, (0.0, 0.0))
    named = compute_metrics("b", "none", setup.params, dict(columns), estimator_names(dict(columns)), None, (0.0, 0.0))
    assert json.dumps(same, sort_keys=True) == json.dumps(named, sort_keys=True)
    assert "zero_slip" in same["offtracking"]["units"]["3"]["estimators"]


def test_a_std_is_found_by_its_role_and_in_an_older_run_by_its_name() -> None:
    declared = [Column.estimate("fused", "x"), Column.std("fused"), Column("fused_std_part", "m", role="diagnostic")]
    assert std_column(declared, "fused").name == "offtracking_fused_std"
    assert std_column(declared, "other") is None
    named = {"offtracking_fused": np.zeros(1), "offtracking_fused_std": np.zeros(1)}
    assert std_column(named, "fused").name == "offtracking_fused_std"
    assert [c.role for c in schema_of(named)] == ["estimate", "std"]
