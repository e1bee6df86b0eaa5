"""Write the tractor–semi-trailer model's reference: ẋ, the hitch force and a short open-loop run per preset.

Run from the repository root (``.venv/bin/python tests/data/two_unit_model/make_reference.py``) on the model the
reference is meant to pin; ``tests/test_chain_dynamics.py`` checks the model against the file. README.md beside
this script says which model wrote it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vehicle_model.dynamics import VehicleModel
from vehicle_model.presets import VEHICLE_PRESETS

HERE = Path(__file__).resolve().parent
SAMPLES = 40
RUN_S, DT, SUBSTEPS = 6.0, 0.02, 4


def sample_points(model: VehicleModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """States and inputs spread over the model's working range (speeds 1–25 m/s, articulation ±60°, ...)."""
    lay = model.layout
    n_axles, n_steer = len(lay.axles), len(lay.steerable_axles)
    x = np.zeros((SAMPLES, lay.n_states))
    x[:, 0:2] = rng.uniform(-50, 50, (SAMPLES, 2))
    x[:, 2] = rng.uniform(-np.pi, np.pi, SAMPLES)
    x[:, 3] = rng.uniform(1.0, 25.0, SAMPLES)
    x[:, 4] = rng.uniform(-1.0, 1.0, SAMPLES)
    x[:, 5] = rng.uniform(-0.5, 0.5, SAMPLES)
    x[:, 6] = rng.uniform(-1.0, 1.0, SAMPLES)
    x[:, 7] = rng.uniform(-0.5, 0.5, SAMPLES)
    x[:, 8:] = rng.uniform(-0.15, 0.15, (SAMPLES, n_axles))
    u = np.zeros((SAMPLES, lay.n_inputs))
    u[:, :n_steer] = rng.uniform(-0.4, 0.4, (SAMPLES, n_steer))
    u[:, n_steer] = rng.uniform(-2e4, 2e4, SAMPLES)
    u[:, n_steer + 1 : n_steer + 1 + n_axles] = rng.uniform(0.1, 1.0, (SAMPLES, n_axles))
    u[:, n_steer + 1 + n_axles :] = rng.uniform(-0.05, 0.05, (SAMPLES, 4))
    return x, u


def open_loop_run(model: VehicleModel) -> np.ndarray:
    """States every ``DT`` (the file keeps every fifth) of a 10 m/s run: a steer ramp to 0.2 rad over 2 s, held
    (steerable trailer axles to −0.05 rad)."""
    lay = model.layout
    n_axles, n_steer = len(lay.axles), len(lay.steerable_axles)
    advance = model.integrator(SUBSTEPS)
    x = np.zeros(lay.n_states)
    x[3] = 10.0
    rows = [x.copy()]
    for k in range(round(RUN_S / DT)):
        t = k * DT
        u = np.zeros(lay.n_inputs)
        u[0] = 0.2 * min(t / 2.0, 1.0)
        u[1:n_steer] = -0.05 * min(t / 2.0, 1.0)
        u[n_steer] = 3000.0
        u[n_steer + 1 : n_steer + 1 + n_axles] = 0.8
        x = np.asarray(advance(x, u, DT / SUBSTEPS)[0]).ravel()
        rows.append(x.copy())
    return np.array(rows)


def main() -> None:
    arrays: dict[str, np.ndarray] = {}
    for name, make in VEHICLE_PRESETS.items():
        model = VehicleModel(make(), compile=False)
        rng = np.random.default_rng(20261203)
        x, u = sample_points(model, rng)
        arrays[f"{name}/x"], arrays[f"{name}/u"] = x, u
        arrays[f"{name}/xdot"] = np.array([np.asarray(model.rhs(a, b)).ravel() for a, b in zip(x, u, strict=True)])
        hitch = model.output_names.index("hitch_force")
        arrays[f"{name}/hitch_force"] = np.array(
            [np.asarray(model.outputs(a, b)[hitch]).ravel() for a, b in zip(x, u, strict=True)]
        )
        arrays[f"{name}/run"] = open_loop_run(model)[::5]  # every 0.1 s
    np.savez_compressed(HERE / "reference.npz", **arrays)


if __name__ == "__main__":
    main()
