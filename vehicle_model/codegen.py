"""Compile casadi functions to a shared library with the system C compiler, cached on disk.

casadi's virtual machine evaluates the model much slower than generated C (README.md), so the
functions are written out with :class:`casadi.CodeGenerator`, compiled once and cached under a
name that hashes the generated source (so a change of parameters or model recompiles). The cache
lives in ``$OFFTRACK_CACHE_DIR`` or ``~/.cache/offtrack``. Set ``OFFTRACK_NO_COMPILE=1`` to skip
compilation; without a C compiler the functions run in the virtual machine with a warning.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings
from pathlib import Path

import casadi as ca

from .errors import OutputError


def cache_dir() -> Path:
    """Directory holding compiled model libraries."""
    root = os.environ.get("OFFTRACK_CACHE_DIR")
    return Path(root) if root else Path.home() / ".cache" / "offtrack"


def _compiler() -> str | None:
    return os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc") or shutil.which("clang")


def load_functions(functions: list[ca.Function], lib: Path) -> list[ca.Function]:
    """The compiled twins of ``functions`` in the shared library ``lib`` (:func:`compile_library`)."""
    return [ca.external(f.name(), str(lib)) for f in functions]


def compile_library(functions: list[ca.Function], tag: str, extra_source: str = "") -> Path | None:
    """Generate C for ``functions``, append ``extra_source``, compile; return the cached shared library.

    ``extra_source`` is C appended to the generated file, so it can call the generated functions
    directly (``name(arg, res, iw, w, mem)``, casadi's calling convention). ``None`` means compilation
    is switched off or impossible (with a warning for the latter).
    """
    if os.environ.get("OFFTRACK_NO_COMPILE"):
        return None
    compiler = _compiler()
    if compiler is None:
        warnings.warn(
            "no C compiler found (install gcc, e.g. 'apt-get install gcc'); the vehicle model runs in "
            "casadi's virtual machine, roughly ten times slower",
            RuntimeWarning,
            stacklevel=3,
        )
        return None
    with tempfile.TemporaryDirectory() as tmp:
        c_name = "model.c"
        gen = ca.CodeGenerator(c_name, {"with_header": False})
        for f in functions:
            gen.add(f)
        cwd = os.getcwd()
        try:
            os.chdir(tmp)
            gen.generate()
        finally:
            os.chdir(cwd)
        source = (Path(tmp) / c_name).read_text() + extra_source
    digest = hashlib.sha256((source + compiler).encode()).hexdigest()[:16]
    safe_tag = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in tag)
    lib = cache_dir() / f"{safe_tag}_{digest}.so"
    if not lib.exists():
        try:
            return _build(lib, source, compiler)
        except OSError as exc:  # a full disk, a quota: say which file of the cache, not only that one failed
            where = exc.filename or getattr(exc, "cache_file", lib)
            raise OutputError(
                f"cannot write {where}: {exc.strerror or exc} (the compiled-model cache; free room there or set "
                "OFFTRACK_CACHE_DIR to another directory)"
            ) from exc
    return lib


def _write_source(path: Path, source: str) -> None:
    """Write the generated C source ``source`` to ``path``."""
    path.write_text(source)


def _build(lib: Path, source: str, compiler: str) -> Path | None:
    """Compile ``source`` into the cached library ``lib`` through a temporary directory beside it; None (with a
    warning) if the compiler fails.

    Raises
    ------
    OSError
        A file of the cache could not be written; ``cache_file`` (or ``filename``) names it.
    """
    step = lib.parent
    try:
        lib.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=lib.parent) as tmp:
            src = step = Path(tmp) / "model.c"
            _write_source(src, source)
            out = Path(tmp) / lib.name
            cmd = [compiler, "-O2", "-fPIC", "-shared", str(src), "-o", str(out), "-lm"]
            proc = subprocess.run(cmd, capture_output=True, text=True)
            if proc.returncode != 0:
                warnings.warn(
                    f"compiling the vehicle model failed ({' '.join(cmd)}): {proc.stderr.strip()[:500]}; "
                    "running in casadi's virtual machine instead",
                    RuntimeWarning,
                    stacklevel=4,
                )
                return None
            step = lib
            os.replace(out, lib)  # atomic: concurrent workers never load a half-written library
    except OSError as exc:
        exc.cache_file = step  # type: ignore[attr-defined]
        raise
    return lib
