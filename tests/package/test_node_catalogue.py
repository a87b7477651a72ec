"""contouring_ros/wire/catalogue.py is the one list of the graph's node concerns: setup.py's console scripts,
the graph's nodes and topics, the composed loop, the experiment file's sections, the
launch file and the node and topic tables of the docs all agree with it."""
import importlib
import json
import re
import subprocess
import sys

import pytest

from contouring_ros.run import composed
from contouring_ros import config
from contouring_ros.wire import graph
from contouring_ros.nodes import parameters
from contouring_ros.wire import catalogue
from contouring_ros.nodes.node import LockstepNode
from conftest import DEFAULT, ROOT
from test_launch import _launched, launch_file  # noqa: F401 (launch_file: the fixture)

AXES = ["x", "y", "z"]


@pytest.mark.parametrize("command, ros_layout", [("install", True), ("develop", True), ("bdist_wheel", False),
                                                  ("editable_wheel", False), ("dist_info", False)])
def test_setup_py_installs_the_catalogue_s_console_scripts_without_importing_the_package(command, ros_layout):
    """setup.py runs with numpy and rclpy unimportable and reads the catalogue without importing the package;
    colcon's commands (install, develop) get the executables `ros2 run` names, pip's wheel builds the
    contouring-ros-<node> commands, so that nothing named plant or servo lands on the PATH."""
    script = ("import runpy, sys, setuptools\n"
              f"sys.argv = ['setup.py', {command!r}]\n"
              "sys.modules['numpy'] = sys.modules['rclpy'] = None\n"
              "setuptools.setup = lambda **kw: print(repr(kw['entry_points']['console_scripts']))\n"
              "runpy.run_path('setup.py')\n"
              "assert not [m for m in sys.modules if m.startswith('contouring_ros')], 'setup.py imported the package'\n")
    result = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    scripts = eval(result.stdout)
    names = [node.console_script if ros_layout else node.pip_script for node in catalogue.NODES]
    assert scripts == [f"{name} = contouring_ros.nodes.scripts:{node.console_script}"
                       for name, node in zip(names, catalogue.NODES)] + ["contouring-ros = contouring_ros.cli:main"]
    if not ros_layout:
        assert all(name.startswith("contouring-ros-") for name in names)
        assert "contouring-ros-contour-estimator" in names and "contouring-ros-plant" in names


@pytest.mark.parametrize("node", catalogue.NODES, ids=lambda node: node.name)
def test_every_class_string_names_a_node_class(node):
    cls = catalogue.load_class(node)
    assert isinstance(cls, type) and issubclass(cls, LockstepNode), node.node_class
    assert (cls.role, cls.default_name, cls.per_axis) == (node.name, node.name, node.per_axis)
    assert callable(importlib.import_module(node.module).main)


def test_every_topic_is_typed_and_named_by_the_graph():
    for node in catalogue.NODES:
        topics = [i.topic for i in node.inputs] + list(node.outputs)
        assert all(t in catalogue.TOPIC_TYPES or t == catalogue.EVERY_TOPIC for t in topics), node.name
        assert all(i.use in catalogue.USES for i in node.inputs), node.name
        assert all(i.when in (None, "ccc_takes_state", "interpolator_takes_state") for i in node.inputs), node.name
    published = [t for node in catalogue.NODES for t in node.outputs]
    assert len(published) == len(set(published)), "a topic with two publishers"
    assert set(catalogue.TOPIC_TYPES) == set(published) | {catalogue.DIAGNOSTICS}
    assert (graph.state_topic("x"), graph.command_topic("x")) == ("/x/state", "/x/command")


def test_graph_nodes_and_topics_come_from_the_catalogue():
    names = [name for node in catalogue.NODES for name in node.full_names(AXES)]
    assert graph.node_names(AXES) == names
    assert names[0] == "/interpolator" and names[-1] == "/recorder"
    topics = graph.topics(AXES)
    assert [t.name for t in topics] == [name for node in catalogue.NODES for axis in (AXES if node.per_axis else [None])
                                        for out in node.outputs for name in catalogue.expand(out, AXES, axis)]
    for topic in topics:
        node = next(n for n in catalogue.NODES if topic.publisher in n.full_names(AXES))
        assert any(topic.name in catalogue.expand(out, AXES) for out in node.outputs)
        assert topic.subscribers[-1] == "/recorder"


def test_a_topic_lists_its_readers_then_the_nodes_it_paces_then_the_recorder():
    subscribers = {t.name: t.subscribers for t in graph.topics(["x", "y"], interpolator_takes_state=True)}
    assert subscribers["/contour_error"] == ("/ccc", "/interpolator", "/recorder")
    assert subscribers["/x/state"] == ("/interpolator", "/contour_estimator", "/ccc", "/x/servo", "/recorder")
    assert subscribers["/reference"] == ("/contour_estimator", "/ccc", "/x/servo", "/y/servo", "/recorder")
    assert subscribers["/y/command"] == ("/y/plant", "/recorder")


def test_graph_and_composed_loop_run_the_nodes_in_the_same_order():
    every = graph.node_names(AXES)
    assert composed.loop_order(AXES) == every
    group = ["/recorder", "/y/servo", "/ccc", "/x/plant"]
    assert composed.loop_order(AXES, group) == ["/x/plant", "/ccc", "/y/servo", "/recorder"]
    specs = graph.node_specs(AXES)
    assert [s.full_name for s in specs] == ["/recorder"] + every[:-1]
    for spec in specs:
        node = catalogue.NODE[spec.name]
        assert (spec.executable, spec.module) == (node.console_script, node.module)
    assert set(composed._node_classes()) == set(catalogue.NODE)


def test_the_launch_file_starts_the_catalogue_s_nodes(launch_file, tmp_path):  # noqa: F811
    launched = _launched(launch_file, str(DEFAULT), str(tmp_path / "run.mcap"))
    axes = list(config.load_experiment(DEFAULT).axes)
    expected = {name: node.console_script for node in catalogue.NODES for name in node.full_names(axes)}
    assert {name: executable for name, (executable, *_) in launched.items()} == expected


def test_experiment_sections_and_parameter_tables_come_from_the_catalogue():
    sections = config.node_sections(AXES)
    assert set(sections) == set(graph.node_names(AXES))
    assert all(name.rsplit("/", 1)[1] == concern for name, concern in sections.items())
    # the order the validator names them in ("unknown node section (expected one of: ...)")
    assert list(sections) == ["/x/plant", "/y/plant", "/z/plant", "/x/servo", "/y/servo", "/z/servo",
                              "/contour_estimator", "/ccc", "/interpolator", "/recorder"]
    assert list(config.OPTIONAL_NODES) == [node.name for node in catalogue.NODES if node.optional]
    assert set(config.ROLE_TYPES) == {node.name for node in catalogue.NODES if not node.optional}
    assert catalogue.PER_AXIS == {"plant", "servo"}
    for node in catalogue.NODES:      # every node's keys are described (from their Params)
        keys = config.OPTIONAL_NODES[node.name] if node.optional else \
            next(iter(config.ROLE_TYPES[node.name][1].registered().values())).params
        assert all(parameters.description(spec, key) != key for key, spec in keys.items()), node.name


# --- the docs' tables -------------------------------------------------------------------------------------

def _table(text: str, header: str) -> list:
    """The rows (lists of cells, backticks removed) of the Markdown table whose header row starts with ``header``."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip().startswith(header))
    rows = []
    for line in lines[start + 2:]:
        if not line.strip().startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip().strip("|").split("|")])
    return rows


def _plain(cell: str) -> str:
    return cell.replace("`", "")


def _topics_named(cell: str) -> list:
    return re.findall(r"`(/[^`]*)`", cell)


@pytest.mark.parametrize("document", ["README.md", "docs/ARCHITECTURE.md"])
def test_the_docs_topic_tables_are_the_catalogue_s(document):
    rows = _table((ROOT / document).read_text(), "| topic | type |")
    assert [(_plain(topic), _plain(kind)) for topic, kind, *_ in rows] == \
        [(topic, kind) for topic, kind, _ in catalogue.topic_rows()]


def test_the_graph_module_s_topic_table_is_the_catalogue_s():
    rows = _table(graph.__doc__, "| topic ")
    assert [(topic, kind, publisher.lstrip("/")) for topic, kind, publisher, *_ in rows] == \
        [(topic, kind, publisher.lstrip("/")) for topic, kind, publisher in catalogue.topic_rows()]


def test_the_readme_s_node_table_is_the_catalogue_s():
    rows = _table((ROOT / "README.md").read_text(), "| node | console script |")
    assert [_plain(row[0]) for row in rows] == [name for name, *_ in catalogue.node_rows()]
    for (name, script, inputs, outputs), (_, doc_script, doc_inputs, doc_outputs) in zip(catalogue.node_rows(), rows):
        assert _plain(doc_script) == script, name
        if inputs == (catalogue.EVERY_TOPIC,):
            assert "every topic" in doc_inputs, name
            inputs = ()
        assert set(_topics_named(doc_inputs)) == set(inputs), name
        assert set(_topics_named(doc_outputs)) == set(outputs), name
        if not catalogue.NODE[name.rsplit("/", 1)[1]].per_axis:      # another node takes every axis' topic
            assert all(f"every `{topic}`" in doc_inputs for topic in inputs if catalogue.AXIS in topic), name


# what a node's process must not import at start: each takes a node a quarter to two seconds on one core,
# and the eight processes of a graph start on two cores at once, within a realtime run's start delay
HEAVY = ("scipy.signal", "scipy.stats", "scipy.optimize", "scipy.interpolate", "scipy.linalg", "matplotlib",
         "numba", "mcap")


def test_a_node_s_module_imports_nothing_heavy():
    """Every node's module imports without the libraries the nodes need only for some experiments (they are
    imported where used): a graph of eight node processes on a 2-core machine is up in about 5 s, not 12."""
    heavy = {}
    for node in catalogue.NODES:
        script = (f"import json, sys, {node.module}\n"
                  f"print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))\n")
        result = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True,
                                timeout=120)
        assert result.returncode == 0, result.stderr
        if imported := json.loads(result.stdout):
            heavy[node.name] = imported
    assert not heavy, heavy
