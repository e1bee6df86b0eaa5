"""One run of a scenario: the co-simulation loop, the run directory's files, metrics and plots."""
