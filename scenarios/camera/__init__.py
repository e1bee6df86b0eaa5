"""The trailer's stereo camera in a scenario: the configuration mapped to :mod:`sensor`'s camera (``build``),
infeasible cameras refused up front (``feasibility``), the render workers (``workers``) and the frames scheduled
with the camera latency (``delivery``)."""
