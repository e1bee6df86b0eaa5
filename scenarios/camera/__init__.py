"""The trailer's stereo camera in a scenario: the configuration mapped to :mod:`sensor`'s camera (``build``), the
render workers (``workers``) and the frames scheduled with the camera latency (``delivery``). A camera that cannot
work is refused when its configuration is validated (:mod:`scenarios.camera_checks`)."""
