"""The odometry's kernels call each other with integer values, not literal constants.

numba types an inline integer constant as ``Literal[int]`` and compiles a called kernel once per literal
argument value (its "Notes on Literal Types"): a kernel called from three sites with three literal modes is
compiled three times on a machine's first run. A literal passed as ``np.int64(...)`` is a plain int64, so the
callee is compiled once (docs/visual_odometry.md §16, "What a first run on a machine compiles").
"""

from __future__ import annotations

import ast
from pathlib import Path

import numba
import numpy as np
import pytest

from sensor.vo import kernels_motion

_VO = Path(kernels_motion.__file__).parent


def _is_kernel(function: ast.FunctionDef) -> bool:
    return any(isinstance(d, ast.Name) and d.id == "kernel" for d in function.decorator_list)


def _int_constant(node: ast.expr) -> bool:
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        node = node.operand
    return isinstance(node, ast.Constant) and isinstance(node.value, int)


def _assigned_names(tree: ast.AST) -> dict[str, list[ast.expr]]:
    """Every value assigned to each plain name in ``tree`` (tuple unpacking of a tuple of values included)."""
    values: dict[str, list[ast.expr]] = {}
    for node in ast.walk(tree):
        if not isinstance(node, ast.Assign):
            continue
        for target in node.targets:
            if isinstance(target, ast.Name):
                values.setdefault(target.id, []).append(node.value)
            elif isinstance(target, ast.Tuple) and isinstance(node.value, ast.Tuple):
                for name, value in zip(target.elts, node.value.elts, strict=False):
                    if isinstance(name, ast.Name):
                        values.setdefault(name.id, []).append(value)
            elif isinstance(target, ast.Tuple):
                for name in target.elts:
                    if isinstance(name, ast.Name):
                        values.setdefault(name.id, []).append(node.value)
    return values


def _int_constant_names(tree: ast.AST) -> set[str]:
    """Names in ``tree`` that are only ever assigned integer constants."""
    return {name for name, values in _assigned_names(tree).items() if all(_int_constant(v) for v in values)}


def _modules(folder: Path) -> dict[str, ast.Module]:
    return {path.stem: ast.parse(path.read_text(), str(path)) for path in sorted(folder.glob("*.py"))}


def _literal_kernel_arguments(folder: Path = _VO) -> list[str]:
    """``module:line callee(argument)`` of every argument of a kernel call inside a kernel that numba would
    type as a literal integer: an integer constant, a module constant (own or imported from ``sensor.vo``)
    or a local name assigned only integer constants, in the modules of ``folder``."""
    modules = _modules(folder)
    kernels = {
        m: {f.name for f in tree.body if isinstance(f, ast.FunctionDef) and _is_kernel(f)}
        for m, tree in modules.items()
    }
    constants = {
        m: _int_constant_names(ast.Module([s for s in tree.body if isinstance(s, ast.Assign)], []))
        for m, tree in modules.items()
    }
    found = []
    for module, tree in modules.items():
        callees, module_constants = set(kernels[module]), set(constants[module])
        for node in tree.body:
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("sensor.vo."):
                source = node.module.rsplit(".", 1)[1]
                for alias in node.names:
                    if alias.name in kernels.get(source, ()):
                        callees.add(alias.asname or alias.name)
                    if alias.name in constants.get(source, ()):
                        module_constants.add(alias.asname or alias.name)
        for function in tree.body:
            if not (isinstance(function, ast.FunctionDef) and _is_kernel(function)):
                continue
            local, local_constants = _assigned_names(function), _int_constant_names(function)
            for call in ast.walk(function):
                if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Name) and call.func.id in callees):
                    continue
                for arg in [*call.args, *(k.value for k in call.keywords)]:
                    name = arg.id if isinstance(arg, ast.Name) else None
                    literal = _int_constant(arg) or (
                        name is not None
                        and (name in local_constants or (name in module_constants and name not in local))
                    )
                    if literal:
                        found.append(f"{module}:{call.lineno} {call.func.id}({ast.unparse(arg)})")
    return found


def test_no_kernel_passes_a_literal_integer_to_another_kernel() -> None:
    assert _literal_kernel_arguments() == []


def test_the_scan_finds_literal_arguments(tmp_path: Path) -> None:
    """The scan is not vacuous: it finds a constant, a module constant and a local constant, not np.int64(…)."""
    (tmp_path / "kernels_a.py").write_text(
        "MODE, OTHER = 0, 1\n"
        "@kernel\ndef callee(a, b):\n    return a + b\n"
        "@kernel\ndef caller(x):\n"
        "    three = 3\n"
        "    return callee(x, 2) + callee(x, MODE) + callee(x, three) + callee(x, np.int64(4)) + callee(x, -1)\n"
    )
    (tmp_path / "kernels_b.py").write_text(
        "from sensor.vo.kernels_a import OTHER, callee\n@kernel\ndef user(x):\n    return callee(x, OTHER)\n"
    )
    assert sorted(_literal_kernel_arguments(tmp_path)) == [
        "kernels_a:8 callee(-1)", "kernels_a:8 callee(2)", "kernels_a:8 callee(MODE)", "kernels_a:8 callee(three)",
        "kernels_b:4 callee(OTHER)",
    ]  # fmt: skip


@pytest.mark.skipif(numba.config.DISABLE_JIT, reason="needs numba's compiler")
def test_a_kernel_compiled_afresh_types_its_callees_arguments_as_int64() -> None:
    """On numba itself: a fresh (uncached) compile of :func:`rotations` types the target matrix and column it
    passes to ``_rotate_rows`` as int64, one signature for the nine calls; a literal would give Literal[int]."""
    fresh = numba.njit(nogil=True, error_model="numpy")(kernels_motion.rotations.py_func)
    out = np.zeros((4, 3, 3))
    fresh(0.1, 0.2, 0.3, out)
    expected = np.zeros((4, 3, 3))
    kernels_motion.rotations(0.1, 0.2, 0.3, expected)
    assert np.array_equal(out, expected)
    signatures = kernels_motion._rotate_rows.signatures
    assert len(signatures) == 1
    assert signatures[0][1] == numba.types.int64 and signatures[0][2] == numba.types.int64
