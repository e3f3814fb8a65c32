"""ROS nodes of laser-corners (see ``docs/ros.md``).

* :mod:`laser_corners.ros.convert`, :mod:`laser_corners.ros.node_core`: ROS-free message
  conversion, parameter validation and per-scan work, shared by both nodes.
* :mod:`laser_corners.ros.ros1_node`: the rospy node (``laser-corners ros1``).
* :mod:`laser_corners.ros.ros2_node`: the rclpy node (``laser-corners ros2``; rclpy from the
  ``ros2`` extra, or a ROS 2 install with the colcon package in ``ros2/``).

Importing this package imports no ROS module.
"""
