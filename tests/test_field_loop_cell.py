"""``benchmarks/field_loop_cell.py``: the field-loop study's own case with settings appended, and its command line's
refusals (one line, exit 2, before any work)."""

from __future__ import annotations

import pytest

from benchmarks.field_loop_cell import case_from_arguments
from scenarios.studies.field_loop import field_loop_cases


def test_a_grid_cell_is_the_studys_own_case_with_the_settings_appended() -> None:
    """For the default subset's icy field cell, the case's overrides are the study's case's, then the settings
    (read as ``--set`` reads them), and its name and labels the study's."""
    study = next(
        case
        for case in field_loop_cases()
        if (labels := dict(case.labels))["camber"] == 5.0
        and labels["conditions"] == "field"
        and labels["feedback"] == "viso_ot_fused"
    )
    labels = dict(study.labels)
    cell = [labels["scenario"], labels["surface"], "5", "field", labels["alignment"], str(labels["seed"])]
    settings = ["camera.vo_covariance_model=sandwich", "fusion.vo_covariance_scale=1.0"]
    spec, out_dir, stem = case_from_arguments(["lst", *cell, "viso_ot_fused", "0", "out", *settings])
    assert spec.labels == study.labels and spec.name == study.name
    assert spec.overrides == (
        *study.overrides,
        ("camera.vo_covariance_model", "sandwich"),
        ("fusion.vo_covariance_scale", 1.0),
    )
    assert str(out_dir) == "out"
    assert stem == "_".join(["lst", *cell[:5], f"s{labels['seed']}", "viso_ot_fused"])


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ({4: "foggy"}, "argument conditions: invalid choice: 'foggy'"),
        ({7: "radar"}, "argument feedback: invalid choice: 'radar'"),
        ({8: "2"}, "argument full: invalid choice: 2"),
        ({10: "novalue"}, "--set 'novalue' must look like field.sub=value"),
        ({0: "no-such-vehicle"}, "--vehicle"),
    ],
)
def test_bad_arguments_are_refused_on_one_line(change, named, capsys) -> None:
    argv = ["lst", "roundabout-3", "dry", "0", "field", "aligned", "1", "viso_ot_fused", "0", "out", "seed=1"]
    for index, value in change.items():
        argv[index] = value
    with pytest.raises(SystemExit) as stop:
        case_from_arguments(argv)
    assert stop.value.code == 2
    error = capsys.readouterr().err.splitlines()
    assert len(error) == 1 and error[0].startswith("python -m benchmarks.field_loop_cell: error: "), error
    assert named in error[0], error
