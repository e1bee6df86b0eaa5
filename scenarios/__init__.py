"""Scenarios: everything that composes the model, the controllers and the sensor into runs, one room per job.

Rooms, lowest first (a room imports only the rooms above it in this list; ``tests/test_architecture.py``):

* :mod:`scenarios.config` — the validated configuration schema, catalogue loading, dotted overrides;
* ``scenarios/catalogue/`` — the scenario YAML files;
* :mod:`scenarios.setup` — configuration → the parts of a run (reference path, surface, vehicle model,
  driver feed-forward, trailer controller) and the registry that shares built models;
* :mod:`scenarios.camera` — the stereo rig and the world of a scenario, and the camera pipeline (render →
  visual odometry → VISO-OT) that the loop runs;
* :mod:`scenarios.run` — one run: the co-simulation loop, the run directory (time series, metrics, plots);
* :mod:`scenarios.export` — rendered data for other tools: KITTI-style datasets, stereo videos;
* :mod:`scenarios.studies` — many runs: case specs and records, the sweep runner and its executors, the
  studies and their figures, feedback comparison;
* :mod:`scenarios.envs` — the Gymnasium environments and gain tuning;
* :mod:`scenarios.bench` — the benchmarks of ``offtrack bench``;
* :mod:`scenarios.cli` — the ``offtrack`` command line.
"""
