"""One case of the ``field-loop`` study with settings of its own: the command the figures of docs/field_bias.md and
docs/studies.md give for a cell the study's own grid does not select (another seed, one feedback, an opt-in setting).

The case is :func:`scenarios.studies.field_loop.field_loop_case` with each ``KEY=VALUE`` appended to its overrides
(read as ``--set`` reads it, :func:`scenarios.config.parse_assignment`), run by
:func:`scenarios.studies.field_loop.run_field_loop_case` into ``OUT_DIR/<case name>/`` (the run directory every run
writes), and its row — the study's columns, each further unit's ``unit<k>_…`` — written to
``OUT_DIR/row-<VEHICLE>_<SCENARIO>_…_s<SEED>_<FEEDBACK>.json`` and printed.

Usage::

    python -m benchmarks.field_loop_cell VEHICLE SCENARIO SURFACE CAMBER CONDITIONS ALIGNMENT SEED FEEDBACK FULL \\
        OUT_DIR [KEY=VALUE ...]

``VEHICLE`` ``lst`` (the study's own) or a combination :func:`scenarios.studies.field_loop.field_loop_vehicle` takes
(``au-b-double-steered``, ``au-a-double-steered``, a combination file); ``FULL`` 0 (the study's short runs) or 1.
For example the sandwich covariance on the B-double's icy field cell at seed 1::

    python -m benchmarks.field_loop_cell au-b-double-steered roundabout-3 ice 5 field paper 1 viso_ot_fused 0 out \\
        camera.vo_covariance_model=sandwich fusion.vo_covariance_scale=1.0

Each case renders when its feedback is ``viso_ot_fused``; run one at a time on a small machine.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import NoReturn

from scenarios.config import parse_assignment
from scenarios.studies.field_loop import (
    ALIGNMENTS,
    CONDITIONS,
    FEEDBACKS,
    field_loop_case,
    field_loop_vehicle,
    run_field_loop_case,
)
from scenarios.studies.records import CaseSpec

HEADLINE = ("true_offtracking_rms_after_warmup_m", "true_offtracking_max_after_warmup_m", "fused_rms_error_m")
"""The first towed unit's columns printed (beside every ``unit<k>_`` unit's ``true_rms_m`` and ``true_max_m``)."""


class _OneLineParser(argparse.ArgumentParser):
    """An argument parser whose refusal is one line (no usage block) and exit 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def case_from_arguments(argv: list[str]) -> tuple[CaseSpec, Path, str]:
    """The case, the output directory and the row file's stem from the command line (module docstring).

    Raises
    ------
    SystemExit
        Exit 2 with one line naming the argument and its allowed values (argparse), before any work.
    """
    parser = _OneLineParser(prog="python -m benchmarks.field_loop_cell", description=__doc__.splitlines()[0])
    parser.add_argument("vehicle")
    parser.add_argument("scenario")
    parser.add_argument("surface")
    parser.add_argument("camber", type=float)
    parser.add_argument("conditions", choices=CONDITIONS)
    parser.add_argument("alignment", choices=tuple(ALIGNMENTS))
    parser.add_argument("seed", type=int)
    parser.add_argument("feedback", choices=FEEDBACKS)
    parser.add_argument("full", type=int, choices=(0, 1))
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("settings", nargs="*", metavar="KEY=VALUE")
    args = parser.parse_args(argv)
    try:
        extra = tuple(parse_assignment(item) for item in args.settings)
        vehicle = field_loop_vehicle(None if args.vehicle == "lst" else args.vehicle)
    except ValueError as exc:
        parser.error(str(exc))
    spec = field_loop_case(
        args.scenario,
        args.surface,
        args.camber,
        args.conditions,
        args.alignment,
        args.seed,
        args.feedback,
        bool(args.full),
        vehicle,
    )
    spec = CaseSpec(spec.study, spec.scenario, spec.overrides + extra, spec.labels)
    camber = f"{args.camber:g}"
    stem = "_".join(
        (
            args.vehicle,
            args.scenario,
            args.surface,
            camber,
            args.conditions,
            args.alignment,
            f"s{args.seed}",
            args.feedback,
        )
    )
    return spec, args.out_dir, stem


def main(argv: list[str] | None = None) -> int:
    """Run the case and write its row (module docstring); the run's status decides nothing here."""
    spec, out_dir, stem = case_from_arguments(sys.argv[1:] if argv is None else argv)
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    row = run_field_loop_case(spec, out_dir)
    row["wall_s"] = time.perf_counter() - start
    (out_dir / f"row-{stem}.json").write_text(json.dumps(row, default=str, indent=1))
    shown = {k: row.get(k) for k in HEADLINE} | {
        k: v for k, v in row.items() if k.startswith("unit") and k.endswith(("true_rms_m", "true_max_m"))
    }
    print(stem, json.dumps(shown, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
