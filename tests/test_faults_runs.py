"""Fault injection into one run's life: two processes into one ``--out``, a check of a run that did not complete,
numbers that are not numbers, impossible axle loads, a coupling past its limit, a stop on a long road, a cache
that cannot be written.

Each test injects its fault and checks what the README's failure table promises for it; the holder of a claimed
``--out`` is a real second process (the claim is a lock the kernel holds per process)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from scenarios.cli import app

REPO = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-c", "from scenarios.cli import main; main()"]


def invoke(*args: str):
    return CliRunner().invoke(app, list(args), prog_name="offtrack")


# --- one process per --out -------------------------------------------------------------------------------------


def _hold(directory: Path) -> subprocess.Popen:
    """A second process that claims ``directory`` (as a run writing there does) and waits."""
    code = (
        "import sys, time; from scenarios.run.claim import claim_directory; "
        "claim_directory(sys.argv[1]); print('held', flush=True); time.sleep(120)"
    )
    proc = subprocess.Popen([sys.executable, "-c", code, str(directory)], stdout=subprocess.PIPE, text=True, cwd=REPO)
    assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
    return proc


def test_a_second_process_into_a_claimed_out_is_refused_before_any_work(tmp_path: Path) -> None:
    out = tmp_path / "r"
    (out / "cases").mkdir(parents=True)
    (out / "config.yaml").write_text("the holder's\n")
    holder = _hold(out)
    try:
        for args in (
            ("run", "roundabout-test", "--duration", "1", "--no-plots", "--out", str(out)),
            ("run", "roundabout-test", "--duration", "1", "--no-plots", "--force", "--out", str(out)),
            ("study", "unit-steering", "--out", str(out)),  # resuming into it
            ("assess", "reference", "--out", str(out)),
        ):
            result = invoke(*args)
            assert result.exit_code == 2, (args, result.output)
            assert f"--out {out} is in use by process {holder.pid}" in result.output, result.output
            assert "Traceback" not in result.output
            assert sorted(p.name for p in out.iterdir()) == ["cases", "config.yaml"]  # nothing read, cleared, written
            assert (out / "config.yaml").read_text() == "the holder's\n"
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait(timeout=30)
    # A holder killed outright leaves no stale claim: the kernel dropped its lock with it.
    (out / "cases").rmdir()
    result = invoke("run", "roundabout-test", "--duration", "1", "--no-plots", "--force", "--out", str(out))
    assert result.exit_code == 0, result.output
    assert json.loads((out / "metrics.json").read_text())["status"] == "completed"


@pytest.mark.slow
def test_four_runs_started_together_into_one_out_leave_one_run(tmp_path: Path) -> None:
    out = tmp_path / "r"
    procs = [
        subprocess.Popen(
            [*CLI, "run", "roundabout-test", "--seed", str(s), "--duration", "3", "--no-plots", "--out", str(out)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=REPO,
        )
        for s in range(4)
    ]
    results = [(p, *p.communicate(timeout=600)) for p in procs]
    codes = sorted(p.returncode for p, _, _ in results)
    assert codes == [0, 2, 2, 2], [(p.returncode, err) for p, _, err in results]
    winner = next(i for i, (p, _, _) in enumerate(results) if p.returncode == 0)
    config = (out / "config.yaml").read_text()
    assert f"seed: {winner}\n" in config
    assert json.loads((out / "metrics.json").read_text())["rows"] > 0
