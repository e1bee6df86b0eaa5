"""The study ``tiny`` of the sweep tests (``test_sweep.py``): three short model-only cases of ``roundabout-3``
(:data:`TINY`), and optionally a short rendered one (:data:`RENDERED_CASE`), written in parts of 50 rows.

:func:`set_up` registers it in the process that runs ``offtrack study tiny``: through ``main()`` in the test's own
process (with pytest's ``monkeypatch``, undone after the test), or in a process of its own (:data:`STUDY_PROCESS`).
"""

from __future__ import annotations

import errno
from collections.abc import Callable
from typing import Any

from scenarios.studies.cases import model_only_cases
from scenarios.studies.records import CaseSpec

TINY = model_only_cases(3, duration_s=2.0, study="tiny")
"""The model-only cases of ``tiny``."""

RENDERED_CASE = "case-3_surface-dry_camber-0.0"
"""The rendered case ``tiny`` adds with ``rendered``."""

FULL_DISK_CASE = "case-1_"
"""The start of the name of the case whose series finds no room after its first part with ``disk_full``."""


def _rendered_case() -> CaseSpec:
    camera = (("camera.width", 672), ("camera.height", 196), ("seed", 7))
    overrides = (("duration_s", 1.5), ("estimators.viso_ot", True), ("estimators.zero_slip", True), *camera)
    return CaseSpec("tiny", "constant-slip", overrides, (("case", 3), ("surface", "dry"), ("camber", 0.0)))


def set_up(
    setattr_: Callable[[Any, str, Any], None] = setattr,
    setitem: Callable[[Any, Any, Any], None] = lambda mapping, key, value: mapping.__setitem__(key, value),
    *,
    rendered: bool = False,
    disk_full: bool = False,
) -> None:
    """Register ``tiny`` and its part size in this process (through ``setattr_`` and ``setitem``: pytest's
    ``monkeypatch.setattr`` and ``monkeypatch.setitem`` undo them after a test).

    ``rendered``: with the rendered case (it renders in the process that runs it: never a test's own process);
    ``disk_full``: the series of case 1 (:data:`FULL_DISK_CASE`) finds no room after its first part, in this
    process (a serial study).
    """
    import scenarios.run.results as results
    from scenarios.studies import registry

    cases = [*TINY, _rendered_case()] if rendered else list(TINY)
    setitem(registry.STUDIES, "tiny", registry.Study("tiny", "model-only cases", lambda full: cases, lambda t, o: None))
    setattr_(results, "FLUSH_ROWS", 50)  # two parts per case (100 rows)
    if disk_full:
        write_table = results.pq.write_table

        def fill_the_disk(table: Any, where: Any, **kwargs: Any) -> None:
            name = str(getattr(where, "name", where))
            if FULL_DISK_CASE in name and ".part-000000." not in name:
                raise OSError(errno.ENOSPC, "No space left on device")
            return write_table(table, where, **kwargs)

        setattr_(results.pq, "write_table", fill_the_disk)


STUDY_PROCESS = """
import sys
sys.path.insert(0, sys.argv.pop(1))  # this folder
import tiny_study
tiny_study.set_up(rendered=sys.argv.pop(1) == "rendered")
from scenarios.cli import main
main()
"""
"""``python -c STUDY_PROCESS FOLDER RENDERED study tiny ...``: ``offtrack study tiny`` in a process of its own,
``tiny`` set up there (``RENDERED``: ``rendered`` or ``model-only``)."""
