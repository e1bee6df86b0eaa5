"""Where the CPU's vector code changes a camera run's numbers: every OpenCV call and the camera's stages, hashed.

``trace OUT.json [--portable]`` runs one short field camera run in this process (``roundabout-3``, the
controller-limits study's camera overrides at seed 9 — the airfield world, an estimated calibration of 40 views, a
lens, a low sun with the lagging auto-exposure, mount flex, the paper's rotation, self-calibration — at 672 × 196 px
for ``TRACE_DURATION`` s, default 0.5; serial: set ``OFFTRACK_CAMERA_WORKERS=0``), the calibration computed here
(not read from the disk cache). Every function of the ``cv2`` module is wrapped: each call records its name, its
caller, a digest of its arguments and a digest of its result, in call order; so do the world's build (textures,
mipmaps), the calibration, the render, the optics (flex warp, lens), the development (exposure, noise,
rectification) and the odometry's ``process``; and the run's time series, column by column. ``--portable`` turns
the portable arithmetic on first (:mod:`scenarios.portable_arithmetic`). The CPU switches (``OPENCV_CPU_DISABLE``,
``OPENCV_IPP``, ``NPY_DISABLE_CPU_FEATURES``, ``NUMBA_CPU_NAME``, ``LP_NATIVE_VECTOR_WIDTH``) are the caller's
environment: each is read when its library loads.

``compare A.json B.json`` prints, per OpenCV function and caller and per stage, how many calls had equal inputs and
a different result (the place where rounding enters), different inputs (carried from before), or were the same;
and which time-series columns differ. Run from the repository root::

    OFFTRACK_CAMERA_WORKERS=0 .venv/bin/python benchmarks/cpu_dispatch_trace.py trace /tmp/a.json
    OFFTRACK_CAMERA_WORKERS=0 OPENCV_CPU_DISABLE=AVX2,FMA3,AVX .venv/bin/python benchmarks/cpu_dispatch_trace.py \\
        trace /tmp/b.json
    .venv/bin/python benchmarks/cpu_dispatch_trace.py compare /tmp/a.json /tmp/b.json
"""

from __future__ import annotations

import collections
import hashlib
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

SWITCHES = ("OPENCV", "NPY", "NUMBA_CPU", "LP_", "OFFTRACK_PORTABLE")
UNWRAPPED = {"setNumThreads", "getNumThreads", "checkHardwareSupport", "useOptimized", "setUseOptimized"}
TIMINGS = {"render_ms", "vo_ms"}
"""Time-series columns that are wall times (never the same twice)."""


def _digest(value: Any, d: Any = None) -> Any:
    import numpy as np

    d = d or hashlib.sha256()
    if isinstance(value, np.ndarray):
        d.update(value.dtype.str.encode() + str(value.shape).encode())
        d.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, tuple | list):
        d.update(b"(")
        for v in value:
            _digest(v, d)
        d.update(b")")
    elif isinstance(value, dict):
        for k in sorted(value, key=str):
            d.update(str(k).encode())
            _digest(value[k], d)
    elif isinstance(value, float | np.floating):
        d.update(float(value).hex().encode())
    elif isinstance(value, int | str | bool | None | np.integer):
        d.update(repr(value).encode())
    elif hasattr(value, "__dict__"):
        _digest(vars(value), d)
    else:
        d.update(type(value).__name__.encode())
    return d


def _hex(value: Any) -> str:
    return _digest(value).hexdigest()[:12]


def trace(out: Path, portable: bool) -> None:
    """Run the short field camera run with every OpenCV call and stage recorded; write ``out`` (JSON)."""
    if portable:
        os.environ["OFFTRACK_PORTABLE_ARITHMETIC"] = "1"
    import cv2

    from scenarios.portable_arithmetic import apply

    apply()
    log: list[tuple[str, str, str, str]] = []

    def wrap(name: str, function: Any) -> Any:
        def call(*args: Any, **kwargs: Any) -> Any:
            caller = sys._getframe(1).f_code
            before = _hex((args, kwargs))
            result = function(*args, **kwargs)
            log.append((f"cv2.{name}", f"{Path(caller.co_filename).stem}.{caller.co_name}", before, _hex(result)))
            return result

        return call

    for name in dir(cv2):
        function = getattr(cv2, name)
        if type(function).__name__ == "builtin_function_or_method" and name not in UNWRAPPED:
            setattr(cv2, name, wrap(name, function))

    def stage(owner: Any, name: str, label: str) -> None:
        method = getattr(owner, name)

        def call(*args: Any, **kwargs: Any) -> Any:
            result = method(*args, **kwargs)
            log.append((f"stage.{label}", "stage", _hex((args[1:], kwargs)), _hex(result)))
            return result

        setattr(owner, name, call)

    import scenarios.camera.build as build
    import sensor.calibration as calibration
    from sensor.field_optics import FieldOptics
    from sensor.frame_odometry import FrameOdometry
    from sensor.renderer import StereoRenderer
    from sensor.stereo_camera import PairDeveloper

    stage(StereoRenderer, "render", "render")
    stage(FieldOptics, "optical", "optical (flex warp, lens)")
    stage(FieldOptics, "electronic", "electronic (noise, rectification)")
    stage(PairDeveloper, "develop", "develop")
    stage(FrameOdometry, "process", "odometry")
    build.cached_calibrate_rig = calibration.calibrate_rig  # computed here, not read from the disk cache
    stage(build, "cached_calibrate_rig", "calibration")
    build_world = build.build_world

    def world(*args: Any, **kwargs: Any) -> Any:
        built = build_world(*args, **kwargs)
        log.append(("stage.world textures", "stage", "", _hex(built.textures)))
        log.append(("stage.world mipmaps", "stage", "", _hex(built.mipmaps)))
        return built

    build.build_world = world

    import pandas as pd

    from scenarios.config import load_scenario
    from scenarios.run.runner import run_scenario
    from scenarios.studies.controller_limits_camera import camera_overrides

    overrides = dict(camera_overrides())
    duration = float(os.environ.get("TRACE_DURATION", "0.5"))
    overrides.update({"duration_s": duration, "camera.width": 672, "camera.height": 196})
    run_dir = out.with_suffix(".run")
    run_dir.mkdir(parents=True, exist_ok=True)
    cpu0 = time.process_time()
    run_scenario(load_scenario("roundabout-3", overrides), run_dir, plots=False)
    cpu_s = time.process_time() - cpu0
    series = pd.read_parquet(run_dir / "timeseries.parquet")
    record = {
        "environment": {k: v for k, v in os.environ.items() if k.startswith(SWITCHES)},
        "opencv_features": [i for i in range(1, 512) if cv2.checkHardwareSupport(i)],
        "opencv_optimized": cv2.useOptimized(),
        "opencv_threads": cv2.getNumThreads(),
        "ipp": cv2.ipp.getIppVersion() if cv2.ipp.useIPP() else "off",
        "cpu_s": cpu_s,
        "log": log,
        "columns": {c: _hex(series[c].to_numpy()) for c in series.columns},
    }
    out.write_text(json.dumps(record))
    print(f"{out}: {len(log)} calls, {cpu_s:.1f} s CPU")


def compare(a_path: Path, b_path: Path) -> None:
    """Print where two traces part (module notes)."""
    a, b = json.loads(a_path.read_text()), json.loads(b_path.read_text())
    for label, t in (("A", a), ("B", b)):
        print(
            label, t["environment"], "features", t["opencv_features"], "IPP", t["ipp"], "threads", t["opencv_threads"]
        )
    counts: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    for x, y in zip(a["log"], b["log"], strict=False):
        if x[0] != y[0]:
            print("the calls part ways at", x, y)
            break
        kind = ("same input, " if x[2] == y[2] else "other input, ") + (
            "same result" if x[3] == y[3] else "OTHER RESULT"
        )
        counts[f"{x[0]} <- {x[1]}"][kind] += 1
    print(f"calls: {len(a['log'])} / {len(b['log'])}")
    for key, c in counts.items():
        if set(c) != {"same input, same result"}:
            print(f"  {key}: {dict(c)}")
    same = sum(set(c) == {"same input, same result"} for c in counts.values())
    print(f"  every other function and caller ({same}): the same inputs and results")
    columns = [c for c in a["columns"] if a["columns"][c] != b["columns"].get(c) and c not in TIMINGS]
    print(f"time-series columns that differ (wall times aside): {len(columns)} of {len(a['columns'])}: {columns}")


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "trace":
        trace(Path(sys.argv[2]), "--portable" in sys.argv[3:])
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        compare(Path(sys.argv[2]), Path(sys.argv[3]))
    else:
        sys.exit(__doc__)
