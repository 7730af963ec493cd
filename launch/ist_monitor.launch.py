"""Starts ist_monitor as a ROS 2 node.

    ros2 launch ist_monitor ist_monitor.launch.py params_file:=/path/to/cell.yaml \
        namespace:=cell1 use_sim_time:=true log_level:=info

Arguments: `params_file` (default: the package's config/ur5e.yaml), `namespace` (default: none),
`use_sim_time` (default: false; the clock is /clock's), `log_level` (default: info). Remap the
inputs and outputs with `remappings=` in your own launch file, e.g.
`('/camera/depth/points', '/realsense/depth/points')`.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description():
    share = get_package_share_directory("ist_monitor")
    return LaunchDescription([
        DeclareLaunchArgument("params_file",
                              default_value=os.path.join(share, "config", "ur5e.yaml"),
                              description="the node's parameters file"),
        DeclareLaunchArgument("namespace", default_value="",
                              description="the node's namespace"),
        DeclareLaunchArgument("use_sim_time", default_value="false",
                              description="take the clock from /clock"),
        DeclareLaunchArgument("log_level", default_value="info",
                              description="debug, info, warn or error"),
        Node(
            package="ist_monitor",
            executable="ist_monitor",
            name="ist_monitor",
            namespace=LaunchConfiguration("namespace"),
            parameters=[
                LaunchConfiguration("params_file"),
                {"use_sim_time": ParameterValue(LaunchConfiguration("use_sim_time"),
                                                value_type=bool)},
            ],
            ros_arguments=["--log-level", LaunchConfiguration("log_level")],
            output="screen",
        ),
    ])
