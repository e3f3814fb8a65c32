"""Launch the laser-corners ROS 2 node.

ros2 launch laser_corners_ros laser_corners.launch.py scan:=/scan
ros2 launch laser_corners_ros laser_corners.launch.py scan:=/scan use_sim_time:=true
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    scan = LaunchConfiguration("scan")
    preset = LaunchConfiguration("preset")
    use_sim_time = LaunchConfiguration("use_sim_time")
    return LaunchDescription(
        [
            DeclareLaunchArgument("scan", default_value="scan", description="LaserScan topic"),
            DeclareLaunchArgument("preset", default_value="paper", description="preset name"),
            DeclareLaunchArgument("use_sim_time", default_value="false"),
            Node(
                package="laser_corners_ros",
                executable="laser_corners_node",
                name="laser_corners",
                output="screen",
                remappings=[("scan", scan)],
                parameters=[{"preset": preset, "use_sim_time": use_sim_time}],
            ),
        ]
    )
