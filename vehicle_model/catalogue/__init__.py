"""The vehicle presets: one combination a YAML file (vehicle_model.combination)."""
