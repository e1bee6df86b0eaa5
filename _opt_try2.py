import sys, time, numpy as np, pandas as pd
import scenarios.studies.optimal_problem as op
from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from vehicle_model.simulator import Simulator
cfg = load_scenario("roundabout-3", {"vehicle": "lst", "feedback": "truth", "path.entry_length": 1, "duration_s": 8})
setup = build_scenario(cfg)
sim = Simulator(setup.params, setup.surface, model=setup.model)
d = pd.read_parquet("/tmp/h45c/opt_tiny/pid/timeseries.parquet")
cols = {c: d[c].to_numpy() for c in d.columns}
lim = cfg.controller.path_following(cfg.rates.control_hz)
orig = op.ca.Opti.solver
mode = sys.argv[1]
def solver(self, name, opts, iopts):
    if mode == "expand": opts = {**opts, "expand": True}
    if mode == "lbfgs": iopts = {**iopts, "hessian_approximation": "limited-memory"}
    return orig(self, name, opts, iopts)
op.ca.Opti.solver = solver
t0 = time.time()
s = op.solve_optimal_steer(setup.params, cols, sim, lim, relinearisations=1)
print(mode, s.status, s.cost, "%.1f s" % (time.time() - t0))
