import sys, time, numpy as np, pandas as pd
from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from vehicle_model.simulator import Simulator
from scenarios.studies.optimal_problem import solve_optimal_steer
run = sys.argv[1]; overrides = eval(sys.argv[2])
cfg = load_scenario(sys.argv[3], overrides)
setup = build_scenario(cfg)
sim = Simulator(setup.params, setup.surface, model=setup.model)
d = pd.read_parquet(f"{run}/timeseries.parquet")
cols = {c: d[c].to_numpy() for c in d.columns}
lim = cfg.controller.path_following(cfg.rates.control_hz)
t0 = time.time()
sol = solve_optimal_steer(setup.params, cols, sim, lim, max_iter=int(sys.argv[4]) if len(sys.argv) > 4 else 300)
print("status", sol.status, "cost", sol.cost, "time", time.time() - t0)
e = sol.offtracking; print("opt rms %.4f max %.4f" % (np.sqrt(np.mean(e**2)), np.abs(e).max()))
print("max steer deg", np.degrees(np.abs(sol.steer).max()), "max rate deg/s", np.degrees(np.abs(np.diff(sol.steer, axis=0)).max() / 0.2))
tr = np.interp(sol.times, d.time, d.offtracking_truth.fillna(0)); print("pid rms at nodes %.4f max %.4f" % (np.sqrt(np.mean(tr**2)), np.abs(tr).max()))
