"""What the trailer senses: on-board signals, the procedural world, the stereo rig and its renderer, the stereo
camera (:mod:`sensor.stereo_camera`: render, field optics, development), visual odometry (:mod:`sensor.vo`) and
VISO-OT per frame (:mod:`sensor.frame_odometry`).

Imports only :mod:`vehicle_model` (docs/design.md §2).
"""
