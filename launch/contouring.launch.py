"""Launch the contouring graph of one experiment file: the same nodes, namespaces and parameters as
`contouring-ros run` (both come from contouring_ros.wire.graph.node_specs, which reads the node catalogue,
contouring_ros/wire/catalogue.py).

    ros2 launch contouring_ros contouring.launch.py experiment:=/path/to/experiment.yaml [bag:=run.mcap] [namespace:=m1]

`experiment` is a path, or the name of a scenario installed with the package (share/contouring_ros/config).
`namespace` puts every node and topic under it (/m1/x/plant publishes /m1/x/state); the nodes then read a
copy of the experiment file whose node sections carry the namespace (written to a temporary folder).
The launch file does not give the run its own ROS domain the way the runner does: set ROS_DOMAIN_ID,
FASTRTPS_DEFAULT_PROFILES_FILE (the package's loopback-only profile) and ROS_AUTOMATIC_DISCOVERY_RANGE
as the README's ROS recipe shows, yourself.
"""
import tempfile
from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def graph_nodes(context):
    """The graph's Node actions for the experiment named by the launch arguments."""
    from contouring_ros.api import load_experiment
    from contouring_ros.wire.graph import node_specs, normalize_namespace
    from contouring_ros.run.runner import default_bag_path, shared_overrides, write_parameter_file
    experiment = load_experiment(LaunchConfiguration("experiment").perform(context))
    path = Path(experiment.path).resolve()
    bag = LaunchConfiguration("bag").perform(context) or str(default_bag_path(experiment))
    namespace = normalize_namespace(LaunchConfiguration("namespace").perform(context))
    parameter_file = path if namespace == "/" else \
        write_parameter_file(path, namespace, tempfile.mkdtemp(prefix="contouring_ros_"))
    return [Node(package="contouring_ros", executable=spec.executable, name=spec.name, namespace=spec.namespace,
                 parameters=[str(parameter_file), dict(spec.overrides)], output="screen")
            for spec in node_specs(experiment.axes, shared_overrides(experiment), bag, str(path), namespace)]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument("experiment", description="experiment YAML: a path or an installed scenario name"),
        DeclareLaunchArgument("bag", default_value="", description="bag to write (default bags/<name>_<time>.mcap)"),
        DeclareLaunchArgument("namespace", default_value="/", description="every node and topic under it (e.g. m1)"),
        OpaqueFunction(function=graph_nodes),
    ])
