"""Every notebook runs top to bottom with its default parameters (outputs are not kept).

The default suite runs the two light notebooks with a smaller parameter set, given in a cell inserted after the
notebook's ``parameters`` cell (as papermill does): every cell still runs, on fewer cases. Each notebook's own
defaults run under ``make test-all``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOK_DIR = Path(__file__).parent.parent / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.ipynb"))


@pytest.fixture(scope="module")
def kernel_name(tmp_path_factory):
    # A kernelspec that runs this interpreter, so the notebooks see exactly the installed project.
    root = tmp_path_factory.mktemp("jupyter")
    spec = root / "kernels" / "offtrack-test"
    spec.mkdir(parents=True)
    argv = [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"]
    (spec / "kernel.json").write_text(json.dumps({"argv": argv, "display_name": "offtrack", "language": "python"}))
    import os

    previous = os.environ.get("JUPYTER_PATH")
    os.environ["JUPYTER_PATH"] = str(root) + (os.pathsep + previous if previous else "")
    yield "offtrack-test"
    if previous is None:
        os.environ.pop("JUPYTER_PATH", None)
    else:
        os.environ["JUPYTER_PATH"] = previous


def test_there_are_notebooks():
    names = {p.stem for p in NOTEBOOKS}
    assert {
        "roundabout_test",
        "estimators_under_slip",
        "controller_design_and_tuning",
        "paper_section3",
        "paper_section4",
    } <= names


HEAVY_NOTEBOOKS = {"paper_section4", "paper_section3", "estimators_under_slip"}
"""Run only with ``make test-all``: paper_section4 renders six field-condition cases (~4 min on 2 cores); the §3 and
estimators-under-slip notebooks run their studies' subsets (~50 s each), whose code the default suite tests in
``test_sweep.py`` and ``test_figures.py``. The light notebooks' own defaults also run only there (their small
parameters run by default)."""


def test_every_notebook_is_committed_without_outputs() -> None:
    for path in NOTEBOOKS:
        notebook = nbformat.read(path, as_version=4)
        assert all(not cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code"), path.name


SMALL_PARAMETERS = {
    # one surface (ice), one combination (steered: its controller runs too; an unsteered one is the same code with
    # another configuration), and twice the speed (half the simulated time of the circuit)
    "roundabout_test": 'SPEED_KMH = 10.0\nSURFACES = ["ice"]\nCASES = [("lst", "truth")]',
    # the designed gains and one Optuna proposal, compared on the first held-out condition, on a tenth of a turn
    "controller_design_and_tuning": "TUNING_TRIALS = 2\nHELD_OUT_CONDITIONS = 1\nEPISODE_TURNS = 0.1",
}
"""The default suite's parameters of the light notebooks, run after each one's own parameter cell."""

NOTEBOOK_PARAMS = [
    pytest.param(p, id=p.stem, marks=[pytest.mark.slow] if p.stem in HEAVY_NOTEBOOKS | set(SMALL_PARAMETERS) else [])
    for p in NOTEBOOKS
]


def with_parameters(notebook: nbformat.NotebookNode, source: str) -> nbformat.NotebookNode:
    """``notebook`` with a code cell of ``source`` inserted after its cell tagged ``parameters``."""
    (index,) = [i for i, c in enumerate(notebook.cells) if "parameters" in c.get("metadata", {}).get("tags", [])]
    cell = nbformat.v4.new_code_cell(source, metadata={"tags": ["injected-parameters"]})
    notebook.cells.insert(index + 1, cell)
    return notebook


def test_the_small_parameters_name_only_the_notebooks_own_parameters() -> None:
    # An injected name the notebook does not define would run the notebook's defaults under another name.
    for stem, source in SMALL_PARAMETERS.items():
        notebook = nbformat.read(NOTEBOOK_DIR / f"{stem}.ipynb", as_version=4)
        (own,) = [c.source for c in notebook.cells if "parameters" in c.get("metadata", {}).get("tags", [])]
        defined = {line.split("=")[0].strip() for line in own.splitlines() if "=" in line and line[0].isupper()}
        injected = {line.split("=")[0].strip() for line in source.splitlines()}
        assert injected and injected <= defined, (stem, injected - defined)


@pytest.mark.rendering
@pytest.mark.parametrize("path", NOTEBOOK_PARAMS)
def test_notebook_runs(path, kernel_name, tmp_path):
    run_notebook(path, kernel_name, tmp_path)


@pytest.mark.rendering
@pytest.mark.parametrize("stem", sorted(SMALL_PARAMETERS))
def test_notebook_runs_with_small_parameters(stem, kernel_name, tmp_path):
    run_notebook(NOTEBOOK_DIR / f"{stem}.ipynb", kernel_name, tmp_path, SMALL_PARAMETERS[stem])


def run_notebook(path: Path, kernel_name: str, tmp_path: Path, parameters: str | None = None) -> None:
    """Execute the notebook at ``path`` (after ``parameters``, if given) and check no cell raised."""
    notebook = nbformat.read(path, as_version=4)
    assert all(not cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code"), "commit without outputs"
    if parameters is not None:
        notebook = with_parameters(notebook, parameters)
    client = NotebookClient(
        notebook, timeout=900, kernel_name=kernel_name, resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()
    errors = [o for c in notebook.cells for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert not errors
