"""The tractor–semi-trailer: parameters, combination files and presets, tyres, surfaces, the casadi model,
simulation, geometry, off-tracking.

Imports none of the project's other packages (docs/design.md §2).
"""
