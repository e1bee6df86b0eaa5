"""The fused filter's settings screened open loop on the field-loop grid's cells, the rendered frames cached.

A closed field-loop cell costs 3–4 minutes, nearly all of it rendering; the filter itself costs seconds. Here each
chosen cell of ``offtrack study field-loop --full`` (its fused-feedback case) is run **steered on the truth**, with
the fused estimate computed beside it as an observer, so the path does not depend on the filter's settings. On the
first run of a cell the camera keeps its developed stereo pairs in ``--cache`` (its frame cache,
:mod:`scenarios.camera.frame_cache`, one directory per cell; the size is checked against the free disk first); every
later run reads them back and runs only the odometry, self-calibration and the filter. Per cell it prints the fused
estimate's error RMS and mean after 20 s, the share within 2σ, the std's RMS and the zero-slip estimate's error RMS
(open loop: the true off-tracking is the truth-fed loop's, not what the estimate would steer)::

    .venv/bin/python benchmarks/fusion_open_loop.py OUT --cells "roundabout-3_surface-dry;figure-eight_surface-ice" \\
        [--set fusion.kinematic_error_model=state ...] [--cache DIR] [--cached-only] [--workers 2] [--json]

``--cells``: ``;``-separated alternatives, each a ``,``-separated set of substrings a case's name must all hold.
docs/field_bias.md §6.5 lists what was screened this way. The cache is the frames of this build's renderer and
field conditions: clear it when either changes.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import multiprocessing as mp
import os
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
CELL_BYTES = 2.6e9  # the largest cell's frames (roundabout-3), for the free-space check


def cached_frames(cache: Path, name: str) -> Path:
    """The frame cache directory of the cell ``name``'s camera."""
    return cache / name.removeprefix("scenario-")


def is_cached(cache: Path, name: str) -> bool:
    """Whether the cell ``name``'s frames are in the cache (its directory holds frames)."""
    return any(cached_frames(cache, name).glob("*/*.npz"))


def run_cell(args: tuple[str, list[tuple[str, Any]], str, str]) -> tuple[str, dict[str, Any]]:
    """One cell steered on the truth with the fused filter observing; the frames from (or into) the cache."""
    name, extra, out, cache_dir = args
    from scenarios.studies.workers import setup_process

    setup_process()
    import pandas as pd

    from scenarios.camera.frame_cache import FRAME_CACHE_ENV
    from scenarios.studies.field_loop import field_loop_cases, run_field_loop_case

    os.environ[FRAME_CACHE_ENV] = str(cached_frames(Path(cache_dir), name))  # this process runs one cell at a time
    spec = next(s for s in field_loop_cases(full=True) if s.name == name)
    overrides = tuple((k, v) for k, v in spec.overrides if k != "feedback")
    overrides += (("feedback", "truth"), ("estimators.viso_ot_fused", True), *extra)
    spec = dataclasses.replace(spec, overrides=overrides)
    row = run_field_loop_case(spec, Path(out))
    series = pd.read_parquet(Path(out) / spec.name / "timeseries.parquet")
    late = series["time"].to_numpy() > 20.0
    truth = series["offtracking_truth"].to_numpy()
    fused = series["offtracking_viso_ot_fused"].to_numpy()
    std = series["offtracking_viso_ot_fused_std"].to_numpy()
    known = late & np.isfinite(fused)
    error = fused[known] - truth[known]
    zero_slip = series["offtracking_zero_slip"].to_numpy()[late] - truth[late]
    return name, {
        "fused_rms_error_m": float(np.sqrt(np.mean(error**2))),
        "fused_mean_error_m": float(np.mean(error)),
        "fused_within_2sigma": float(np.mean(np.abs(error) <= 2.0 * std[known])),
        "fused_std_rms_m": float(np.sqrt(np.mean(std[known] ** 2))),
        "zero_slip_rms_error_m": float(np.sqrt(np.mean(zero_slip**2))),
        "status": str(row.get("status")),
    }


def parse_set(items: list[str]) -> list[tuple[str, Any]]:
    """``key=value`` overrides, the value read as YAML (numbers, booleans, lists), as ``offtrack … --set`` reads them
    (:func:`scenarios.config.parse_assignment`)."""
    from scenarios.config import ConfigError, parse_assignment

    try:
        return [parse_assignment(item) for item in items]
    except ConfigError as exc:
        raise SystemExit(f"{exc}: expected key=value") from None


def main(argv: list[str] | None = None) -> int:
    """Screen the given settings on the chosen cells; print one line per cell (or one JSON object)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="run directories go here")
    parser.add_argument("--cells", required=True, help="';'-separated alternatives of ','-separated substrings")
    parser.add_argument("--set", action="append", default=[], help="a run setting key=value (repeatable)")
    parser.add_argument("--cache", type=Path, default=Path("fusion-frames"), help="the frame cache directory")
    parser.add_argument("--cached-only", action="store_true", help="only the cells whose frames are cached")
    parser.add_argument("--workers", type=int, default=2, help="cells run at once (spawned processes)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    from scenarios.studies.field_loop import field_loop_cases

    extra = parse_set(args.set)
    wants = [alternative.split(",") for alternative in args.cells.split(";")]
    names = [
        s.name
        for s in field_loop_cases(full=True)
        if s.name.endswith("viso_ot_fused") and any(all(w in s.name for w in want) for want in wants)
    ]
    args.cache.mkdir(parents=True, exist_ok=True)
    missing = [n for n in names if not is_cached(args.cache, n)]
    if args.cached_only:
        names = [n for n in names if n not in missing]
        missing = []
    if not names:
        raise SystemExit(f"--cells {args.cells!r}: no fused-feedback case of the full grid matches")
    free = shutil.disk_usage(args.cache).free
    if len(missing) * CELL_BYTES > free:
        raise SystemExit(
            f"--cache {args.cache}: {len(missing)} cells need {len(missing) * CELL_BYTES / 1e9:.0f} GB, "
            f"{free / 1e9:.0f} GB free"
        )
    rows = {}
    with mp.get_context("spawn").Pool(max(1, args.workers)) as pool:
        jobs = [(n, extra, str(args.out), str(args.cache)) for n in names]
        for name, row in pool.imap_unordered(run_cell, jobs):
            rows[name] = row
            if not args.json:
                figures = " ".join(f"{k}={v:.4f}" for k, v in row.items() if isinstance(v, float))
                print(name.removeprefix("scenario-"), figures, row["status"], flush=True)
    if args.json:
        print(json.dumps({"benchmark": "fusion_open_loop", "settings": dict(extra), "cells": rows}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
