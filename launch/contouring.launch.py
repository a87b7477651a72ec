"""Launch the contouring graph of one experiment file: the same nodes, namespaces and parameters as
`contouring-ros run` (both come from contouring_ros.graph.node_specs).

    ros2 launch contouring_ros contouring.launch.py experiment:=/path/to/experiment.yaml [bag:=run.mcap]

`experiment` is a path, or the name of a scenario installed with the package (share/contouring_ros/config).
The launch file does not give the run its own ROS domain the way the runner does: set ROS_DOMAIN_ID,
FASTRTPS_DEFAULT_PROFILES_FILE (the package's loopback-only profile) and ROS_AUTOMATIC_DISCOVERY_RANGE
as the README's ROS recipe shows, yourself.
"""
from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def graph_nodes(context):
    """The graph's Node actions for the experiment named by the launch arguments."""
    from contouring_ros.api import load_experiment
    from contouring_ros.graph import node_specs
    from contouring_ros.runner import default_bag_path, shared_overrides
    experiment = load_experiment(LaunchConfiguration("experiment").perform(context))
    path = str(Path(experiment.path).resolve())
    bag = LaunchConfiguration("bag").perform(context) or str(default_bag_path(experiment))
    return [Node(package="contouring_ros", executable=spec.executable, name=spec.name, namespace=spec.namespace,
                 parameters=[path, dict(spec.overrides)], output="screen")
            for spec in node_specs(experiment.axes, shared_overrides(experiment), bag, path)]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument("experiment", description="experiment YAML: a path or an installed scenario name"),
        DeclareLaunchArgument("bag", default_value="", description="bag to write (default bags/<name>_<time>.mcap)"),
        OpaqueFunction(function=graph_nodes),
    ])
