"""The open-loop screening script of the fused filter (``benchmarks/fusion_open_loop.py``): its input checks, which
run before any rendering."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "fusion_open_loop.py"


def load_script():
    spec = importlib.util.spec_from_file_location("fusion_open_loop", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_settings_are_read_as_yaml_values() -> None:
    script = load_script()
    assert script.parse_set(["fusion.tractor_slip=0.005", "fusion.kinematic_error_model=state"]) == [
        ("fusion.tractor_slip", 0.005),
        ("fusion.kinematic_error_model", "state"),
    ]
    with pytest.raises(SystemExit, match="expected key=value"):
        script.parse_set(["fusion.tractor_slip"])


def test_cells_that_match_no_case_stop_before_any_work(tmp_path: Path) -> None:
    script = load_script()
    with pytest.raises(SystemExit, match="no fused-feedback case of the full grid matches"):
        script.main([str(tmp_path / "out"), "--cells", "no-such-manoeuvre", "--cache", str(tmp_path / "cache")])
    assert not (tmp_path / "out").exists()
    cell = script.cached_frames(tmp_path, "scenario-a_b")
    assert cell == tmp_path / "a_b" and not script.is_cached(tmp_path, "scenario-a_b")
    (cell / "0123456789abcdef").mkdir(parents=True)
    assert not script.is_cached(tmp_path, "scenario-a_b")  # a camera's directory without frames
    (cell / "0123456789abcdef" / "000000.npz").write_bytes(b"")
    assert script.is_cached(tmp_path, "scenario-a_b")
