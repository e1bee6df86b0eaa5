"""Scenarios: everything that composes the model, the controllers and the sensor into runs, one room per job.

Rooms, lowest first (a room imports only the rooms above it in this list; ``tests/test_architecture.py``):

* :mod:`scenarios.configuration` — the validated configuration schema, catalogue loading, dotted overrides,
  gathered by :mod:`scenarios.config`;
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
* :mod:`scenarios.commands` — the ``offtrack`` commands by room, and the options they share;
* :mod:`scenarios.cli` — the ``offtrack`` command line: the app, its command table and ``main``.

One thing happens on import, before numpy loads: its BLAS is held to one thread (``OPENBLAS_NUM_THREADS``,
``MKL_NUM_THREADS``; :data:`BLAS_THREADS`), unless the environment already says otherwise. A threaded BLAS splits
the sums of a large product or solve between its threads, so their last bits depend on how many there are, and a
closed loop grows a last-bit difference into a different run (benchmarks/README.md, "One BLAS thread", has a
field-conditions figure-of-eight run both ways). With one thread a run gives the same numbers on any machine, as
the studies' workers (:data:`scenarios.studies.workers.THREAD_LIMITS`) do; the model
and the odometry are compiled code that does not use BLAS, and a second BLAS thread only competes with the render
worker for the cores (benchmarks/README.md, "One BLAS thread").
"""

import os

BLAS_THREADS = {"OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
"""The BLAS thread settings applied on import where the environment has none."""

for _name, _value in BLAS_THREADS.items():
    os.environ.setdefault(_name, _value)
