"""The optimal reference's NLP: CPU time of its mapped formulation against the same NLP expanded as a whole.

One case (the 50 m roundabout at 15 km/h, dry, LST, truth-fed, ``duration_s`` of driving): the PID run once, then
:func:`scenarios.studies.optimal_problem.solve_optimal_steer` over it twice, ``expand=False`` (the shooting interval
one SX function mapped over the nodes) and ``expand=True`` (the whole NLP one SX graph), each timed in this
process's CPU time (build, derivatives and both Ipopt solves): ``offtrack bench optimal [--duration 8] [--json]``
(or ``python -m scenarios.bench.optimal``), one JSON object.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

from ..config import load_scenario
from ..studies.optimal_problem import solve_optimal_steer
from ..studies.optimal_reference import pid_run


def bench_optimal(duration_s: float = 8.0) -> dict[str, Any]:
    """CPU seconds of the mapped and the expanded formulation on one case, their ratio and both solutions' costs.

    Parameters
    ----------
    duration_s
        Simulated seconds of the roundabout (its entry 1 m long); the kingpin must drive the follow-point offset.
    """
    overrides = {"vehicle": "lst", "feedback": "truth", "path.entry_length": 1.0, "duration_s": duration_s}
    config = load_scenario("roundabout-3", overrides)
    with tempfile.TemporaryDirectory() as tmp:
        pid = pid_run(config, Path(tmp))
    result: dict[str, Any] = {"case": {"scenario": "roundabout-3", **overrides}}
    for name, expand in (("mapped", False), ("expanded", True)):
        start = time.process_time()
        solution = solve_optimal_steer(pid.params, pid.recorded, pid.simulator, pid.limits, expand=expand)
        result[name] = {"cpu_s": time.process_time() - start, "status": solution.status, "cost_m2": solution.cost}
    result["expanded_over_mapped_cpu"] = result["expanded"]["cpu_s"] / result["mapped"]["cpu_s"]
    return result


def main() -> None:
    """Print :func:`bench_optimal`'s JSON object."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=8.0, help="simulated seconds of the roundabout")
    print(json.dumps(bench_optimal(parser.parse_args().duration), indent=1))


if __name__ == "__main__":
    main()
