"""Train a residual PPO policy on ``offtrack/TrailerSteering-v0`` and compare it with the designed and tuned PID.

The policy adds a correction (± ``--residual-deg``) to the path-following PID's virtual-axle steer; the PID
steers by the zero-slip estimate (``--feedback zero_slip``, blind to slip) or by VISO-OT (``viso_ot``, renders
the trailer camera: about ten times slower). Training roads are drawn at every reset from
:data:`TRAIN_ROADS` — ice to snow, adverse or inward camber, laden or unladen, either direction — where the
zero-slip kinematics are wrong and a learned correction can beat the PID. It is then evaluated, deterministic,
on held-out draws (seeds the training never used) against

* the **designed** PID (the same environment with a zero residual: exactly the controller of ``offtrack run``);
* the **tuned** PID: gains tuned with Optuna on ``offtrack/GainTuning-v0`` over the same ranges
  (:func:`scenarios.envs.tuning.tune_gains`), run with a zero residual.

Needs the ``rl`` extra (``pip install -e '.[rl]'``: stable-baselines3 and PyTorch). Example::

    .venv/bin/python benchmarks/train_ppo.py --steps 100000 --feedback zero_slip --held-out 6 --trials 12

prints the comparison as a Markdown table (``--json`` also writes every figure).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import scenarios.envs  # noqa: F401  (registers the environments)
from scenarios.extras import require

TRAIN_ROADS: dict[str, Any] = {
    "mu": (0.1, 0.3),
    "camber_percent": (0.0, 5.0),
    "camber_direction": ("outward", "inward"),
    "speed_kmh": (12.0, 18.0),
    "vehicle": ("lst", "lst-unladen"),
    "direction": ("left", "right"),
}
"""Training and held-out ranges: ice (μ 0.1) to snow (0.3), up to 5 % camber either way, 12–18 km/h."""

HELD_OUT_SEED = 1_000_000
"""Held-out draws use seeds from here on (training episodes are seeded from ``--seed``, far below)."""


def env_kwargs(feedback: str, residual_deg: float, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Arguments of the residual steering environment on the randomised roads."""
    kwargs: dict[str, Any] = {
        "action_mode": "residual",
        "feedback": feedback,
        "randomise": TRAIN_ROADS,
        "residual_scale_deg": residual_deg,
    }
    if overrides:
        kwargs["overrides"] = {"path.turns": 0.25, **overrides}
    return kwargs


def evaluate(
    make_env: Callable[[], gym.Env], policy: Callable[[np.ndarray], np.ndarray] | None, seeds: Sequence[int]
) -> list[dict[str, Any]]:
    """Episode summaries of ``policy`` (``None``: zero residual, the PID alone) on the draws of ``seeds``."""
    env = make_env()
    out = []
    for seed in seeds:
        obs, settings = env.reset(seed=int(seed))
        while True:
            action = np.zeros(1, dtype=np.float32) if policy is None else policy(obs)
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        out.append({**settings, **info["episode_summary"]})
    env.close()
    return out


def table(rows: Mapping[str, list[dict[str, Any]]]) -> str:
    """Mean figures per controller over the held-out draws, as a Markdown table."""
    lines = [
        "| controller | RMS e_tr after warm-up [mm] | max e_tr [mm] | saturated | return | failed |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, summaries in rows.items():
        rms = np.nanmean([s["rms_offtracking"] for s in summaries])
        peak = np.nanmean([s["max_offtracking"] for s in summaries])
        sat = np.mean([s["saturated_fraction"] for s in summaries])
        ret = np.mean([s["return"] for s in summaries])
        failed = sum(1 for s in summaries if s["termination_reason"])
        lines.append(
            f"| {name} | {1e3 * rms:.1f} | {1e3 * peak:.1f} | {sat:.1%} | {ret:.1f} | {failed}/{len(summaries)} |"
        )
    return "\n".join(lines)


def per_draw_table(rows: Mapping[str, list[dict[str, Any]]]) -> str:
    """RMS true off-tracking after warm-up [mm] per held-out draw and controller."""
    names = list(rows)
    first = rows[names[0]]
    lines = ["| draw | " + " | ".join(names) + " |", "|---|" + "---:|" * len(names)]
    for k, s in enumerate(first):
        road = (
            f"μ {s['mu']:.2f}, {s['camber_percent']:.1f} % {s['camber_direction']}, {s['speed_kmh']:.0f} km/h, "
            f"{s['vehicle']}, {s['direction']}"
        )
        cells = [f"{1e3 * rows[n][k]['rms_offtracking']:.1f}" for n in names]
        lines.append(f"| {road} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def train_and_compare(
    steps: int = 100_000,
    feedback: str = "zero_slip",
    held_out: int = 6,
    trials: int = 12,
    seed: int = 0,
    residual_deg: float = 3.0,
    overrides: Mapping[str, Any] | None = None,
    n_steps: int = 2048,
    log: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Train, tune and compare (module docstring); return the tables and every figure.

    Parameters
    ----------
    steps
        PPO training steps (control periods).
    feedback
        ``zero_slip`` or ``viso_ot``: what the PID (and the policy's observation) sees.
    held_out
        Held-out draws to compare on.
    trials
        Optuna trials for the tuned PID (0: no tuned PID).
    seed
        Seeds PPO, the training draws and the tuning.
    residual_deg
        Largest correction [°] of the virtual-axle steer.
    overrides
        Dotted configuration fields over the default scenario (e.g. a shorter path for a quick check).
    n_steps
        PPO rollout length per update.
    log
        Progress messages.
    """
    require("stable_baselines3", "rl", "training PPO")
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    from scenarios.envs.tuning import tune_gains

    torch.set_num_threads(1)
    kwargs = env_kwargs(feedback, residual_deg, overrides)
    t0 = time.perf_counter()
    venv = VecNormalize(
        make_vec_env("offtrack/TrailerSteering-v0", n_envs=1, seed=seed, env_kwargs=kwargs),
        norm_obs=True,
        norm_reward=True,
        clip_obs=10.0,
        gamma=0.99,
    )
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=n_steps,
        batch_size=min(256, n_steps),
        n_epochs=10,
        learning_rate=3e-4,
        gamma=0.99,
        gae_lambda=0.95,
        clip_range=0.2,
        policy_kwargs={"log_std_init": -1.5, "net_arch": [64, 64]},
        seed=seed,
        verbose=0,
    )
    model.learn(total_timesteps=steps)
    train_s = time.perf_counter() - t0
    log(f"PPO: {steps} steps in {train_s:.0f} s")
    venv.training = False

    def policy(obs: np.ndarray) -> np.ndarray:
        action, _ = model.predict(venv.normalize_obs(obs[None, :]), deterministic=True)
        return np.asarray(action, dtype=np.float32).reshape(1)

    seeds = [HELD_OUT_SEED + k for k in range(held_out)]
    rows: dict[str, list[dict[str, Any]]] = {}
    rows["designed PID"] = evaluate(lambda: gym.make("offtrack/TrailerSteering-v0", **kwargs), None, seeds)
    tuned: dict[str, float] | None = None
    if trials > 0:
        t1 = time.perf_counter()
        tuning_kwargs = {"feedback": feedback}
        if overrides:
            tuning_kwargs["overrides"] = kwargs["overrides"]
        result = tune_gains(
            n_trials=trials, train_draws=2, seed=seed, randomise=TRAIN_ROADS, held_out={}, env_kwargs=tuning_kwargs
        )
        tuned = {"kp": result.tuned[0].kp, "ki": result.tuned[0].ki, "kd": result.tuned[0].kd}
        log(f"Optuna: {trials} trials in {time.perf_counter() - t1:.0f} s → {tuned}")
        gains = {f"controller.{k}": v for k, v in tuned.items()}
        tuned_kwargs = {**kwargs, "overrides": {**kwargs.get("overrides", {"path.turns": 0.25}), **gains}}
        rows["Optuna-tuned PID"] = evaluate(
            lambda: gym.make("offtrack/TrailerSteering-v0", **tuned_kwargs), None, seeds
        )
    rows["designed PID + PPO residual"] = evaluate(
        lambda: gym.make("offtrack/TrailerSteering-v0", **kwargs), policy, seeds
    )
    venv.close()
    return {
        "steps": steps,
        "feedback": feedback,
        "train_s": train_s,
        "tuned_gains": tuned,
        "table": table(rows),
        "per_draw": per_draw_table(rows),
        "held_out": rows,
    }


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Command line (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000, help="PPO training steps")
    parser.add_argument("--feedback", choices=("zero_slip", "viso_ot"), default="zero_slip")
    parser.add_argument("--held-out", type=int, default=6, help="held-out draws to compare on")
    parser.add_argument("--trials", type=int, default=12, help="Optuna trials for the tuned PID (0: none)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--residual-deg", type=float, default=3.0, help="largest correction [deg]")
    parser.add_argument("--n-steps", type=int, default=2048, help="PPO rollout length per update")
    parser.add_argument("--short", action="store_true", help="a tenth of the roundabout (quick check)")
    parser.add_argument("--json", type=Path, help="write every figure here")
    args = parser.parse_args(argv)
    overrides = {"path.turns": 0.1, "path.entry_length": 10.0, "path.exit_length": 5.0} if args.short else None
    out = train_and_compare(
        args.steps, args.feedback, args.held_out, args.trials, args.seed, args.residual_deg, overrides, args.n_steps
    )
    print(out["table"])
    print()
    print(out["per_draw"])
    if args.json is not None:
        args.json.write_text(json.dumps(out, indent=2, default=float))
    return out


if __name__ == "__main__":
    main()
