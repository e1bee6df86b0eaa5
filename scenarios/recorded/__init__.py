"""Real cameras in: calibration from photos, recorded stereo sequences turned into run directories, VO evaluation."""
