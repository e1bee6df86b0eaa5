"""Tune the trailer path-following PID gains with Optuna through ``offtrack/GainTuning-v0``.

Trains on randomised wet-to-dry roads with up to 3 % camber (laden and unladen, 12–18 km/h, both turn
directions), then compares the tuned gains with the designed defaults on held-out conditions and prints the
before/after table. The default budget (30 trials × 3 draws, about 100 scenario runs) takes about a minute.

    python benchmarks/tune_gains.py [--trials 30] [--draws 3] [--seed 0] [--feedback truth] [--json]

Needs ``optuna`` (``pip install 'offtrack[tune]'``).
"""

from __future__ import annotations

import argparse
import json
import sys

from scenarios.envs.tuning import tune_gains


def main(argv: list[str] | None = None) -> int:
    """Run the tuning example; print the table (or one JSON object with ``--json``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=30, help="Optuna trials (default 30)")
    parser.add_argument("--draws", type=int, default=3, help="training domain draws per trial (default 3)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the draws and of the sampler")
    parser.add_argument("--feedback", default="truth", choices=["truth", "zero_slip", "viso_ot"])
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)

    def progress(done: int, total: int, best: float) -> None:
        if not args.json:
            print(f"\rtrial {done}/{total}: best training cost {best:.5f}", end="", file=sys.stderr, flush=True)

    result = tune_gains(
        n_trials=args.trials,
        train_draws=args.draws,
        seed=args.seed,
        env_kwargs={"feedback": args.feedback},
        progress=progress,
    )
    if args.json:
        print(json.dumps({"benchmark": "tune_gains", **result.to_dict()}))
        return 0
    print(file=sys.stderr)
    print(result.table())  # ends with the held-out verdicts and the advice
    print(f"{result.trials} trials, {result.evaluations} scenario runs, {result.wall_s:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
