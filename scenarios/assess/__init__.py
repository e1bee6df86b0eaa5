"""Assessment of a run against performance standards: measures computed from a run's recorded columns."""
