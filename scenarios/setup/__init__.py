"""From a scenario's configuration to the parts of a run: reference path, surface, vehicle and model, controllers."""
