"""The ROS 1 bag fast path: what rosbags' ROS 1 reader and writer get from this package.

- :mod:`~laser_corners.io.ros1.decode`: ``LaserScan``, ``Odometry`` and ``TFMessage`` bytes
  decoded with ``struct``/numpy;
- :mod:`~laser_corners.io.ros1.index`, :mod:`~laser_corners.io.ros1.lean` and
  :mod:`~laser_corners.io.ros1.runs`: the lean path (the message index read with numpy, whole
  chunk runs located and decoded in blocks);
- :mod:`~laser_corners.io.ros1.chunks`: reading a bag from its chunk records when rosbags
  cannot parse its index;
- :mod:`~laser_corners.io.ros1.legacy`: message type names of pre-Electric bags;
- :mod:`~laser_corners.io.ros1.writer`: rosbags' writer with rosbag's bag header layout.

Nothing is imported here; the readers and writers of :mod:`laser_corners.io` import the
modules they use.
"""
