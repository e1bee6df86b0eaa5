"""Rendered data for other tools: KITTI-odometry-style datasets and stereo videos."""
