"""The ``controller-limits`` study on the paper's 11.5 m field manoeuvres: a selection between its default subset and
``--full``.

The cells are ``field-figure-eight``, ``field-roundabout-left`` and ``field-roundabout-right`` × dry, wet, ice × the
LST; each runs unsteered, truth-fed and zero-slip-fed (:data:`scenarios.studies.controller_limits.FEEDBACKS`), with
``--camera`` on the fused camera under field conditions
(:mod:`scenarios.studies.controller_limits_camera`, rendered) and, unless ``--no-optimal``, its optimal reference
(model-only), every case driven as the study drives it, slowing for the surface (``speed.friction_share`` at
:data:`scenarios.studies.controller_limits.FRICTION_SHARE`). The cases are the
study's own (:func:`scenarios.studies.controller_limits.controller_limits_cases` with ``cells``), run and gathered
by the study's sweep: ``table.csv``/``table.md``, ``controller_limits.png`` and ``controller_limits.json`` (each
cell's check, and the camera cells' checks) as ``offtrack study controller-limits`` writes them (each row with its
largest outswing after warm-up, :func:`scenarios.studies.controller_limits.largest_outswing`). The model-only PID
cases run first, then the camera cases (the figure-of-eight's first, wet, dry, ice within a manoeuvre), then the
optimal references, and those in the order of :func:`_reference_order`, so a run cut short still holds every
cell's check and the cells that matter most. Running it again into the same directory
runs only the cases not yet finished.

Usage::

    python -m benchmarks.controller_limits_field OUT_DIR [--no-optimal] [--camera] [--workers N]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from scenarios.loop.ends import RunStatus
from scenarios.studies.controller_limits import (
    CAMERA_FEEDBACK,
    OPTIMAL,
    controller_limits_cases,
    controller_limits_figures,
    run_controller_limits_case,
)
from scenarios.studies.records import CaseSpec
from scenarios.studies.sweep import run_sweep

SCENARIOS = ("field-figure-eight", "field-roundabout-left", "field-roundabout-right")
SURFACES = ("dry", "wet", "ice")
REFERENCE_SURFACE_ORDER = ("wet", "dry", "ice")


def _reference_order(case: CaseSpec) -> tuple[bool, int]:
    """The optimal references' order: the mirrored roundabout last, and wet, dry, then ice (where the tractor
    leaves the road before the first turn) within each."""
    return case.scenario == SCENARIOS[-1], REFERENCE_SURFACE_ORDER.index(dict(case.labels)["surface"])


def _camera_order(case: CaseSpec) -> tuple[int, int]:
    """The camera cases' order: by manoeuvre as :data:`SCENARIOS`, and wet, dry, then ice within each."""
    return SCENARIOS.index(case.scenario), REFERENCE_SURFACE_ORDER.index(dict(case.labels)["surface"])


def main() -> None:
    """Run the selection into OUT_DIR and print the wall time."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--no-optimal", action="store_true", help="skip the optimal references")
    parser.add_argument("--camera", action="store_true", help="add each cell's fused camera case (rendered)")
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args()
    cells = [(s, surface, "lst") for s in SCENARIOS for surface in SURFACES]
    cases = controller_limits_cases(cells=cells, optimal=not args.no_optimal, camera=args.camera)
    pid = [c for c in cases if dict(c.labels)["feedback"] not in (OPTIMAL, CAMERA_FEEDBACK)]
    camera = sorted((c for c in cases if dict(c.labels)["feedback"] == CAMERA_FEEDBACK), key=_camera_order)
    references = sorted((c for c in cases if dict(c.labels)["feedback"] == OPTIMAL), key=_reference_order)
    cases = pid + camera + references
    start = time.perf_counter()
    result = run_sweep(cases, args.out_dir, run_controller_limits_case, workers=args.workers, resume=True)
    table = result.table
    done = table[table["status"] != RunStatus.FAILED].reset_index(drop=True)
    if not done.empty:
        controller_limits_figures(done, args.out_dir)
    print(f"{len(cases)} cases in {time.perf_counter() - start:.0f} s wall")


if __name__ == "__main__":
    main()
