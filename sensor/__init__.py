"""What the trailer senses: on-board signals, the procedural world, the stereo rig and its renderer, visual
odometry (:mod:`sensor.vo`) and VISO-OT.

Imports only :mod:`vehicle_model` (docs/design.md §2).
"""
