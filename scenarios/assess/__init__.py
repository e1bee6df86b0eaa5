"""Assessment of a run against performance standards (docs/pbs.md, docs/pbs_high_speed.md): measures computed from
a run's recorded columns."""
