"""What the visual odometry's first frames on a machine compile: numba's compiles per kernel, on an empty cache.

Runs :meth:`sensor.vo.StereoOdometry.process` on the first ``--frames`` frames of the cached rendered sequence of
``offtrack bench vo`` (:func:`scenarios.bench.vo.rendered_sequence`: roundabout-3, seed 0; the default
configuration of ``VOConfig.from_horizontal_fov``; OpenCV, BLAS and numba on one thread) in this process, with
numba's cache in a new empty folder (``NUMBA_CACHE_DIR``), and listens to numba's ``numba:compile`` events: per
kernel of ``sensor.vo`` the compiles, their thread CPU time including the kernels first compiled inside them
(``incl``) and without (``own``), and the signatures its dispatcher holds afterwards (a kernel called with
literal integer arguments holds one per value; docs/visual_odometry.md §16). Run from the repository root::

    .venv/bin/python benchmarks/vo_cold_compile.py [--frames 3] [--json]
"""

from __future__ import annotations

import os
import tempfile

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread, before numpy is imported
os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="vo_cold_compile_")  # empty: everything compiles

import argparse  # noqa: E402
import collections  # noqa: E402
import importlib  # noqa: E402
import json  # noqa: E402
import pkgutil  # noqa: E402
import resource  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numba  # noqa: E402
from numba.core import event  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


class CompileListener(event.Listener):
    """Thread CPU time of every ``numba:compile`` event, with the time of the events nested in it."""

    def __init__(self) -> None:
        self.open: list[list[Any]] = []
        self.events: list[dict[str, Any]] = []

    def on_start(self, ev: event.Event) -> None:
        function = ev.data["dispatcher"].py_func
        self.open.append([f"{function.__module__}.{function.__qualname__}", time.thread_time(), 0.0])

    def on_end(self, ev: event.Event) -> None:
        name, start, nested = self.open.pop()
        incl = time.thread_time() - start
        if self.open:
            self.open[-1][2] += incl
        self.events.append({"kernel": name, "incl_s": incl, "own_s": incl - nested})


def _process_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def cold_compile(frames: int) -> dict[str, Any]:
    """Compile events and signatures of the odometry's first ``frames`` frames on an empty numba cache."""
    listener = CompileListener()
    event.register("numba:compile", listener)
    import cv2

    import sensor.vo
    from scenarios.bench.vo import rendered_sequence, vo_calibration
    from sensor.vo import StereoOdometry, VOConfig

    cv2.setNumThreads(1)
    sequence = rendered_sequence()  # the 30 frames of `offtrack bench vo`, rendered once and cached
    vo = StereoOdometry(VOConfig.from_horizontal_fov(*vo_calibration(sequence)), seed=0)
    start = _process_cpu()
    for i in range(frames):
        vo.process(sequence.left[i], sequence.right[i])
    frames_cpu = _process_cpu() - start
    event.unregister("numba:compile", listener)
    kernels: dict[str, dict[str, Any]] = collections.defaultdict(lambda: {"compiles": 0, "incl_s": 0.0, "own_s": 0.0})
    for e in listener.events:
        k = kernels[e["kernel"]]
        k["compiles"] += 1
        k["incl_s"] += e["incl_s"]
        k["own_s"] += e["own_s"]
    for info in pkgutil.iter_modules(sensor.vo.__path__):
        module = importlib.import_module(f"sensor.vo.{info.name}")
        for name, value in vars(module).items():
            if isinstance(value, numba.core.dispatcher.Dispatcher) and value.py_func.__module__ == module.__name__:
                kernels[f"{module.__name__}.{name}"]["signatures"] = len(value.signatures)
    return {
        "frames": frames,
        "numba": numba.__version__,
        "process_cpu_s": frames_cpu,
        "compile_cpu_s": sum(e["own_s"] for e in listener.events),
        "signatures": sum(k.get("signatures", 0) for k in kernels.values()),
        "kernels": dict(kernels),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=3, help="frames processed (1-30; default 3)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    args = parser.parse_args()
    if not 1 <= args.frames <= 30:
        parser.error(f"--frames must be within 1-30, got {args.frames}")
    try:
        result = cold_compile(args.frames)
    finally:
        shutil.rmtree(os.environ["NUMBA_CACHE_DIR"], ignore_errors=True)
    if args.json:
        print(json.dumps(result, indent=1))
        return
    print(
        f"{args.frames} frames: process CPU {result['process_cpu_s']:.1f} s, compiles {result['compile_cpu_s']:.1f} s"
    )
    print(f"{'kernel':55s} {'compiles':>8s} {'incl s':>7s} {'own s':>6s} {'signatures':>10s}")
    ranked = sorted(result["kernels"].items(), key=lambda kv: -kv[1]["incl_s"])
    for name, k in ranked:
        if k["compiles"] or k.get("signatures"):
            print(f"{name:55s} {k['compiles']:8d} {k['incl_s']:7.2f} {k['own_s']:6.2f} {k.get('signatures', 0):10d}")


if __name__ == "__main__":
    main()
