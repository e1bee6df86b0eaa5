"""Speed of the stereo visual odometry on one core (DESIGN §9: aim for ≥ 40 fps at 1344×391).

Renders a synthetic planar sequence (:mod:`sensor.vo.synthetic`), then times
:meth:`StereoOdometry.process` alone at steady state. Scenes: ``busy`` — textured ground and wall
filling the whole view, about 8 500 features per image (a worst case); ``open`` — ground and
featureless sky with a smoother texture, about 4 000 features per image.
The process is pinned to one CPU and OpenCV to one thread. Run ``python -m sensor.vo.benchmark``
(``--profile`` adds a cProfile table); it prints one JSON object.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import pstats
import time

import cv2
import numpy as np

from sensor.vo.odometry import StereoOdometry
from sensor.vo.synthetic import PlanarScene, planar_sequence

__all__ = ["bench_vo"]


def _pin_one_core() -> set[int] | None:
    """Pin the process to one CPU; return the previous affinity (None where unsupported)."""
    try:
        cpus = os.sched_getaffinity(0)
        os.sched_setaffinity(0, {max(cpus)})
    except (AttributeError, OSError):  # not Linux
        return None
    return cpus


def _restore(cpus: set[int] | None) -> None:
    if cpus is not None:
        os.sched_setaffinity(0, cpus)


SCENES = {"busy": {}, "open": {"wall_distance": None, "smoothing": 4.0}}


def bench_vo(n_frames: int = 12, passes: int = 3, profile: bool = False, seed: int = 0, scene: str = "busy") -> dict:
    """Time the odometry on a rendered 1344×391 sequence.

    Parameters
    ----------
    n_frames : int
        Frames of the sequence (≥ 3).
    passes : int
        Timed passes over the sequence (after one warm-up pass); the fastest pass of each frame counts.
    profile : bool
        Add the top functions of a cProfile run (``profile_top``).
    seed : int
        Seed of the odometry.
    scene : str
        ``"busy"`` or ``"open"`` (see the module docstring).

    Returns
    -------
    dict
        ``fps`` (1 / median steady-state CPU time of a frame, the fastest of the passes per frame —
        robust to other processes on the machine), ``fps_wall`` (the same in wall-clock time),
        ``ms_per_frame``, ``ms_features``, ``ms_matching``, ``ms_motion`` (wall-clock medians),
        ``ms_first_frame``, counts and, with ``profile``, ``profile_top``.
    """
    if n_frames < 3:
        raise ValueError(f"n_frames must be ≥ 3, got {n_frames}")
    if scene not in SCENES:
        raise ValueError(f"scene must be one of {sorted(SCENES)}, got {scene!r}")
    previous_affinity = _pin_one_core()
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        seq = planar_sequence(n_frames, scene=PlanarScene.procedural(**SCENES[scene]))
        config = seq.rig.vo_config()
        vo = StereoOdometry(config, seed)

        def run() -> tuple[list, list[float]]:
            vo.reset()
            results, cpu = [], []
            for left, right in zip(seq.left, seq.right, strict=True):
                c0 = time.thread_time()
                results.append(vo.process(left, right))
                cpu.append(time.thread_time() - c0)
            return results, cpu

        run()  # warm-up (caches, allocator)
        wall = np.full(n_frames, np.inf)
        cpu = np.full(n_frames, np.inf)
        parts = np.full((n_frames - 1, 3), np.inf)
        for _ in range(passes):
            results, cpu_times = run()
            wall = np.minimum(wall, [r.time_total for r in results])
            cpu = np.minimum(cpu, cpu_times)
            parts = np.minimum(parts, [[r.time_features, r.time_matching, r.time_motion] for r in results[1:]])
        breakdown = np.median(parts, axis=0)
        out = {
            "benchmark": "vo",
            "scene": scene,
            "image": f"{seq.rig.width}x{seq.rig.height}",
            "frames": n_frames,
            "opencv_threads": 1,
            "pinned_one_core": previous_affinity is not None,
            "fps": float(1.0 / np.median(cpu[1:])),
            "fps_wall": float(1.0 / np.median(wall[1:])),
            "ms_per_frame": float(1e3 * np.median(cpu[1:])),
            "ms_per_frame_wall": float(1e3 * np.median(wall[1:])),
            "ms_per_frame_max": float(1e3 * cpu[1:].max()),
            "ms_features": float(1e3 * breakdown[0]),
            "ms_matching": float(1e3 * breakdown[1]),
            "ms_motion": float(1e3 * breakdown[2]),
            "ms_first_frame": float(1e3 * cpu[0]),
            "n_features_dense": len(vo._previous[0].dense) if vo._previous else 0,
            "n_matches": int(np.median([r.n_matches for r in results[1:]])),
            "n_inliers": int(np.median([r.n_inliers for r in results[1:]])),
            "valid_frames": int(sum(r.valid for r in results[1:])),
        }
        if profile:
            prof = cProfile.Profile()
            prof.enable()
            run()
            prof.disable()
            stream = io.StringIO()
            pstats.Stats(prof, stream=stream).sort_stats("tottime").print_stats(15)
            out["profile_top"] = stream.getvalue()
        return out
    finally:
        cv2.setNumThreads(threads)
        _restore(previous_affinity)


def main(argv: list[str] | None = None) -> None:
    """Command-line entry: print the benchmark as JSON."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=12)
    parser.add_argument("--passes", type=int, default=3)
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--scene", choices=sorted(SCENES), default="busy")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    result = bench_vo(args.frames, args.passes, args.profile, scene=args.scene)
    result["wall_s"] = time.perf_counter() - t0
    profile_text = result.pop("profile_top", None)
    print(json.dumps(result))
    if profile_text:
        print(profile_text)


if __name__ == "__main__":
    main()
