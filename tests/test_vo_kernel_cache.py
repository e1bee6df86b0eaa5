"""The odometry's compiled-kernel cache is keyed by the sources, so an edit of any VO module compiles afresh."""

from __future__ import annotations

import shutil
from pathlib import Path

from sensor.vo import jit


def test_cache_folder_changes_with_any_vo_source(tmp_path: Path, monkeypatch) -> None:
    """numba checks only a kernel's own file: a kernel that calls one of another module would keep its stale
    machine code. The folder name follows every source: a copy gives the same digest, an edit of the callee's
    module (kernels_search, called by kernels_circle) another one."""
    copy = tmp_path / "vo"
    shutil.copytree(Path(jit.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert jit.sources_digest(copy) == jit.sources_digest()
    search = copy / "kernels_search.py"
    search.write_text(search.read_text() + "\n# edited\n")
    assert jit.sources_digest(copy) != jit.sources_digest()
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("OFFTRACK_CACHE_DIR", str(tmp_path))
    assert jit.numba_cache_dir() == tmp_path / "numba" / jit.sources_digest()
