"""The stable-baselines3 example (``benchmarks/train_ppo.py``): a residual PPO policy against the designed and
the Optuna-tuned PID on held-out roads. Skipped without the ``rl`` extra; the default run trains a few thousand
steps on a short road, the slow one a real budget."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "train_ppo.py"

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("stable_baselines3") is None, reason="needs the rl extra (stable-baselines3)"
)


def _train(tmp_path: Path, *args: str, timeout: float) -> dict:
    """Run the script in its own process: PyTorch (through Triton) can crash on import in a process that has
    already loaded the renderer's libraries, so it is never imported into the test process."""
    out = tmp_path / "ppo.json"
    cmd = [sys.executable, str(SCRIPT), *args, "--json", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "| controller |" in done.stdout
    return json.loads(out.read_text())


def test_train_ppo_example_runs_and_tabulates_the_comparison(tmp_path: Path) -> None:
    out = _train(
        tmp_path, "--short", "--steps", "2048", "--n-steps", "512", "--held-out", "2", "--trials", "2", timeout=300
    )
    table = out["table"]
    for name in ("designed PID", "Optuna-tuned PID", "designed PID + PPO residual"):
        assert f"| {name} |" in table
        assert len(out["held_out"][name]) == 2
    designed = out["held_out"]["designed PID"]
    assert all(s["termination_reason"] == "" and s["rms_offtracking"] > 0 for s in designed)
    assert set(out["tuned_gains"]) == {"kp", "ki", "kd"}


@pytest.mark.slow
def test_residual_ppo_does_not_lose_to_the_designed_pid_on_held_out_ice(tmp_path: Path) -> None:
    out = _train(tmp_path, "--steps", "50000", "--held-out", "4", "--trials", "0", timeout=1800)
    rms = {name: sum(s["rms_offtracking"] for s in rows) for name, rows in out["held_out"].items()}
    assert rms["designed PID + PPO residual"] <= 1.05 * rms["designed PID"]
