"""Data for other tools: KITTI-odometry-style datasets, stereo videos, animations, a run's time series (CSV, .mat)."""
