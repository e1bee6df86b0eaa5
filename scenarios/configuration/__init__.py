"""The scenario configuration, one job a module; :mod:`scenarios.config` gathers them as the one way in.

* :mod:`~scenarios.configuration.errors` — :class:`ConfigError` and the "did you mean" of its messages;
* :mod:`~scenarios.configuration.road_sections` — the road's sections (path, friction patches, surface, camber,
  speed);
* :mod:`~scenarios.configuration.sections` — the vehicle's sections (rates, signals, estimators, fusion,
  controller), with ``controller.mpc`` in :mod:`~scenarios.configuration.mpc_section` and the terrain in
  :mod:`~scenarios.configuration.terrain_section`;
* :mod:`~scenarios.configuration.vehicle_field` — the ``vehicle`` field: a preset, a combination file or inline;
* :mod:`~scenarios.configuration.scenario_config` — :class:`ScenarioConfig`, the complete scenario;
* :mod:`~scenarios.configuration.field_errors` — a validation error as one line per bad field;
* :mod:`~scenarios.configuration.loading` — the catalogue, YAML files, dotted overrides and validation.
"""
