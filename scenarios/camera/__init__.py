"""The trailer's stereo camera in a scenario: the rig and the world from the configuration, and the camera pipeline."""
