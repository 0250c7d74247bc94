# SPDX-License-Identifier: Apache-2.0
"""Start the skynav node graph on a full ROS 2 install.

    ros2 launch skynav_bringup skynav.launch.py [params_file:=/path/to/params.yaml]

Starts every installed skynav node that has a `ros2 run` executable, the same
set `skynav launch` starts where the ROS 2 launch tools are missing.
"""

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from skynav_core.nodes import installed_nodes


def generate_launch_description():
    default_params = Path(get_package_share_directory('skynav_bringup')) / 'config' / 'skynav.yaml'
    params_file = LaunchConfiguration('params_file')
    nodes = [
        Node(
            package=spec.package,
            executable=spec.executable,
            name=spec.name,
            parameters=[params_file],
            output='screen',
        )
        for spec in installed_nodes()
        if spec.executable is not None
    ]
    return LaunchDescription([DeclareLaunchArgument('params_file', default_value=str(default_params))] + nodes)
