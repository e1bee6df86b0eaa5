"""Controllers and the model-based estimate: the driver, the speed controller, Cheng's zero-slip estimator,
the path-following trailer steering and its gain design.

Imports only :mod:`vehicle_model` (docs/design.md §2).
"""
