# SPDX-License-Identifier: Apache-2.0
"""Start the skynav node graph on a full ROS 2 install (docs/install.md, "The colcon way").

    ros2 launch skynav_bringup skynav.launch.py [namespace:=robot1] [map:=/path/route.db]
        [params_file:=/path/params.yaml] [use_sim_time:=true] [camera:=colour]

Starts every installed skynav node that has an executable, the graph `skynav launch` starts where the ROS 2
launch tools are missing, each node from the shipped parameter file with `params_file` over it. What each node
gets from these arguments is skynav_bringup.ros_launch's (tested without the launch tools); this file only
declares the arguments and hands each node to launch_ros.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from skynav_bringup.ros_launch import CAMERA_CHOICES, SIM_TIME_CHOICES, graph_launch


def generate_launch_description():
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                'namespace',
                default_value='',
                description='put every node, topic, service and action of the graph under /NAMESPACE, its '
                '/clock and /tf_static too (e.g. robot1); empty: none',
            ),
            DeclareLaunchArgument(
                'map',
                default_value='',
                description='SQLite map file (skynav map build, skynav teach) for the nodes that take a map; '
                'empty: none',
            ),
            DeclareLaunchArgument(
                'params_file',
                default_value='',
                description='ROS 2 parameter file over the shipped defaults (config/skynav.yaml); empty: none',
            ),
            DeclareLaunchArgument(
                'use_sim_time',
                default_value='',
                choices=list(SIM_TIME_CHOICES),
                description='every node on /clock (true) or the system clock (false); empty: as the '
                'parameter files say',
            ),
            DeclareLaunchArgument(
                'camera',
                default_value='',
                choices=list(CAMERA_CHOICES),
                description='the camera source of the nodes that read camera frames (auto: the first that '
                'delivers); empty: as the parameter files say (auto as shipped)',
            ),
            OpaqueFunction(function=start_nodes),
        ]
    )


def start_nodes(context):
    """Return a launch_ros Node for every node of the graph, with the arguments' values known."""
    nodes = graph_launch(
        namespace=LaunchConfiguration('namespace').perform(context),
        map_path=LaunchConfiguration('map').perform(context),
        params_file=LaunchConfiguration('params_file').perform(context),
        use_sim_time=LaunchConfiguration('use_sim_time').perform(context),
        camera=LaunchConfiguration('camera').perform(context),
    )
    return [
        Node(
            executable=str(node.executable),
            name=node.name,
            namespace=node.namespace or None,
            parameters=node.parameters,
            remappings=node.remappings,
            output='screen',
        )
        for node in nodes
    ]
