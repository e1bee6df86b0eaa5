"""Fingerprint offtrack's observable behaviour, to show that a restructuring changed none of it.

Runs a fixed set of cases through the interfaces users have (the ``offtrack`` command line and
``gymnasium.make``), stores every recorded number, and compares two such fingerprints column by column::

    python benchmarks/behaviour_fingerprint.py record OUT_DIR [--only PREFIX ...]
    python benchmarks/behaviour_fingerprint.py compare BEFORE_DIR AFTER_DIR

The cases:

* ``run/…`` — model-only runs of the five catalogue scenarios with every model-only feedback source
  (``none``, ``truth``, ``zero_slip``; the steered ones on the ``lst``), on dry and icy cambered roads: every
  column of ``timeseries.parquet`` and the numbers of ``metrics.json`` (wall times left out);
* ``camera/…`` — rendered closed loops (VISO-OT and fused VISO-OT feedback, ideal and field cameras, serial and
  pipelined): every column, the per-frame visual-odometry columns included;
* ``render/…`` — ``offtrack render`` datasets: every image's bytes, ``calib.txt``, ``poses.txt``;
* ``env/…`` — Gymnasium episodes with fixed seeds and actions: observations, rewards, ends and the numbers of
  ``info``;
* ``study/…`` — the default (small) subsets of the studies (``scenarios.studies.registry.STUDIES``): every
  column of ``table.csv`` but wall times, hosts and paths.

``compare`` prints, per case, ``identical`` or the columns that differ with the largest absolute and relative
difference, and exits 1 if any column differs by more than ``--rtol`` (default 1e-12, relative) or is missing.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from scenarios.studies.registry import STUDIES as STUDY_REGISTRY

OFFTRACK = [sys.executable, "-c", "from scenarios.cli import main; main()"]

FIELD = [
    "camera.lens={k1: -0.08, k2: 0.01, p1: 0.0002, p2: -0.0001, k3: 0.0}",
    "camera.calibration={mode: estimated, views: 15, corner_noise_px: 0.1}",
    "camera.lighting={sun: true, sun_azimuth_deg: 270.0, sun_elevation_deg: 10.0, exposure_lag_s: 0.5}",
    "camera.world=airfield",
    "camera.flex={twist_deg_per_mps2: [0.05, 0.0, -0.03], vibration_rms_deg: [0.01, 0.01, 0.01]}",
    "camera.right_misalignment_deg=[0.25, -0.12, -0.18]",
    "camera.self_calibration.enabled=true",
]
"""The field conditions of the camera cases (a calibration of 15 views to keep it short)."""

MODEL_RUNS: dict[str, list[str]] = {
    "run/roundabout-test/reference/none": ["roundabout-test"],
    "run/roundabout-test/lst/none": ["roundabout-test", "--vehicle", "lst"],
    "run/roundabout-test/lst/truth": ["roundabout-test", "--vehicle", "lst", "--feedback", "truth"],
    "run/roundabout-test/lst/zero_slip": ["roundabout-test", "--vehicle", "lst", "--feedback", "zero_slip"],
    "run/roundabout-3/lst/none": ["roundabout-3", "--vehicle", "lst"],
    "run/roundabout-3/lst/truth": ["roundabout-3", "--vehicle", "lst", "--feedback", "truth"],
    "run/roundabout-3/lst/zero_slip": ["roundabout-3", "--vehicle", "lst", "--feedback", "zero_slip"],
    "run/roundabout-3/lst/ice5/zero_slip": [
        "roundabout-3",
        "--vehicle",
        "lst",
        "--feedback",
        "zero_slip",
        "--surface",
        "ice",
        "--camber",
        "5",
    ],
    "run/roundabout-3/lst/ice5/truth": [
        "roundabout-3",
        "--vehicle",
        "lst",
        "--feedback",
        "truth",
        "--surface",
        "ice",
        "--camber",
        "5",
    ],
    "run/roundabout-450/lst/none": ["roundabout-450", "--vehicle", "lst", "--direction", "right"],
    "run/roundabout-450/lst/truth": ["roundabout-450", "--vehicle", "lst", "--feedback", "truth", "--mu", "0.2"],
    "run/roundabout-450/lst/zero_slip": ["roundabout-450", "--vehicle", "lst", "--feedback", "zero_slip"],
    "run/figure-eight/lst/none": ["figure-eight", "--vehicle", "lst"],
    "run/figure-eight/lst/truth": ["figure-eight", "--vehicle", "lst", "--feedback", "truth"],
    "run/figure-eight/lst/zero_slip": [
        "figure-eight",
        "--vehicle",
        "lst",
        "--feedback",
        "zero_slip",
        "--set",
        "estimators.zero_slip_variant=steer_angle",
        "--set",
        "signals.tractor_yaw_rate.noise_std=0.002",
        "--set",
        "signals.articulation.bias=0.001",
        "--seed",
        "7",
    ],
    "run/constant-slip/none": ["constant-slip"],
    "run/roundabout-3/lst/truth/kp": [
        "roundabout-3",
        "--vehicle",
        "lst",
        "--feedback",
        "truth",
        "--set",
        "controller.kp=0.5",
        "--set",
        "controller.ki=0.05",
        "--set",
        "controller.kd=0.2",
        "--set",
        "controller.feedforward=steady",
        "--duration",
        "60",
    ],
}

VISO_OT_RUN = ["roundabout-3", "--vehicle", "lst", "--feedback", "viso_ot", "--set", "estimators.viso_ot=true"]
VISO_OT_RUN += ["--duration", "10"]
"""A VISO-OT closed loop with ideal cameras (serial and pipelined must agree)."""

FUSED_FIELD_RUN = [
    *("roundabout-3", "--vehicle", "lst", "--feedback", "viso_ot_fused", "--set", "estimators.viso_ot_fused=true"),
    *("--duration", "10", "--seed", "3", *[a for item in FIELD for a in ("--set", item)]),
]
"""A fused VISO-OT closed loop under the field conditions (serial and pipelined must agree)."""

CAMERA_RUNS: dict[str, tuple[list[str], dict[str, str]]] = {
    "camera/roundabout-3/viso_ot/serial": (VISO_OT_RUN, {"OFFTRACK_CAMERA_WORKERS": "0"}),
    "camera/roundabout-3/viso_ot/pipelined": (VISO_OT_RUN, {"OFFTRACK_CAMERA_WORKERS": "1"}),
    "camera/roundabout-3/fused-field/serial": (FUSED_FIELD_RUN, {"OFFTRACK_CAMERA_WORKERS": "0"}),
    "camera/roundabout-3/fused-field/pipelined": (FUSED_FIELD_RUN, {"OFFTRACK_CAMERA_WORKERS": "1"}),
    "camera/constant-slip/side": (
        [
            "constant-slip",
            "--set",
            "estimators.viso_ot=true",
            "--set",
            "camera.psi_c2v_deg=270",
            "--set",
            "camera.lateral=1.275",
            "--set",
            "camera.baseline=1.5",
            "--duration",
            "6",
        ],
        {"OFFTRACK_CAMERA_WORKERS": "0"},
    ),
}

RENDERS: dict[str, list[str]] = {
    "render/roundabout-3": ["roundabout-3", "--frames", "4", "--seed", "2"],
    "render/figure-eight/field": ["figure-eight", "--frames", "3", *[a for item in FIELD for a in ("--set", item)]],
}

STUDIES = tuple(STUDY_REGISTRY)
"""Every study of :data:`scenarios.studies.registry.STUDIES`, run by name on the command line."""

VOLATILE = ("wall", "_at", "host", "pid", "worker", "run_dir", "path", "elapsed", "_ms", "cpu")
"""Parts of column or key names whose values are timings, places or processes, not behaviour."""


def _volatile(name: str) -> bool:
    return any(part in name for part in VOLATILE)


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for key, item in value.items():
            _flatten(f"{prefix}.{key}" if prefix else str(key), item, out)
    elif isinstance(value, list | tuple) and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        out[prefix] = np.asarray(value, dtype=float)
    elif isinstance(value, bool | int | float) or value is None:
        out[prefix] = np.asarray([math.nan if value is None else float(value)])
    elif isinstance(value, np.ndarray) and value.dtype.kind in "fiub":
        out[prefix] = np.asarray(value, dtype=float).ravel()
    else:
        out[prefix] = str(value)


def _offtrack(args: list[str], env: dict[str, str] | None = None) -> None:
    proc = subprocess.run([*OFFTRACK, *args], env={**os.environ, **(env or {})}, capture_output=True, text=True)
    if proc.returncode not in (0, 3):
        raise RuntimeError(f"offtrack {' '.join(args)} exited {proc.returncode}:\n{proc.stderr[-3000:]}")


def _run_columns(run_dir: Path) -> dict[str, Any]:
    import pandas as pd

    frame = pd.read_parquet(run_dir / "timeseries.parquet")
    out: dict[str, Any] = {f"col.{c}": frame[c].to_numpy(dtype=float) for c in frame.columns if not _volatile(c)}
    metrics = json.loads((run_dir / "metrics.json").read_text())
    flat: dict[str, Any] = {}
    _flatten("", metrics, flat)
    out.update({f"metrics.{k}": v for k, v in flat.items() if not _volatile(k) and k not in ("camera.workers",)})
    return out


def record_runs(work: Path, only: list[str]) -> dict[str, dict[str, Any]]:
    cases: dict[str, dict[str, Any]] = {}
    for name, args in MODEL_RUNS.items():
        if name in only:
            out = work / name
            _offtrack(["run", *args, "--no-plots", "--out", str(out), "--force"])
            cases[name] = _run_columns(out)
    for name, (args, env) in CAMERA_RUNS.items():
        if name in only:
            out = work / name
            _offtrack(["run", *args, "--no-plots", "--out", str(out), "--force"], env)
            cases[name] = _run_columns(out)
    return cases


def record_renders(work: Path, only: list[str]) -> dict[str, dict[str, Any]]:
    cases: dict[str, dict[str, Any]] = {}
    for name, args in RENDERS.items():
        if name not in only:
            continue
        out = work / name
        if out.exists():
            shutil.rmtree(out)
        _offtrack(["render", *args, "--out", str(out)])
        import cv2

        values: dict[str, Any] = {}
        for image in sorted(out.glob("image_*/*.png")):
            pixels = cv2.imread(str(image), cv2.IMREAD_UNCHANGED)
            values[f"image.{image.parent.name}/{image.name}"] = pixels.astype(float).ravel()
        for text in ("calib.txt", "poses.txt", "times.txt"):
            values[f"text.{text}"] = hashlib.sha256((out / text).read_bytes()).hexdigest()
        cases[name] = values
    return cases


def _episode(env_id: str, kwargs: dict[str, Any], seed: int, steps: int, actions: str) -> dict[str, Any]:
    import gymnasium

    import scenarios.envs  # noqa: F401  (registers the environments)

    env = gymnasium.make(env_id, **kwargs)
    obs, info = env.reset(seed=seed)
    rows: dict[str, list[Any]] = {"obs": [np.asarray(obs, dtype=float)]}
    flat: dict[str, Any] = {}
    _flatten("reset_info", info, flat)
    for k in range(steps):
        if actions == "sine":
            action = np.array([0.3 * math.sin(0.05 * k)], dtype=np.float32)
        elif actions == "zero":
            action = np.zeros(env.action_space.shape, dtype=np.float32)
        else:
            action = np.array([0.2, -0.4, 0.1], dtype=np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        rows["obs"].append(np.asarray(obs, dtype=float))
        rows.setdefault("reward", []).append(float(reward))
        rows.setdefault("ended", []).append(float(terminated) + 2.0 * float(truncated))
        step_info: dict[str, Any] = {}
        _flatten("", {k2: v for k2, v in info.items() if k2 not in ("config",)}, step_info)
        for key, value in step_info.items():
            if isinstance(value, np.ndarray):
                rows.setdefault(f"info.{key}", []).append(value)
            else:
                flat[f"info_text.{key}.{k}"] = value
        if terminated or truncated:
            _flatten("final_info", {k2: v for k2, v in info.items() if k2 not in ("config",)}, flat)
            break
    env.close()
    out = {key: np.concatenate([np.ravel(v) for v in values]) for key, values in rows.items()}
    out.update({k: v for k, v in flat.items() if not _volatile(k)})
    return out


ENVS: dict[str, tuple[str, dict[str, Any], int, int, str]] = {
    "env/steering/truth/direct": ("offtrack/TrailerSteering-v0", {}, 3, 400, "sine"),
    "env/steering/truth/full": ("offtrack/TrailerSteering-v0", {"overrides": {"path.turns": 0.1}}, 4, 5000, "zero"),
    "env/steering/zero_slip/residual": (
        "offtrack/TrailerSteering-v0",
        {
            "feedback": "zero_slip",
            "action_mode": "residual",
            "randomise": {"mu": (0.1, 0.8), "direction": ("left", "right")},
        },
        5,
        300,
        "sine",
    ),
    "env/steering/viso_ot_fused": ("offtrack/TrailerSteering-v0", {"feedback": "viso_ot_fused"}, 6, 120, "sine"),
    "env/steering/viso_ot": ("offtrack/TrailerSteering-v0", {"feedback": "viso_ot"}, 8, 80, "sine"),
    "env/gain_tuning": ("offtrack/GainTuning-v0", {"randomise": {"mu": (0.2, 0.8)}}, 7, 1, "gains"),
}


def record_envs(only: list[str]) -> dict[str, dict[str, Any]]:
    os.environ.setdefault("OFFTRACK_CAMERA_WORKERS", "0")
    return {name: _episode(*spec) for name, spec in ENVS.items() if name in only}


def record_studies(work: Path, only: list[str]) -> dict[str, dict[str, Any]]:
    import pandas as pd

    cases: dict[str, dict[str, Any]] = {}
    for study in STUDIES:
        name = f"study/{study}"
        if name not in only:
            continue
        out = work / name
        _offtrack(["study", study, "--out", str(out), "--force", "--no-resume"], {"OFFTRACK_CAMERA_WORKERS": "0"})
        table = pd.read_csv(out / "table.csv")
        values: dict[str, Any] = {}
        for column in table.columns:
            if _volatile(column):
                continue
            series = table[column]
            if series.dtype.kind in "fiub":
                values[f"table.{column}"] = series.to_numpy(dtype=float)
            else:
                values[f"table.{column}"] = "|".join(map(str, series.tolist()))
        cases[name] = values
    return cases


def _wanted(name: str, only: list[str]) -> bool:
    return not only or any(name.startswith(prefix) for prefix in only)


def _digest(value: Any) -> str:
    if isinstance(value, np.ndarray):
        return hashlib.sha256(np.ascontiguousarray(value, dtype=float).tobytes()).hexdigest()[:16]
    return hashlib.sha256(json.dumps(value).encode()).hexdigest()[:16]


def record(out: Path, only: list[str]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    work = out / "work"
    arrays = out / "arrays"
    arrays.mkdir(exist_ok=True)
    index_path = out / "fingerprint.json"
    index = json.loads(index_path.read_text()) if index_path.is_file() else {}
    failed = []

    def save(name: str, values: dict[str, Any]) -> None:
        stem = name.replace("/", "__")
        numeric = {k: v for k, v in values.items() if isinstance(v, np.ndarray)}
        np.savez_compressed(arrays / f"{stem}.npz", **numeric)
        (arrays / f"{stem}.json").write_text(json.dumps({k: v for k, v in values.items() if k not in numeric}))
        index[name] = {k: _digest(v) for k, v in sorted(values.items())}
        index_path.write_text(json.dumps(index, indent=1, sort_keys=True))
        print(f"recorded {name}", flush=True)

    groups = [
        *((name, lambda n=name: record_runs(work, [n])[n]) for name in [*MODEL_RUNS, *CAMERA_RUNS]),
        *((name, lambda n=name: record_renders(work, [n])[n]) for name in RENDERS),
        *((name, lambda n=name: record_envs([n])[n]) for name in ENVS),
        *((f"study/{s}", lambda n=f"study/{s}": record_studies(work, [n])[n]) for s in STUDIES),
    ]
    for name, job in groups:
        if not _wanted(name, only):
            continue
        try:
            save(name, job())
        except Exception as exc:  # recorded as missing; the others go on
            failed.append(name)
            print(f"FAILED {name}: {exc}", flush=True)
    print(f"{len(index)} cases in {out}; failed: {failed}")


def _load(directory: Path, name: str) -> dict[str, Any]:
    stem = name.replace("/", "__")
    with np.load(directory / "arrays" / f"{stem}.npz") as data:
        values: dict[str, Any] = {k: data[k] for k in data.files}
    values.update(json.loads((directory / "arrays" / f"{stem}.json").read_text()))
    return values


def compare(before: Path, after: Path, rtol: float) -> int:
    a_index = json.loads((before / "fingerprint.json").read_text())
    b_index = json.loads((after / "fingerprint.json").read_text())
    worst_all = 0.0
    bad = 0
    for name in sorted(set(a_index) | set(b_index)):
        if name not in a_index or name not in b_index:
            print(f"{name}: only in {'before' if name in a_index else 'after'}")
            bad += 1
            continue
        if a_index[name] == b_index[name]:
            print(f"{name}: identical ({len(a_index[name])} columns)")
            continue
        a, b = _load(before, name), _load(after, name)
        lines = []
        for key in sorted(set(a) | set(b)):
            if key not in a or key not in b:
                lines.append(f"  {key}: only in {'before' if key in a else 'after'}")
                bad += 1
                continue
            x, y = a[key], b[key]
            if isinstance(x, np.ndarray) and isinstance(y, np.ndarray):
                if x.shape != y.shape:
                    lines.append(f"  {key}: shape {x.shape} → {y.shape}")
                    bad += 1
                    continue
                same_nan = np.array_equal(np.isnan(x), np.isnan(y))
                finite = np.isfinite(x) & np.isfinite(y)
                diff = np.abs(x[finite] - y[finite])
                if same_nan and (not diff.size or diff.max() == 0.0):
                    continue
                scale = np.maximum(np.abs(x[finite]), np.abs(y[finite]))
                rel = float(np.max(diff / np.where(scale > 0, scale, 1.0))) if diff.size else math.inf
                worst_all = max(worst_all, rel if same_nan else math.inf)
                lines.append(
                    f"  {key}: max |Δ| {diff.max() if diff.size else math.nan:.3e}, max rel {rel:.3e}"
                    + ("" if same_nan else ", NaN pattern differs")
                )
                if rel > rtol or not same_nan:
                    bad += 1
            elif x != y:
                lines.append(f"  {key}: {str(x)[:80]!r} → {str(y)[:80]!r}")
                bad += 1
        print(f"{name}: differs" if lines else f"{name}: identical values")
        print("\n".join(lines))
    print(f"largest relative difference {worst_all:.3e}; {bad} difference(s) beyond rtol {rtol:g}")
    return 1 if bad else 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record")
    rec.add_argument("out", type=Path)
    rec.add_argument("--only", nargs="*", default=[])
    cmp_ = sub.add_parser("compare")
    cmp_.add_argument("before", type=Path)
    cmp_.add_argument("after", type=Path)
    cmp_.add_argument("--rtol", type=float, default=1e-12)
    args = parser.parse_args()
    if args.command == "record":
        record(args.out, args.only)
    else:
        raise SystemExit(compare(args.before, args.after, args.rtol))


if __name__ == "__main__":
    main()
