"""Recorded stereo sequences and what comes with them: KITTI folders, video pairs, ROS bags, poses, signals, metrics.

Every reader gives a :class:`~sensor.recordings.sequence.StereoRecording`: the frames' slots (number, time, and why
a frame's images are missing) known before any image is decoded, then the pairs in order. The checks a reader makes
before any work raise :class:`~vehicle_model.errors.InputError` with one line naming the file or field.
"""
