"""laser-corners SLAM in place of slam_toolbox (docs/ros.md, "nav2").

ros2 launch laser_corners_ros slam.launch.py output:=/maps/today
"""

from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PARAMS = Path(__file__).resolve().parent.parent / "config" / "slam.yaml"


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription(
        [
            DeclareLaunchArgument("output", default_value="", description="the map folder"),
            DeclareLaunchArgument("scan", default_value="scan", description="LaserScan topic"),
            DeclareLaunchArgument("params", default_value=str(PARAMS)),
            DeclareLaunchArgument("use_sim_time", default_value="false"),
            Node(
                package="laser_corners_ros",
                executable="laser_corners_node",
                name="laser_corners",
                output="screen",
                remappings=[("scan", LaunchConfiguration("scan"))],
                parameters=[
                    LaunchConfiguration("params"),
                    {
                        "output": LaunchConfiguration("output"),
                        "use_sim_time": LaunchConfiguration("use_sim_time"),
                    },
                ],
            ),
        ]
    )
