"""The shape of the code: no import cycles, dependencies pointing one way (docs/design.md §2), modules cut by job.

The import graph is read from the source with :mod:`ast` (every ``import`` and ``from … import``, also those
inside functions and ``if TYPE_CHECKING:`` blocks, since each is a dependency), so the checks need no import
of the project and see imports that run only on some paths.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("vehicle_model", "controller", "sensor", "scenarios")

ALLOWED_PACKAGE_IMPORTS: dict[str, set[str]] = {
    "vehicle_model": set(),
    "controller": {"vehicle_model"},
    "sensor": {"vehicle_model"},
    "scenarios": {"vehicle_model", "controller", "sensor"},
}
"""docs/design.md §2: which of the four packages each may import."""

SCENARIO_ROOMS: tuple[str, ...] = (
    "portable_arithmetic",
    "extras",
    "yaml_input",
    "camera_schema",
    "camera_checks",
    "registry",
    "unit_feedback",
    "estimator_settings",
    "scenario_shortcuts",
    "roads",
    "configuration",
    "config",
    "config_fields",
    "catalogue",
    "setup",
    "camera",
    "loop",
    "run",
    "assess",
    "export",
    "recorded",
    "studies",
    "envs",
    "cli_format",
    "bench",
    "commands",
    "cli",
)
"""The rooms of ``scenarios/``, lowest first: a room imports only rooms before it."""

LONG_MODULE_LINES = 600
"""A module longer than this says why in its docstring, on a line that starts with :data:`LONG_REASON`: one job per
module, and 500 lines is a prompt to review the cut, not a limit to trim to."""
LONG_REASON = "Why this module is long:"


def _module_name(path: Path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(path): path for package in PACKAGES for path in sorted((REPO / package).rglob("*.py"))}


def _imported(module: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The project modules that ``module`` imports (the deepest known module of each imported name)."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join([*anchor, base] if base else anchor)
            names = [f"{base}.{alias.name}" for alias in node.names] + [base]
        for name in names:
            while name and name not in known:
                name = name.rpartition(".")[0]
            if name and name != module:
                found.add(name)
    return found


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    known = _modules()
    return {module: _imported(module, path, known) for module, path in known.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module, or a module importing itself (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in sorted(graph.get(node, ())):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while True:
                other = stack.pop()
                on_stack.discard(other)
                component.append(other)
                if other == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def _room(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if parts[0] == "scenarios" and len(parts) > 1 else None


def test_the_cycle_check_finds_a_cycle() -> None:
    # The check itself: a three-module ring and a pair are found, a chain is not.
    ring = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"e"}, "e": {"d"}, "f": {"a"}}
    assert sorted(_cycles(ring)) == [["a", "b", "c"], ["d", "e"]]
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_the_graph_sees_relative_lazy_and_type_checking_imports(graph: dict[str, set[str]]) -> None:
    # Spot checks that the parser resolves the import forms the project uses.
    assert "sensor.vo.config" in graph["sensor.vo.odometry"]  # absolute, inside the package
    assert "scenarios.camera.delivery" in graph["scenarios.loop.camera_estimator"]  # imported inside a function
    assert "vehicle_model.parameters" in graph["vehicle_model.geometry"]  # relative
    assert "vehicle_model.dynamics" in graph["scenarios.run.runner"]  # under TYPE_CHECKING


def test_no_import_cycles(graph: dict[str, set[str]]) -> None:
    assert _cycles(graph) == []


def test_packages_import_only_downwards(graph: dict[str, set[str]]) -> None:
    wrong = sorted(
        (module, other)
        for module, imports in graph.items()
        for other in imports
        if (a := module.split(".")[0]) != (b := other.split(".")[0]) and b not in ALLOWED_PACKAGE_IMPORTS[a]
    )
    assert wrong == []


def test_scenario_rooms_import_only_lower_rooms(graph: dict[str, set[str]]) -> None:
    rooms = {path.stem for path in (REPO / "scenarios").iterdir() if path.suffix == ".py" or path.is_dir()}
    rooms -= {"__init__", "__pycache__"}
    assert rooms == set(SCENARIO_ROOMS), "every room of scenarios/ has its place in the order"
    rank = {room: i for i, room in enumerate(SCENARIO_ROOMS)}
    upward = sorted(
        (module, other)
        for module, imports in graph.items()
        if (room := _room(module)) is not None
        for other in imports
        if (target := _room(other)) is not None and rank[target] > rank[room]
    )
    assert upward == []


def test_scenario_room_inits_import_nothing(graph: dict[str, set[str]]) -> None:
    # A room's __init__ only says what lives there, so importing one module never drags in its siblings, and a
    # spawned sweep worker starts on the standard library alone (scenarios.studies.workers).
    modules = _modules()
    room_inits = [m for m in graph if m.split(".")[0] == "scenarios" and modules[m].name == "__init__.py"]
    assert {m: sorted(graph[m]) for m in room_inits if graph[m]} == {}


def test_the_sweep_worker_module_imports_only_the_standard_library() -> None:
    # Spawned workers import scenarios.studies.workers to run their initializer, which limits every library to one
    # thread; numpy (and its BLAS) must not be loaded before that.
    code = (
        "import sys; import scenarios.studies.workers; "
        "heavy = sorted(m for m in ('numpy', 'pandas', 'casadi', 'cv2', 'pyarrow') if m in sys.modules); "
        "print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_a_long_module_says_why() -> None:
    unexplained = {}
    for module, path in _modules().items():
        text = path.read_text()
        lines = len(text.splitlines())
        docstring = ast.get_docstring(ast.parse(text)) or ""
        if lines > LONG_MODULE_LINES and not any(line.startswith(LONG_REASON) for line in docstring.splitlines()):
            unexplained[module] = lines
    assert unexplained == {}


def test_every_module_says_what_lives_there() -> None:
    missing = [module for module, path in _modules().items() if not ast.get_docstring(ast.parse(path.read_text()))]
    assert missing == []


def test_importing_the_package_holds_numpys_blas_to_one_thread_unless_told_otherwise() -> None:
    # scenarios/__init__.py: a threaded BLAS makes a closed-loop run depend on the machine's core count.
    code = "import os, scenarios, numpy; print(os.environ['OPENBLAS_NUM_THREADS'], os.environ['MKL_NUM_THREADS'])"
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["1", "1"]
    told = subprocess.run(
        [sys.executable, "-c", code],
        cwd=REPO,
        env={**env, "OPENBLAS_NUM_THREADS": "2"},
        capture_output=True,
        text=True,
        check=True,
    )
    assert told.stdout.split() == ["2", "1"]  # the user's own setting stands
