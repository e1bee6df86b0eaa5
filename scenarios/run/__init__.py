"""One run of a scenario: driving the co-simulation to its end, the run directory's files, metrics and plots."""
