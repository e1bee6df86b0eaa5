"""One short rendered VISO-OT run under field conditions, shared by the tests that re-render a run's camera.

``roundabout-3`` at 672 × 196 px for 0.45 s (five camera frames) with a lens, a low sun with the lagging
auto-exposure and mount vibration (:data:`FIELD`). The animation's camera panel re-renders the run's frames in the
test's own process, so the run is made in a child process (which owns its renderer). It is made once a session: the
pytest-xdist workers share it through their common temporary directory, the first to need it making it under an
exclusive lock (``shared_runs.py``). Read only: a test that writes into it copies it first.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from shared_runs import shared_run

REPO = Path(__file__).resolve().parents[1]

FIELD = {
    "camera.lighting.sun": True,  # a low sun, shadows, sky, glare and the lagging auto-exposure
    "camera.flex.vibration_rms_deg": [0.05, 0.05, 0.05],
    "camera.lens.k1": -0.05,
}
"""Field conditions of the camera: lens, lighting and mount vibration."""

OVERRIDES = {"estimators.viso_ot": True, "duration_s": 0.45, "camera.width": 672, "camera.height": 196, **FIELD}
"""The run's overrides of ``roundabout-3``."""


def field_camera_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The run directory (made on the first call of the session, in a child process)."""

    def make(run_dir: Path) -> None:
        code = (
            "import sys; from pathlib import Path; from scenarios.config import load_scenario; "
            "from scenarios.run.runner import run_scenario; "
            f"run_scenario(load_scenario('roundabout-3', {OVERRIDES!r}), Path(sys.argv[1]), plots=False)"
        )
        subprocess.run([sys.executable, "-c", code, str(run_dir)], check=True, timeout=600, cwd=REPO)

    return shared_run(tmp_path_factory, "shared-field-camera-run", make)
