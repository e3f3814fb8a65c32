"""colcon/ament_python package of the laser-corners ROS 2 node.

The node's code is :mod:`laser_corners.ros.ros2_node` of the laser-corners Python package
(install it into the Python that ROS 2 uses first: ``pip install -e <repo>``); this package
only adds the ROS 2 executable, the launch file and the ament index entry.
"""

from glob import glob

from setuptools import setup

PACKAGE = "laser_corners_ros"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=[],
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
    ],
    install_requires=["setuptools", "laser-corners"],
    zip_safe=True,
    maintainer="laser-corners developers",
    maintainer_email="laser-corners@example.org",
    description="ROS 2 node of laser-corners (corner-like keypoints in 2D laser scans)",
    license="BSD-3-Clause",
    entry_points={
        "console_scripts": [
            "laser_corners_node = laser_corners.ros.ros2_node:main",
        ],
    },
)
