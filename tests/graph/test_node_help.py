"""Nodes started by hand explain themselves: --help says what the node is and how to start it; a node without
an experiment file, a per-axis node outside every axis' namespace and one under an axis the file does not
have say so, naming the file's own sections and axes (was: 'sample_time: missing required key',
'/plant.model: missing required key', '/z/servo.law: missing required key')."""
import subprocess
import sys

import pytest

from contouring_ros.wire import catalogue
from contouring_ros.nodes.explain import explain, help_text, parameter_files, wants_help
from contouring_ros.run.runner import DomainLease, private_environment
from conftest import DEFAULT, ROOT

P = str(DEFAULT)


def _node(name: str, *arguments) -> subprocess.CompletedProcess:
    """The node's module started as `ros2 run` starts its script, on a domain of its own."""
    with DomainLease() as lease:
        return subprocess.run([sys.executable, "-m", f"contouring_ros.nodes.{name}", *arguments], cwd=ROOT,
                              env=private_environment(lease.domain_id), capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("node", catalogue.NODES, ids=lambda node: node.name)
def test_help_says_what_the_node_is_and_how_to_start_it(node):
    text = help_text(node.name)
    assert text.startswith(f"{catalogue.doc_name(node)}: the {node.name} node")
    assert f"ros2 run contouring_ros {node.console_script} --ros-args" in text and node.pip_script in text
    assert ("-r __ns:=/<axis>" in text) == node.per_axis
    for topic in node.outputs:
        assert topic in text


def test_the_command_line_is_read_as_ros_reads_it():
    argv = ["plant", "--ros-args", "-r", "__ns:=/x", "--params-file", "a.yaml", "--params-file", "b.yaml", "--",
            "--params-file", "not_ros.yaml"]
    assert parameter_files(argv) == ["a.yaml", "b.yaml"]
    assert wants_help(["plant", "--help"]) and wants_help(["plant", "-h", "--ros-args"])
    assert not wants_help(["plant", "--ros-args", "--help"]) and not wants_help(["plant"])


def test_explanations_name_the_file_s_sections_and_axes(write_experiment):
    assert explain("/plant", "plant", ["plant"]).startswith("/plant: no experiment file: start it with --ros-args "
                                                           "--params-file EXPERIMENT.yaml -r __ns:=/<axis>")
    assert explain("/plant", "plant", ["plant", "--ros-args", "--params-file", P]) == (
        "/plant: a plant serves one axis: this file has /x/plant and /y/plant: start it under one of those "
        "namespaces (-r __ns:=/x)")
    assert explain("/z/servo", "servo", ["servo", "--ros-args", "-r", "__ns:=/z", "--params-file", P]) == (
        "/z/servo: z is not an axis of this experiment (its axes: x, y): start it under one of /x, /y")
    three = write_experiment(DEFAULT.read_text().replace('axes: ["x", "y"]', 'axes: ["x", "y", "z"]'), "three.yaml")
    assert "z is not an axis" not in (explain("/z/servo", "servo", ["s", "--ros-args", "--params-file", str(three)])
                                      or "")
    assert explain("/x/plant", "plant", ["plant", "--ros-args", "--params-file", P]) is None   # not why
    assert explain("/ccc", "ccc", ["ccc", "--ros-args", "--params-file", P]) is None


@pytest.mark.graph
@pytest.mark.parametrize("arguments, expected", [
    (["--help"], None),
    ([], "/plant: no experiment file: start it with --ros-args --params-file EXPERIMENT.yaml"),
    (["--ros-args", "--params-file", P], "this file has /x/plant and /y/plant: start it under one of those "
                                         "namespaces (-r __ns:=/x)"),
    (["--ros-args", "-r", "__ns:=/z", "--params-file", P], "/z/plant: z is not an axis of this experiment "
                                                          "(its axes: x, y)"),
], ids=["help", "no file", "no namespace", "not an axis"])
def test_a_plant_started_by_hand_explains_itself(arguments, expected):
    done = _node("plant", *arguments)
    assert "Traceback" not in done.stdout + done.stderr
    if expected is None:
        assert done.returncode == 0 and done.stdout == help_text("plant") + "\n"
    else:
        assert done.returncode == 1 and done.stderr.count("\n") == 1 and expected in done.stderr, done.stderr
