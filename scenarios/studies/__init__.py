"""Many runs: case specs and their records, the sweep runner and its executors, the studies, feedback comparison.

Nothing is imported here: a spawned sweep worker imports :mod:`scenarios.studies.workers` on the standard
library alone, before its thread limits are set.
"""
