"""contouring_ros.nodes.rclpy_adapter: the only module that uses rclpy's internals; its check at import; its take and
wait on a real rclpy node."""
from __future__ import annotations

import ast
import importlib.util
import re
import time
from importlib import metadata

import pytest

from conftest import ROOT

from contouring_ros.nodes import rclpy_adapter
from contouring_ros.errors import ContouringError, IncompatibleRclpy
from contouring_ros.wire import catalogue
from contouring_ros.nodes import scripts

ADAPTER = ROOT / "contouring_ros" / "nodes" / "rclpy_adapter.py"
#: what only the adapter may name: rclpy's C extension and the private calls made on its objects
PRIVATE_RCLPY = re.compile(r"implementation_singleton|rclpy_implementation|\b_rclpy\b|\btake_message\b|"
                           r"\bservice_take_request\b|\bservice_send_response\b|\bWaitSet\b|\.handle\b")


def _sources():
    """Every module of the package and every script of bench/ and tools/ but the adapter, with its path
    relative to the root."""
    paths = sorted((ROOT / "contouring_ros").rglob("*.py")) + sorted((ROOT / "bench").glob("*.py")) + \
        sorted((ROOT / "tools").glob("*.py"))
    return [(path.relative_to(ROOT), path.read_text(encoding="utf-8")) for path in paths if path != ADAPTER]


def test_only_the_adapter_uses_rclpy_internals():
    found = [f"{path}:{number}: {line.strip()}" for path, text in _sources()
             for number, line in enumerate(text.splitlines(), 1) if PRIVATE_RCLPY.search(line)]
    for path, text in _sources():
        for node in ast.walk(ast.parse(text, str(path))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "rclpy":
                names = (node.module or "").split(".") + [alias.name for alias in node.names]
                if any(name.startswith("_") for name in names):
                    found.append(f"{path}:{node.lineno}: {ast.unparse(node)}")
    assert not found, "rclpy internals outside contouring_ros/nodes/rclpy_adapter.py:\n" + "\n".join(found)


def _private(name) -> bool:
    return isinstance(name, str) and name.startswith("_") and not name.startswith("__")


def _own(node) -> bool:
    return isinstance(node, ast.Name) and node.id in ("self", "cls")


def test_no_private_attribute_is_read_across_objects():
    """``x._name`` (or getattr/hasattr/setattr(x, "_name")) only on ``self`` or ``cls``: another object's
    (ours or rclpy's) is read through its public methods and properties."""
    found = []
    for path, text in [*_sources(), (ADAPTER.relative_to(ROOT), ADAPTER.read_text(encoding="utf-8"))]:
        for node in ast.walk(ast.parse(text, str(path))):
            if isinstance(node, ast.Attribute) and _private(node.attr) and not _own(node.value):
                found.append(f"{path}:{node.lineno}: {ast.unparse(node)}")
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and \
                    node.func.id in ("getattr", "hasattr", "setattr", "delattr") and len(node.args) > 1 and \
                    isinstance(node.args[1], ast.Constant) and _private(node.args[1].value) and not _own(node.args[0]):
                found.append(f"{path}:{node.lineno}: {ast.unparse(node)}")
    assert not found, "private attributes read across objects:\n" + "\n".join(found)


def _import_adapter_afresh():
    """Execute the adapter's module anew (as its import would), outside sys.modules."""
    spec = importlib.util.spec_from_file_location("contouring_ros.nodes.rclpy_adapter_probe", ADAPTER)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_import_names_the_rclpy_found_and_the_one_written_for_when_an_internal_is_missing(monkeypatch):
    from rclpy.impl.implementation_singleton import rclpy_implementation
    assert _import_adapter_afresh().missing_internals() == []
    monkeypatch.delattr(rclpy_implementation, "WaitSet")
    with pytest.raises(ImportError) as raised:
        _import_adapter_afresh()
    assert isinstance(raised.value, IncompatibleRclpy) and isinstance(raised.value, ContouringError)
    message = str(raised.value)
    assert message == (f"contouring_ros needs rclpy internals that {rclpy_adapter.installed_version()} lacks "
                       "(WaitSet); it was written for rclpy 7.1 (ROS 2 Jazzy)")
    assert "\n" not in message


def test_a_missing_method_is_named_too():
    from rclpy.impl.implementation_singleton import rclpy_implementation

    class Service:
        pass

    implementation = type("Implementation", (), {"WaitSet": rclpy_implementation.WaitSet,
                                                 "Subscription": rclpy_implementation.Subscription,
                                                 "Service": Service})
    assert rclpy_adapter.missing_internals(implementation) == ["Service.service_take_request"]
    with pytest.raises(ImportError, match=r"lacks \(Service.service_take_request\); it was written for rclpy 7.1"):
        rclpy_adapter.check_internals(implementation)


#: a node's console script as pip and colcon write it for setup.py's console_scripts, run where rclpy lacks the
#: WaitSet the adapter checks for
SCRIPT_WITHOUT_WAIT_SET = """
import sys
from rclpy.impl.implementation_singleton import rclpy_implementation
del rclpy_implementation.WaitSet
from contouring_ros.nodes.scripts import {node}
sys.exit({node}())
"""


def test_every_node_has_a_console_script_in_the_scripts_module():
    assert sorted(scripts.__all__) == sorted(node.console_script for node in catalogue.NODES)
    assert all(callable(getattr(scripts, name)) for name in scripts.__all__)


@pytest.mark.parametrize("node", scripts.__all__)
def test_a_node_s_console_script_says_in_one_line_that_rclpy_lacks_an_internal(node):
    import subprocess
    import sys
    done = subprocess.run([sys.executable, "-c", SCRIPT_WITHOUT_WAIT_SET.format(node=node)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert (done.returncode, done.stderr.splitlines()) == (1, [
        f"error: contouring_ros needs rclpy internals that {rclpy_adapter.installed_version()} lacks (WaitSet); "
        "it was written for rclpy 7.1 (ROS 2 Jazzy)"]), done.stderr


def test_the_installed_version_comes_from_the_package_metadata(monkeypatch):
    assert rclpy_adapter.installed_version().startswith(rclpy_adapter.RCLPY_DISTRIBUTIONS)

    def no_metadata(name):
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(metadata, "version", no_metadata)
    assert rclpy_adapter.installed_version() == "rclpy of unknown version"


@pytest.fixture
def ros_context(monkeypatch):
    """An rclpy context of this process on a ROS domain of its own (the runner's environment), shut down after."""
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    from contouring_ros.run.runner import DomainLease, private_environment

    with DomainLease() as lease:
        for key, value in private_environment(lease.domain_id).items():
            monkeypatch.setenv(key, value)
        context = Context()
        rclpy.init(context=context, domain_id=lease.domain_id, signal_handler_options=SignalHandlerOptions.NO)
        try:
            yield context
        finally:
            rclpy.try_shutdown(context=context)


@pytest.mark.graph
def test_take_wait_and_take_request_on_a_real_node(ros_context):
    """In this process, on a domain of its own: one message published, waited for and taken serialised; one
    request at the node's parameter service taken and answered."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rcl_interfaces.srv import ListParameters
    from sensor_msgs.msg import JointState

    from contouring_ros.wire import cdr
    from contouring_ros.nodes.base import GRAPH_QOS

    node = rclpy.create_node("adapter_probe", context=ros_context)
    publisher = node.create_publisher(JointState, "/probe", GRAPH_QOS)
    subscription = node.create_subscription(JointState, "/probe", lambda _: None, GRAPH_QOS, raw=True)
    wait_set, take = rclpy_adapter.SubscriptionWaitSet([subscription], ros_context), \
        rclpy_adapter.taker(subscription, JointState)
    assert len(wait_set) == 1 and take() is None
    deadline = time.monotonic() + 10.0
    while subscription.get_publisher_count() < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    data = cdr.encode_joint_state(1, 2, ["x"], [0.5], [0.25])
    publisher.publish(data)
    taken = None
    while taken is None and time.monotonic() < deadline:
        wait_set.wait(100_000_000)
        taken = take()
    assert taken is not None, "the message published was not taken"
    assert bytes(taken[0]) == data and taken[1]["publication_sequence_number"] == 1
    assert take() is None

    service = next(s for s in node.services if s.srv_name.endswith("/list_parameters"))
    assert rclpy_adapter.take_request(service) == (None, None)
    client = node.create_client(ListParameters, service.srv_name)
    assert client.wait_for_service(timeout_sec=10.0)
    future = client.call_async(ListParameters.Request())
    request = header = None
    while header is None and time.monotonic() < deadline:
        request, header = rclpy_adapter.take_request(service)
        time.sleep(0.01)
    assert isinstance(request, ListParameters.Request)
    service.send_response(service.callback(request, ListParameters.Response()), header)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.spin_until_future_complete(future, timeout_sec=10.0)
    assert future.done() and "use_sim_time" in future.result().result.names
    executor.shutdown()
    node.destroy_node()


@pytest.mark.graph
def test_a_node_that_looks_late_counts_a_publisher_that_left_by_the_messages_it_left(ros_context):
    """wait_for_graph, on a real node: the publisher of an input published, had its message acknowledged and
    left before the node first looked (a recorder slow to start on a short run); its message is waiting, so
    the graph is up. An input nobody ever published on is still waited for, until graph_timeout."""
    import types

    import rclpy
    from rclpy.duration import Duration
    from sensor_msgs.msg import JointState

    from contouring_ros.wire import cdr, graph
    from contouring_ros.errors import RunError
    from contouring_ros.nodes.base import GRAPH_QOS
    from contouring_ros.nodes.node import LockstepNode

    x_state, y_state = graph.state_topic("x"), graph.state_topic("y")
    ros_node = rclpy.create_node("late_looker", context=ros_context)
    node = LockstepNode.__new__(LockstepNode)
    node.node, node.name, node.callbacks, node._realtime, node.n_steps = ros_node, "/late_looker", True, False, 1
    node.experiment = types.SimpleNamespace(graph_timeout=3.0, start_time=0.0, sample_time=0.001,
                                            timing="lockstep")
    node._topics = {t.name: t for t in graph.recorded_topics(["x", "y"])}
    node._outputs = {}
    node._inputs = [(topic, ros_node.create_subscription(JointState, topic, lambda _: None, GRAPH_QOS,
                                                         raw=True), JointState, None)
                    for topic in (x_state, y_state)]
    x_subscription = node._inputs[0][1]

    publisher_node = rclpy.create_node("early_leaver", context=ros_context)
    publisher = publisher_node.create_publisher(JointState, x_state, GRAPH_QOS)
    deadline = time.monotonic() + 10.0
    while publisher.get_subscription_count() < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    publisher.publish(cdr.encode_joint_state(0, 0, ["x"], [0.5], [0.25]))
    assert publisher.wait_for_all_acked(Duration(seconds=10))
    publisher_node.destroy_node()
    while x_subscription.get_publisher_count() > 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert x_subscription.get_publisher_count() == 0

    with pytest.raises(RunError, match=rf"still waiting for the publisher of {y_state}\)"):
        node.wait_for_graph()        # /x/state's publisher has shown itself by its message; /y/state's never
    node._inputs = node._inputs[:1]
    started = time.monotonic()
    node.wait_for_graph()
    assert time.monotonic() - started < 1.0
    assert rclpy_adapter.SubscriptionWaitSet([x_subscription], ros_context).holding() == [True]
    ros_node.destroy_node()
