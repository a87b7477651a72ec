"""launch/contouring.launch.py starts the graph the runner starts.

ROS 2 launch is not on PyPI, so the test stands in for it: minimal `launch` and `launch_ros` modules that
record what the launch file asks for (its arguments, its OpaqueFunction, each Node's package, executable,
name, namespace and parameters). The launch file is then evaluated as `ros2 launch` would, and its nodes are
compared with the runner's commands for the same experiment: same nodes, namespaces, parameter file and
overrides."""
import importlib.util
import sys
import types
from pathlib import Path

import pytest
import yaml

from contouring_ros.config import load_experiment
from contouring_ros.run.runner import graph_commands, write_parameter_file
from conftest import CONFIG, DEFAULT, ROOT


class _Recorded:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class _LaunchConfiguration:
    def __init__(self, name):
        self.name = name

    def perform(self, context):
        return context[self.name]


@pytest.fixture
def launch_file(monkeypatch):
    launch = types.ModuleType("launch")
    launch.LaunchDescription = lambda entities: list(entities)
    actions = types.ModuleType("launch.actions")
    actions.DeclareLaunchArgument = type("DeclareLaunchArgument", (_Recorded,), {})
    actions.OpaqueFunction = type("OpaqueFunction", (_Recorded,), {})
    substitutions = types.ModuleType("launch.substitutions")
    substitutions.LaunchConfiguration = _LaunchConfiguration
    launch_ros = types.ModuleType("launch_ros")
    ros_actions = types.ModuleType("launch_ros.actions")
    ros_actions.Node = type("Node", (_Recorded,), {})
    for name, module in {"launch": launch, "launch.actions": actions, "launch.substitutions": substitutions,
                         "launch_ros": launch_ros, "launch_ros.actions": ros_actions}.items():
        monkeypatch.setitem(sys.modules, name, module)
    spec = importlib.util.spec_from_file_location("contouring_launch", ROOT / "launch" / "contouring.launch.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _launched(module, experiment: str, bag: str, namespace: str = "/") -> dict:
    entities = module.generate_launch_description()
    arguments = {e.args[0] for e in entities if type(e).__name__ == "DeclareLaunchArgument"}
    assert arguments == {"experiment", "bag", "namespace"}
    opaque = next(e for e in entities if type(e).__name__ == "OpaqueFunction")
    nodes = opaque.kwargs["function"]({"experiment": experiment, "bag": bag, "namespace": namespace})
    out = {}
    for node in nodes:
        kw = node.kwargs
        assert kw["package"] == "contouring_ros"
        params_file, overrides = kw["parameters"]
        out[f"{kw['namespace'].rstrip('/')}/{kw['name']}"] = (kw["executable"], kw["namespace"],
                                                              Path(params_file).read_text(), overrides)
    return out


def _runner(path, bag, namespace: str, directory) -> dict:
    out = {}
    parameter_file = write_parameter_file(path.resolve(), namespace, directory)
    for node in graph_commands(path.resolve(), load_experiment(path), bag, namespace=namespace,
                               parameter_file=parameter_file):
        command = node.command
        ros = command[command.index("--ros-args") + 1:]
        remaps = dict(ros[i + 1].split(":=") for i, a in enumerate(ros) if a == "-r")
        params = {}
        for i, a in enumerate(ros):
            if a == "-p":
                key, value = ros[i + 1].split(":=", 1)
                params[key] = yaml.safe_load(value)
        out[node.name] = (command[2].rsplit(".", 1)[1], remaps["__ns"],
                          Path(ros[ros.index("--params-file") + 1]).read_text(), params)
    return out


@pytest.mark.parametrize("scenario", [DEFAULT.name, "paper003_helix_natural_local_f15_10.yaml"])
@pytest.mark.parametrize("namespace", ["/", "/m1"])
def test_the_launch_file_starts_the_runners_graph(launch_file, scenario, namespace, tmp_path):
    """Same nodes, namespaces, parameter files (by content: under a namespace both write a copy) and
    overrides as the runner, at the root and under a namespace."""
    path = CONFIG / scenario
    bag = tmp_path / "run.mcap"
    launched, runner = _launched(launch_file, str(path), str(bag), namespace), _runner(path, bag, namespace, tmp_path)
    assert launched.keys() == runner.keys()
    assert all(name.startswith(namespace.rstrip("/") + "/") for name in runner)
    for name in runner:
        executable, node_namespace, params_text, overrides = launched[name]
        assert (executable, node_namespace, params_text) == runner[name][:3], name
        assert {k: (str(v) if k in ("bag", "experiment_file") else v) for k, v in overrides.items()} == runner[name][3]
    if namespace != "/":
        assert '"/m1/x/plant":' in runner["/m1/x/plant"][2]


def test_the_launch_file_takes_an_installed_scenario_by_name(launch_file, tmp_path):
    launched = _launched(launch_file, "paper000_b_ismc_h50_newton", str(tmp_path / "b.mcap"))
    assert {"/recorder", "/interpolator", "/x/plant", "/y/plant", "/x/servo", "/y/servo", "/contour_estimator",
            "/ccc"} == set(launched)
    assert launched["/x/plant"][2] == DEFAULT.read_text()


def test_setup_installs_the_launch_file():
    setup = (ROOT / "setup.py").read_text()
    assert '(f"share/{package_name}/launch", glob("launch/*.launch.py"))' in setup
