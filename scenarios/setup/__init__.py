"""From a scenario's configuration to the parts of a run: reference path, surface, vehicle and model, the driver's
feed-forward, the initial state; and the process's cache of built scenarios and models."""
