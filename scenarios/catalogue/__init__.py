"""The catalogue of scenarios, one YAML file each (``offtrack list``), read by :mod:`scenarios.config`."""
