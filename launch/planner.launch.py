"""Start planner_node with the default parameters (config/planner.yaml).

    ros2 launch rearrangement_planner planner.launch.py
    ros2 launch rearrangement_planner planner.launch.py controller:=arm_controller

The trajectory command topic `joint_trajectory` is remapped to the joint trajectory
controller's (`/<controller>/joint_trajectory`). Requires a full ROS 2 install (launch_ros).
"""

# ruff: noqa: I001  (ruff takes `launch` for this repo's launch/ folder and splits the block)
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    params = os.path.join(get_package_share_directory("rearrangement_planner"),
                          "config", "planner.yaml")
    controller = LaunchConfiguration("controller")
    return LaunchDescription([
        DeclareLaunchArgument("controller", default_value="joint_trajectory_controller",
                              description="joint trajectory controller receiving the plans"),
        Node(
            package="rearrangement_planner",
            executable="planner_node",
            name="rearrangement_planner",
            output="screen",
            parameters=[params],
            remappings=[("joint_trajectory", ["/", controller, "/joint_trajectory"])],
        ),
    ])
