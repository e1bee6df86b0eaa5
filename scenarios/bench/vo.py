"""``offtrack bench vo``: the stereo visual odometry alone, one thread, on a fixed rendered sequence.

:func:`rendered_sequence` simulates a scenario (default ``roundabout-3``, seeded) long enough for its
first camera frames, renders them and caches the pairs with the left camera's true poses (an ``.npz``
under ``$OFFTRACK_CACHE_DIR`` or ``~/.cache/offtrack``, ``vo_bench/``), so that every benchmark run —
and ``benchmarks/vo_speed_against_baseline.py``, which compares with the VO of a baseline commit — sees the
same frames. :func:`bench_vo` times :meth:`sensor.vo.StereoOdometry.process` on them with OpenCV
limited to one thread: thread CPU time per frame (median and p90, robust to other processes on a
shared machine), wall time, and the stage breakdown (features; matching with bucketing and
refinement; motion).
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vehicle_model.geometry import CombinationPose

from ..camera.build import stereo_camera
from ..config import load_scenario
from ..loop.trailer_steer import UnsteeredTrailer, trailer_axles
from ..run.drive import simulate
from ..setup.build import build_scenario

__all__ = [
    "RenderedSequence",
    "bench_vo",
    "compared_settings",
    "frame_errors",
    "relative_motions",
    "rendered_sequence",
    "vo_calibration",
]

_CACHE_VERSION = 1  # bump when the rendering of the sequence changes


@dataclass(frozen=True, eq=False)
class RenderedSequence:
    """Rendered stereo frames with their ground truth.

    Attributes
    ----------
    left, right : numpy.ndarray
        (n, H, W) uint8 rectified grey images.
    poses : numpy.ndarray
        (n, 4, 4) true left-camera poses ``T_world←camera`` (OpenCV axes) [m].
    calibration : dict
        ``width``, ``height``, ``hfov`` [rad] and ``baseline`` [m] of the rig.
    scenario : str
        Scenario name.
    seed : int
        Scenario seed (world, image noise).
    """

    left: np.ndarray
    right: np.ndarray
    poses: np.ndarray
    calibration: dict[str, float]
    scenario: str
    seed: int

    def __len__(self) -> int:
        return int(self.left.shape[0])


def _cache_dir() -> Path:
    root = os.environ.get("OFFTRACK_CACHE_DIR")
    return (Path(root) if root else Path.home() / ".cache" / "offtrack") / "vo_bench"


def rendered_sequence(frames: int = 30, seed: int = 0, scenario: str = "roundabout-3") -> RenderedSequence:
    """The first ``frames`` camera frames of a scenario's run, rendered once and then read from the cache.

    Parameters
    ----------
    frames : int
        Stereo pairs (≥ 2).
    seed : int
        Scenario seed (``seed`` of the configuration: world, image noise).
    scenario : str
        Catalogue name.

    Returns
    -------
    RenderedSequence
    """
    if frames < 2:
        raise ValueError(f"frames must be at least 2, got {frames}")
    config = load_scenario(scenario, {"seed": seed, "estimators.zero_slip": False})
    needed = (frames - 1) / config.rates.camera_hz + 2.0 / config.rates.control_hz
    config = config.model_copy(update={"duration_s": needed})
    key = json.dumps([_CACHE_VERSION, scenario, seed, frames, config.model_dump(mode="json")], sort_keys=True)
    path = _cache_dir() / f"{scenario}-s{seed}-{frames}-{hashlib.sha256(key.encode()).hexdigest()[:12]}.npz"
    if path.exists():
        with np.load(path) as data:
            cal = json.loads(str(data["calibration"]))
            return RenderedSequence(data["left"], data["right"], data["poses"], cal, scenario, seed)
    setup = build_scenario(config)
    _, cols = simulate(setup, UnsteeredTrailer(trailer_axles(setup)))
    camera = stereo_camera(setup, ideal=True)  # the scenario's rig as an ideal pinhole pair, flat lighting
    rig = camera.rig
    ticks = np.flatnonzero(np.asarray(cols["camera_frame"]) > 0.5)[:frames]
    combination = CombinationPose(*(np.asarray(cols[k])[ticks] for k in ("X", "Y", "psi1", "gamma")))
    poses = rig.camera_in_world(setup.params, combination, "left")
    right_poses = rig.camera_in_world(setup.params, combination, "right")
    pairs = [camera.develop(camera.render_poses(poses[k], right_poses[k], k), k) for k in range(len(ticks))]
    left = np.stack([p[0] for p in pairs])
    right = np.stack([p[1] for p in pairs])
    cal = {"width": rig.width, "height": rig.height, "hfov": float(rig.hfov), "baseline": float(rig.baseline)}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, left=left, right=right, poses=poses, calibration=json.dumps(cal))
    tmp.replace(path)
    return RenderedSequence(left, right, poses, cal, scenario, seed)


def vo_calibration(sequence: RenderedSequence) -> tuple[int, int, float, float]:
    """``(width, height, hfov, baseline)``: the arguments of ``VOConfig.from_horizontal_fov``."""
    cal = sequence.calibration
    return int(cal["width"]), int(cal["height"]), float(cal["hfov"]), float(cal["baseline"])


def relative_motions(poses: np.ndarray) -> np.ndarray:
    """True Tr_delta of each frame after the first: inv(T_k)·T_{k−1}, (n − 1, 4, 4)."""
    return np.linalg.solve(poses[1:], poses[:-1])


def compared_settings(compare: Mapping[str, Any] | None) -> dict[str, Any]:
    """``compare``'s :class:`~sensor.vo.VOConfig` fields, checked before any work.

    Raises
    ------
    ValueError
        One line naming ``--compare``, the field and its allowed values: a name that is not a field, or a value
        outside the field's range.
    """
    from pydantic import ValidationError

    from sensor.vo import VOConfig

    changes = dict(compare or {})
    fields = sorted(VOConfig.model_fields)
    for name in changes:
        if name not in VOConfig.model_fields:
            raise ValueError(f"--compare {name}: not an odometry setting; one of {', '.join(fields)}")
    try:
        VOConfig.from_horizontal_fov(1344, 391, 1.5, 0.5).replace(**changes)  # any camera: the changes are checked
    except ValidationError as exc:
        first = exc.errors()[0]
        name = ".".join(str(part) for part in first["loc"])
        raise ValueError(f"--compare {name}={changes.get(name)!r}: {first['msg']}") from None
    return changes


def frame_errors(results: list, truth: np.ndarray) -> np.ndarray:
    """(n − 1, 2) translation [m] and rotation [rad] error of each frame's estimated ``Tr_delta`` after the first
    against ``truth`` (:func:`relative_motions`), NaN for a frame without one."""
    errors = np.full((len(truth), 2), np.nan)
    for k, (result, true) in enumerate(zip(results[1:], truth, strict=True)):
        if result.motion is not None:
            err = np.linalg.solve(true, result.motion)
            errors[k] = np.linalg.norm(err[:3, 3]), np.arccos(np.clip((np.trace(err[:3, :3]) - 1.0) / 2.0, -1.0, 1.0))
    return errors


def bench_vo(
    frames: int = 30,
    scenario: str = "roundabout-3",
    seed: int = 0,
    passes: int = 3,
    compare: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Visual odometry alone, one thread, on a scenario's cached rendered frames (1344×391 by default).

    Parameters
    ----------
    frames : int
        Stereo pairs of the sequence.
    scenario : str
        Catalogue name of the scenario rendered.
    seed : int
        Scenario seed; the odometry runs with seed 0.
    passes : int
        Timed passes over the sequence after one warm-up pass (JIT compilation, caches); per frame the
        fastest pass counts.
    compare : mapping, optional
        :class:`~sensor.vo.VOConfig` fields (e.g. ``{"gradient_refinement": "lucas_kanade"}``) of a second odometry
        timed beside the default in the same passes, the two alternating (:func:`compared_settings`).

    Returns
    -------
    dict
        ``cpu_ms_median`` and ``cpu_ms_p90`` (thread CPU time per frame, frames after the first),
        ``wall_ms_median``, the stage medians ``cpu_ms_features``, ``cpu_ms_matching`` (matching,
        bucketing and refinement) and ``cpu_ms_motion`` (thread CPU time), ``first_call_s`` (the
        warm-up pass's first two frames: import-time compilation or cache load), ``fps`` (one over the
        median CPU time), matches, inliers, the valid fraction and the mean per-frame error against the true
        motion, ``t_rpe_mm`` and ``r_rpe_mrad``. With ``compare``: ``compare`` (its settings), the same figures
        prefixed ``compare_`` and ``cpu_ratio`` (its median CPU time over the default's).
    """
    import cv2

    from sensor.vo import StereoOdometry, VOConfig

    if passes < 1:
        raise ValueError(f"passes must be at least 1, got {passes}")
    changes = compared_settings(compare)
    sequence = rendered_sequence(frames, seed, scenario)
    config = VOConfig.from_horizontal_fov(*vo_calibration(sequence))
    configs = {"": config} | ({"compare_": config.replace(**changes)} if compare is not None else {})
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        timings = {prefix: _Timing(StereoOdometry(c, seed=0), len(sequence)) for prefix, c in configs.items()}
        for k in range(passes + 1):
            for timing in timings.values():  # the two odometries alternate, pass by pass
                timing.run(sequence, warm_up=k == 0)
    finally:
        cv2.setNumThreads(threads)
    truth = relative_motions(sequence.poses)
    out: dict[str, Any] = {
        "benchmark": "vo",
        "scenario": scenario,
        "seed": seed,
        "frames": len(sequence),
        "width": int(sequence.calibration["width"]),
        "height": int(sequence.calibration["height"]),
        "passes": passes,
    }
    for prefix, timing in timings.items():
        out.update({prefix + key: value for key, value in timing.figures(truth).items()})
    if compare is not None:
        out["compare"] = changes
        out["cpu_ratio"] = out["compare_cpu_ms_median"] / out["cpu_ms_median"]
    out.update({"opencv_threads": 1, "python": platform.python_version()})
    return out


class _Timing:
    """One odometry's per-frame times over the passes: the fastest pass per frame (thread CPU, wall, stages)."""

    def __init__(self, vo: Any, n: int) -> None:
        self.vo = vo
        self.cpu = np.full(n, np.inf)
        self.wall = np.full(n, np.inf)
        self.stages = np.full((n, 3), np.inf)
        self.first_call = 0.0
        self.results: list = []

    def run(self, sequence: RenderedSequence, warm_up: bool) -> None:
        self.vo.reset()
        self.results = []
        for i in range(len(sequence)):
            c0, w0 = time.thread_time(), time.perf_counter()
            self.results.append(self.vo.process(sequence.left[i], sequence.right[i]))
            c1, w1 = time.thread_time(), time.perf_counter()
            if warm_up:
                self.first_call += (w1 - w0) if i < 2 else 0.0
                continue
            self.cpu[i] = min(self.cpu[i], c1 - c0)
            self.wall[i] = min(self.wall[i], w1 - w0)
            r = self.results[-1]
            self.stages[i] = np.minimum(self.stages[i], [r.cpu_features, r.cpu_matching, r.cpu_motion])

    def figures(self, truth: np.ndarray) -> dict[str, float]:
        steady = slice(1, None)
        med = float(np.median(self.cpu[steady]))
        errors = frame_errors(self.results, truth)
        results = self.results[1:]
        return {
            "cpu_ms_median": 1e3 * med,
            "cpu_ms_p90": 1e3 * float(np.percentile(self.cpu[steady], 90)),
            "wall_ms_median": 1e3 * float(np.median(self.wall[steady])),
            "cpu_ms_features": 1e3 * float(np.median(self.stages[steady, 0])),
            "cpu_ms_matching": 1e3 * float(np.median(self.stages[steady, 1])),
            "cpu_ms_motion": 1e3 * float(np.median(self.stages[steady, 2])),
            "first_call_s": self.first_call,
            "fps": 1.0 / med,
            "mean_matches": float(np.mean([r.n_matches for r in results])),
            "mean_inliers": float(np.mean([r.n_inliers for r in results])),
            "valid_fraction": float(np.mean([r.valid for r in results])),
            "t_rpe_mm": 1e3 * float(np.nanmean(errors[:, 0])) if np.isfinite(errors[:, 0]).any() else float("nan"),
            "r_rpe_mrad": 1e3 * float(np.nanmean(errors[:, 1])) if np.isfinite(errors[:, 1]).any() else float("nan"),
        }
