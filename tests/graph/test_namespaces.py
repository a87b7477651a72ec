"""Graphs under a namespace: every node and topic under it, two graphs in one ROS domain apart."""
import json
import re
import subprocess
import sys
import threading

import pytest
from mcap.reader import make_reader

from contouring_ros.wire import graph
from contouring_ros.records.bag_writer import write_simulation
from contouring_ros.config import build_loop, load_experiment, namespaced_parameter_file, read_yaml
from contouring_ros.core.simulation import simulate
from contouring_ros.run.runner import DomainLease, run_graph
from contouring_ros.records.scoring import read_run
from conftest import DEFAULT, shortened


@pytest.mark.parametrize("given, expected", [
    ("m1", "/m1"), ("/m1", "/m1"), ("/m1/", "/m1"), ("lab/m_2", "/lab/m_2"), ("", "/"), ("/", "/"), (None, "/")])
def test_namespaces_are_read_as_ros_reads_them(given, expected):
    assert graph.normalize_namespace(given) == expected


@pytest.mark.parametrize("bad", ["1m", "m-1", "m1//x", "m 1", "é"])
def test_a_name_ros_refuses_is_refused_naming_the_part(bad):
    with pytest.raises(ValueError, match="is not a ROS name part"):
        graph.normalize_namespace(bad)


@pytest.mark.parametrize("bad, fragment", [("m__1", "holds '__'"), ("a" * 230, "at most 160"),
                                           ("/".join(["ab"] * 100), "at most 160")])
def test_a_namespace_ros_would_refuse_late_is_refused_at_once(bad, fragment):
    with pytest.raises(ValueError, match=fragment):
        graph.normalize_namespace(bad)


def test_topics_and_nodes_resolve_under_the_graph_namespace():
    assert graph.resolve("/m1", "/x/state") == "/m1/x/state"
    assert graph.resolve("/", "/x/state") == "/x/state"
    assert graph.resolve("/m1", "/clock") == "/clock" and graph.resolve("/m1", "/diagnostics") == "/diagnostics"
    assert graph.resolve("/m1", "/clock", namespaced_clock=True) == "/m1/clock"
    assert graph.graph_namespace("/m1/x/plant", per_axis=True) == "/m1"
    assert graph.graph_namespace("/m1/ccc", per_axis=False) == "/m1"
    assert graph.graph_namespace("/x/servo", per_axis=True) == "/"
    specs = graph.node_specs(["x", "y"], namespace="/lab/m1")
    assert {s.full_name for s in specs} == {"/lab/m1" + n for n in graph.node_names(["x", "y"])}
    assert graph.namespace_of_topics(["/lab/m1/reference", "/lab/m1/x/state"]) == "/lab/m1"
    with pytest.raises(ValueError, match="several graphs"):
        graph.namespace_of_topics(["/m1/reference", "/m2/reference"])


def test_the_namespaced_parameter_file_changes_only_the_node_keys():
    text = DEFAULT.read_text()
    namespaced = namespaced_parameter_file(text, "/m1")
    original, changed = read_yaml(text), read_yaml(namespaced)
    assert {key: value for key, value in changed.items()} == {
        (key if key == "/**" else "/m1" + key): value for key, value in original.items()}
    assert re.sub(r'"/m1(/[^"]*)"', r"\1", namespaced) == text     # every byte but the keys as written


@pytest.mark.graph
@pytest.mark.slow
def test_namespaced_graphs_share_a_domain_without_hearing_each_other(tmp_path):
    """Three runs of one experiment at once in one ROS domain, under /m1 (process layout), /m2 (composed)
    and /m3 (grouped): each bag holds only its own graph's topics, under its namespace, with the payloads
    of the simulation (a message heard from another graph would be refused by the nodes' publisher checks
    and stop the run)."""
    path = tmp_path / "short.yaml"     # several graphs on one domain: each its own /clock and /diagnostics
    path.write_text(shortened(DEFAULT, 0.3).replace("    sample_time: 0.001\n",
                                                    "    sample_time: 0.001\n    namespaced_clock: true\n", 1))
    experiment = load_experiment(path)
    expected = read_run(write_simulation(tmp_path / "simulation.mcap", experiment,
                                         simulate(build_loop(experiment))), keep_payloads=True).payloads
    with DomainLease() as lease:
        domain = lease.domain_id
    bags, errors = {}, []

    def run(namespace, layout, groups=None):
        try:
            bags[namespace] = run_graph(path, tmp_path / f"{namespace}.mcap", namespace=namespace, layout=layout,
                                        groups=groups, domain_id=domain, shared_domain=True)
        except Exception as error:     # reported below with the namespace
            errors.append(f"{namespace}: {error}")

    threads = [threading.Thread(target=run, args=args) for args in (
        ("m1", "process"), ("m2", "composed"), ("m3", "process", ["x/plant,x/servo", "y/plant,y/servo"]))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors
    for namespace, bag in bags.items():
        with open(bag, "rb") as stream:
            channels = {c.topic for c in make_reader(stream).get_summary().channels.values()}
        assert channels == {f"/{namespace}{t.name}" for t in graph.recorded_topics(["x", "y"])}
        recorded = read_run(bag, keep_payloads=True)
        assert recorded.complete_steps == experiment.n_steps
        assert recorded.payloads == expected, namespace


def test_a_bad_namespace_is_refused_in_one_line():
    result = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "run", str(DEFAULT), "--namespace", "m-1"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "namespace 'm-1'" in lines[0] and "Traceback" not in result.stderr


def _flat(mapping, prefix=""):
    out = {}
    for key, value in mapping.items():
        if isinstance(value, dict):
            out.update(_flat(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def test_a_plain_parameter_file_under_a_namespace_gets_a_hint():
    """A node under /m1 started with the plain file (sections /x/servo ...) receives the shared keys only:
    its missing key is named with the namespace as the cause (was: '/m1/x/servo.law: missing required key')."""
    import yaml
    from contouring_ros.config import experiment_for_node
    from contouring_ros.errors import ConfigError
    shared = _flat(yaml.safe_load(DEFAULT.read_text())["/**"]["ros__parameters"])
    with pytest.raises(ConfigError) as info:
        experiment_for_node(shared, "/m1/x/servo", "servo")
    message = str(info.value)
    assert "missing required key" in message and "under the namespace /m1" in message and "/x/servo" in message
    assert "namespaced_parameter_file" in message and "\n" not in message
    with pytest.raises(ConfigError) as info:          # no namespace: no hint
        experiment_for_node(shared, "/x/servo", "servo")
    assert "hint" not in str(info.value)


SIM_TIME_LISTENER = r"""
import json, sys, time, rclpy
from rclpy.parameter import Parameter
from diagnostic_msgs.msg import DiagnosticArray
rclpy.init()
node = rclpy.create_node("sim_time_listener", parameter_overrides=[Parameter("use_sim_time", value=True)])
heard = set()
node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: heard.update(s.name for s in m.status), 100)
print("ready", flush=True)
latest, deadline = 0, time.monotonic() + 120
while time.monotonic() < deadline and not (latest >= int(sys.argv[1]) and len(heard) >= int(sys.argv[2])):
    rclpy.spin_once(node, timeout_sec=0.1)
    latest = max(latest, node.get_clock().now().nanoseconds)
print(json.dumps([latest, sorted(heard)]), flush=True)
"""


@pytest.mark.graph
def test_a_use_sim_time_node_follows_the_graph_s_clock_under_a_namespace(tmp_path):
    """Under /m1, /clock and /diagnostics stay global (as ROS tools expect): a use_sim_time node on the domain
    follows the graph's clock, and a listener of /diagnostics hears every node's report (was: /m1/clock and
    /m1/diagnostics, and the node stayed at time 0)."""
    from contouring_ros.run.runner import private_environment
    # 5 s of steps: time for every node to discover the listener before its (volatile) end-of-run report; a
    # participant whose first announcements were missed is announced again only seconds later
    path = tmp_path / "short.yaml"
    path.write_text(shortened(DEFAULT, 5.0))
    experiment = load_experiment(path)
    with DomainLease() as lease:
        domain = lease.domain_id
    nodes = graph.node_names(experiment.axes)
    listener = subprocess.Popen([sys.executable, "-c", SIM_TIME_LISTENER, str(4_900_000_000), str(len(nodes) - 1)],
                                env=private_environment(domain), stdout=subprocess.PIPE, text=True)
    try:
        assert listener.stdout.readline().strip() == "ready"
        bag = run_graph(path, tmp_path / "m1.mcap", namespace="m1", domain_id=domain, shared_domain=True)
        out, _ = listener.communicate(timeout=150)
    finally:
        if listener.poll() is None:
            listener.kill()
    latest, heard = json.loads(out.strip().splitlines()[-1])
    assert 4_900_000_000 <= latest <= 5_000_000_000, latest
    assert {"/m1" + name for name in nodes if name != "/recorder"} <= set(heard), heard
    with open(bag, "rb") as stream:
        channels = {c.topic for c in make_reader(stream).get_summary().channels.values()}
    assert {"/clock", "/diagnostics", "/m1/reference", "/m1/x/state"} <= channels
    assert read_run(bag).complete_steps == experiment.n_steps
