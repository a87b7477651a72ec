"""Every node parameter carries a descriptor built from the validator's specs, and ROS tools read it.

The graph-level test starts one node (/x/plant, waiting for the rest of its graph) and reads its parameters
back through the standard parameter services (list, describe, get, set) with a plain rclpy client in its
own process, on the node's private domain: what `ros2 param list|describe|get|set` would show.
"""
import json
import subprocess
import sys

import pytest

from contouring_ros.config import GLOBALS, PLANTS, read_yaml, section_from_parameters
from contouring_ros.nodes.parameters import describe, node_parameters
from contouring_ros.run.runner import DomainLease, private_environment
from conftest import CONFIG, DEFAULT


def _flat(mapping: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in mapping.items():
        out.update(_flat(value, f"{prefix}{key}.") if isinstance(value, dict) else {f"{prefix}{key}": value})
    return out


def _received(path, node: str) -> dict:
    """The flat parameters a node gets from the file: the shared section and its own."""
    data = read_yaml(path.read_text())
    return {**_flat(data["/**"]["ros__parameters"]), **_flat(data.get(node, {}).get("ros__parameters", {}))}


@pytest.mark.parametrize("scenario, node, role", [
    (DEFAULT, "/x/plant", "plant"), (DEFAULT, "/y/servo", "servo"), (DEFAULT, "/contour_estimator", "contour_estimator"),
    (DEFAULT, "/ccc", "ccc"), (CONFIG / "paper003_helix_natural_local_f15_10.yaml", "/ccc", "ccc"),
    (CONFIG / "paper004_saddle_eso.yaml", "/z/servo", "servo"), (DEFAULT, "/interpolator", "interpolator")])
def test_every_given_key_and_every_default_is_described(scenario, node, role):
    received = _received(scenario, node)
    described = node_parameters(received, node, role)
    assert set(received) <= set(described)                   # nothing the file gives is left out
    # every shared key is described, but for one whose default is an empty list, which ROS cannot type
    assert {k for k in GLOBALS if GLOBALS[k].kind != "dict" and GLOBALS[k].default != []} <= \
        {k.split(".")[0] for k in described}
    for name, value in received.items():
        assert described[name].value == value and described[name].given
    assert section_from_parameters({n: p.value for n, p in described.items() if p.given}) == \
        section_from_parameters(received)
    for parameter in described.values():
        assert parameter.description and "read once at start" in describe(parameter)


def test_descriptions_carry_units_and_the_validators_ranges():
    described = node_parameters(_received(DEFAULT, "/x/plant"), "/x/plant", "plant")
    assert "[s]" in described["time_constant"].description and "[s]" in described["sample_time"].description
    low, high = PLANTS["first_order_velocity"]["time_constant"].bounds
    assert f"from {low:g} to {high:g}" in describe(described["time_constant"])
    assert not described["saturation"].given and described["saturation"].value == 0.0     # a default
    assert "one of: on_reference, at_rest" in described["initial_state"].description


#: the start of a plain rclpy client script: `call` one of a node's parameter services (target: sys.argv[1])
_SERVICE_CALL = r"""
import json, sys, rclpy
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters, SetParameters
rclpy.init()
node = rclpy.create_node("parameter_reader")
target = sys.argv[1]

def call(kind, service, request):
    client = node.create_client(kind, f"{target}/{service}")
    if not client.wait_for_service(timeout_sec=60.0):
        raise SystemExit(f"no {service} service")
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=30.0)
    return future.result()
"""

_CLIENT = _SERVICE_CALL + r"""
names = list(call(ListParameters, "list_parameters", ListParameters.Request()).result.names)
descriptors = call(DescribeParameters, "describe_parameters", DescribeParameters.Request(names=names)).descriptors
values = call(GetParameters, "get_parameters", GetParameters.Request(names=["gain", "time_constant", "axes"])).values
change = Parameter(name="gain", value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=1.0))
result = call(SetParameters, "set_parameters", SetParameters.Request(parameters=[change])).results[0]
print(json.dumps({
    "names": names,
    "descriptors": {d.name: {"type": d.type, "description": d.description, "read_only": d.read_only,
                             "range": [[r.from_value, r.to_value] for r in d.floating_point_range]
                                      + [[r.from_value, r.to_value] for r in d.integer_range],
                             "constraints": d.additional_constraints} for d in descriptors},
    "values": [values[0].double_value, values[1].double_value, list(values[2].string_array_value)],
    "set": [result.successful, result.reason]}))
"""


@pytest.mark.graph
def test_a_plain_rclpy_client_reads_the_descriptors_through_the_parameter_services(tmp_path):
    script = tmp_path / "client.py"
    script.write_text(_CLIENT)
    with DomainLease() as lease:
        env = private_environment(lease.domain_id)
        node = subprocess.Popen([sys.executable, "-m", "contouring_ros.nodes.plant", "--ros-args", "-r", "__ns:=/x",
                                 "-r", "__node:=plant", "--params-file", str(DEFAULT), "-p", "graph_timeout:=90.0"],
                                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            client = subprocess.run([sys.executable, str(script), "/x/plant"], env=env, capture_output=True,
                                    text=True, timeout=120)
        finally:
            node.terminate()
            node.wait(timeout=30)
    assert client.returncode == 0, client.stderr[-2000:]
    seen = json.loads(client.stdout.strip().splitlines()[-1])
    expected = node_parameters({**_received(DEFAULT, "/x/plant"), "graph_timeout": 90.0}, "/x/plant", "plant")
    assert set(expected) <= set(seen["names"])
    for name, parameter in expected.items():
        got = seen["descriptors"][name]
        assert got["read_only"] and got["description"] == describe(parameter), name
    assert seen["descriptors"]["gain"]["range"] == [list(PLANTS["first_order_velocity"]["gain"].bounds)]
    assert seen["descriptors"]["disturbance.type"]["type"] == 4          # PARAMETER_STRING
    assert seen["values"] == [10.3, 0.04, ["x", "y"]]
    successful, reason = seen["set"]
    assert not successful and "read-only" in reason.lower().replace("read only", "read-only")


_GET = _SERVICE_CALL + r"""name = sys.argv[2]

value = call(GetParameters, "get_parameters", GetParameters.Request(names=[name])).values[0]
described = call(DescribeParameters, "describe_parameters", DescribeParameters.Request(names=[name])).descriptors[0]
print(json.dumps([value.type, value.double_value, described.description]))
"""


def _node_parameter(tmp_path, executable: str, arguments: list, target: str, name: str) -> list:
    """[type, double value, description] of parameter ``name`` of a node started by hand with ``arguments``."""
    script = tmp_path / "get.py"
    script.write_text(_GET)
    with DomainLease() as lease:
        env = private_environment(lease.domain_id)
        node = subprocess.Popen([sys.executable, "-m", f"contouring_ros.nodes.{executable}", "--ros-args", *arguments],
                                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
        try:
            client = subprocess.run([sys.executable, str(script), target, name], env=env, capture_output=True,
                                    text=True, timeout=120)
        finally:
            node.terminate()
            node.wait(timeout=30)
    assert client.returncode == 0, client.stderr[-2000:]
    return json.loads(client.stdout.strip().splitlines()[-1])


@pytest.mark.graph
def test_the_readme_s_parameter_examples_run_as_written(tmp_path):
    """`ros2 param describe` of the README's node and key describes a parameter the default experiment's node
    has; its second parameter file changes that node's key; `-p` does not beat the node's section (ROS 2's
    precedence, which the README states)."""
    import re
    from conftest import ROOT
    readme = (ROOT / "README.md").read_text()
    target, key = re.search(r"`ros2 param describe (\S+) (\w+)`", readme).groups()
    printf, override = re.search(r"printf '([^']+)' > (\S+)\n", readme).groups()
    command = re.search(r"ros2 run contouring_ros (\w+) --ros-args (--params-file \$P --params-file \S+)\n", readme)
    executable, arguments = command.groups()
    (tmp_path / override).write_text(printf.replace("\\n", "\n"))
    arguments = arguments.replace("$P", str(DEFAULT)).split()
    kind, value, description = _node_parameter(tmp_path, executable, arguments, target, key)
    given = read_yaml(printf.replace("\\n", "\n"))[target]["ros__parameters"][key]
    file_value = read_yaml(DEFAULT.read_text())[target]["ros__parameters"][key]
    assert kind == 3 and value == given != file_value and description      # PARAMETER_DOUBLE, the override's
    kind, value, _ = _node_parameter(tmp_path, executable, ["--params-file", str(DEFAULT), "-p", f"{key}:={given}"],
                                     target, key)
    assert value == file_value                                               # the node's section wins over -p


def test_set_applies_the_sweep_s_keys_to_a_file_the_ros_parser_reads_alike(tmp_path):
    from contouring_ros.config import load_experiment
    from contouring_ros.errors import ConfigError
    from contouring_ros.experiment.settings import settings_file
    out = settings_file(DEFAULT, ["ccc.kp=2.0", "x/servo.a=13.0", "curve.h=60.0"], tmp_path)
    assert out.name == DEFAULT.name
    experiment, base = load_experiment(out), load_experiment(DEFAULT)
    assert experiment.controller["kp"] == 2.0 and experiment.servos["x"]["a"] == 13.0 and experiment.curve["h"] == 60.0
    assert experiment.servos["y"] == base.servos["y"] and list(experiment.axes) == ["x", "y"]
    for bad, fragment in [("ccc.kq=2.0", "/ccc.kq: unknown key"), ("ccc.kp=-1", "/ccc.kp"), ("ccc.kp", "key=value")]:
        with pytest.raises(ConfigError, match=fragment) as info:
            settings_file(DEFAULT, [bad], tmp_path)
        assert str(info.value).startswith("--set ") and "\n" not in str(info.value)


def test_simulate_with_set_scores_the_changed_experiment(tmp_path):
    """`contouring-ros simulate CONFIG --set KEY=VALUE` takes the run's key syntax and prints the scores of
    the changed experiment; a wrong key is one line naming it."""
    import dataclasses

    from conftest import ROOT, shortened
    from contouring_ros.config import build_loop, parse_experiment
    from contouring_ros.core.simulation import simulate
    from contouring_ros.records.scoring import score_run
    path = tmp_path / "short.yaml"
    path.write_text(shortened(DEFAULT, 0.3))
    out = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "simulate", str(path), "--set", "ccc.kp=0.0"],
                         capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr
    experiment = parse_experiment(path.read_text(), str(path))
    loop = build_loop(dataclasses.replace(experiment, controller=dict(experiment.controller, kp=0.0)))
    mce = score_run(loop.curve, simulate(loop)).mce
    printed = float(next(line for line in out.stdout.splitlines() if line.startswith("MCE")).split()[-1])
    assert printed == pytest.approx(mce * 1e6, rel=1e-3)
    plain = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "simulate", str(path)],
                           capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert plain.stdout != out.stdout                      # the setting changed the run
    wrong = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "simulate", str(path), "--set", "ccc.kq=1"],
                           capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert wrong.returncode != 0 and "Traceback" not in wrong.stderr and "kq" in wrong.stderr.strip().splitlines()[-1]


@pytest.mark.graph
def test_run_with_set_records_the_changed_experiment(tmp_path):
    """`contouring-ros run CONFIG --set ccc.kp=2.0`: the graph runs the changed experiment (its bag scores as
    the in-process simulation of it, bit for bit) and keeps it."""
    from conftest import ROOT, shortened
    from contouring_ros.config import build_loop, parse_experiment
    from contouring_ros.core.simulation import simulate
    from contouring_ros.records.scoring import read_run
    path = tmp_path / "short.yaml"
    path.write_text(shortened(DEFAULT, 0.3))
    bag = tmp_path / "set.mcap"
    out = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "run", str(path), "--set", "ccc.kp=2.0",
                          "--bag", str(bag)], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr
    run = read_run(bag)
    experiment = parse_experiment(run.experiment_text, "bag")
    assert experiment.controller["kp"] == 2.0
    expected = simulate(build_loop(experiment))
    assert (run.result.position == expected.position).all() and (run.result.command == expected.command).all()


def test_set_names_the_run_after_what_it_changed(tmp_path):
    """A run changed with --set is named after its settings (its bag, legends, compare columns and report
    then tell it from the file's own runs); different settings keep different names even past 100
    characters; a name the settings give themselves wins; the API names its runs the same way."""
    from contouring_ros import api
    from contouring_ros.run.runner import default_bag_path
    from contouring_ros.experiment.settings import settings_name, written_settings
    _, plain = written_settings(DEFAULT, ["ccc.kp=1.0"], tmp_path)
    assert plain.name == "paper000_b_ismc_h50_newton_ccc.kp-1.0"
    (tmp_path / "two").mkdir()
    _, changed = written_settings(DEFAULT, ["ccc.kp=2.0", "x/servo.a=13.0"], tmp_path / "two")
    assert changed.name == "paper000_b_ismc_h50_newton_ccc.kp-2.0_x-servo.a-13.0"
    assert default_bag_path(changed).name.startswith("paper000_b_ismc_h50_newton_ccc.kp-2.0_x-servo.a-13.0_")
    (tmp_path / "named").mkdir()
    _, named = written_settings(DEFAULT, ["ccc.kp=2.0", "experiment.name=stiff"], tmp_path / "named")
    assert named.name == "stiff"
    long = [settings_name("a" * 90, {"ccc.kp": value}) for value in (1.0, 2.0)]
    assert all(len(name) <= 100 for name in long) and long[0] != long[1]
    assert api.simulate(DEFAULT, {"duration": 0.01, "ccc.kp": 2.0}).experiment.name == \
        "paper000_b_ismc_h50_newton_duration-0.01_ccc.kp-2.0"


def test_compare_names_runs_by_their_settings_and_says_how_they_differ(tmp_path):
    """compare's columns carry what --set changed, and a last block lists the keys whose values differ
    between the runs' experiments with each run's value."""
    from conftest import ROOT, shortened
    path = tmp_path / "short.yaml"
    path.write_text(shortened(DEFAULT, 0.2))
    cli = [sys.executable, "-m", "contouring_ros.cli"]
    for bag, extra in (("plain.mcap", []), ("stiff.mcap", ["--set", "ccc.kp=2.0", "--set", "x/servo.a=13.0"])):
        done = subprocess.run(cli + ["simulate", str(path), "--bag", str(tmp_path / bag)] + extra,
                              capture_output=True, text=True, cwd=ROOT, timeout=300)
        assert done.returncode == 0, done.stderr
    out = subprocess.run(cli + ["compare", str(tmp_path / "plain.mcap"), str(tmp_path / "stiff.mcap")],
                         capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr
    header = out.stdout.splitlines()[0].split()
    name = "paper000_b_ismc_h50_newton"          # the file's experiment.name
    assert header == [name, f"{name}_ccc.kp-2.0_x-servo.a-13.0"]
    differ = out.stdout[out.stdout.index("how the experiments differ:"):].splitlines()[1:]
    rows = {line.split()[0]: line.split(None, 1)[1] for line in differ}     # in the file's order
    assert rows == {"ccc.kp": f"{name}: 1.0; {name}_ccc.kp-2.0_x-servo.a-13.0: 2.0",
                    "x/servo.a": f"{name}: 12.5; {name}_ccc.kp-2.0_x-servo.a-13.0: 13.0"}


def test_run_never_overwrites_a_file_at_its_bag_path(tmp_path):
    """`contouring-ros run CONFIG --bag PATH` with something at PATH is refused in one line before any node
    starts, and the file is left as it was (was: deleted, then the bag written in its place)."""
    from conftest import ROOT
    mine = tmp_path / "mine.mcap"
    mine.write_text("a user's file\n")
    done = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "run", str(DEFAULT), "--bag", str(mine)],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "exists" in done.stderr, done.stderr
    assert "starting" not in done.stdout and mine.read_text() == "a user's file\n"
