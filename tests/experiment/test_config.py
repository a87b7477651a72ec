"""Malformed experiment files fail at once with one line naming the key."""
import re

import numpy as np
import pytest

from contouring_ros.config import load_experiment, parse_experiment
from contouring_ros.errors import ConfigError
from conftest import CONFIG, DEFAULT

BASE = DEFAULT.read_text()


@pytest.mark.parametrize("old,new,expected", [
    ("    gain: 10.3\n    time_constant: 0.040\n    disturbance",
     "    gian: 10.3\n    time_constant: 0.040\n    disturbance", "/x/plant.gian: unknown key"),
    ("    gain: 10.3\n    time_constant: 0.040\n    disturbance",
     "    gain: fast\n    time_constant: 0.040\n    disturbance", "/x/plant.gain: expected a number, got 'fast'"),
    ("type: newton", "type: newtonian", "/contour_estimator.type: unknown name 'newtonian'"),
    ("type: unit_vector", "type: fuzzy", "/ccc.type: unknown name 'fuzzy'"),
    ("    sample_time: 0.001", "    sample_time: -0.001", "sample_time: expected a positive value"),
    ("law: ismc", "law: lqr", "/x/servo.law: unknown name 'lqr'"),
    ("time_constant: 0.045\n    disturbance", "time_constant: 0.0\n    disturbance",
     "/y/plant.time_constant: expected a positive value"),
    ('axes: ["x", "y"]', 'axes: ["x", "y", "z"]', "axes: 3 axes given but the parabola curve has 2"),
    ("/contour_estimator:", "/estimator:", "/estimator: unknown node section"),
    ("    kp: 1.0\n", "", "/ccc.kp: missing required key"),
    ("    mu: 1.0e-3\n", "    mu: [1]\n", "/x/servo.mu: expected a number"),
    ("    sample_time: 0.001", "    sample_time: 0.001\n    timing: soon", "timing: expected one of lockstep, realtime"),
])
def test_malformed_experiment_names_the_key(old, new, expected):
    assert old in BASE
    with pytest.raises(ConfigError) as info:
        parse_experiment(BASE.replace(old, new, 1), "exp.yaml")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("exp.yaml: ")
    assert expected in message


def test_yaml_aliases_are_refused():
    bomb = "a: &a [1, 1]\nb: &b [*a, *a]\nc: [*b, *b]\n"
    with pytest.raises(ConfigError, match="aliases"):
        parse_experiment(bomb, "bomb.yaml")


@pytest.mark.parametrize("content,expected", [(b"", "empty"), (b"\x00\x01\x02binary", "not a text file"),
                                               (b"key: [unclosed", "not valid YAML"), (b"- 1\n- 2\n", "ROS 2 parameter file")])
def test_unreadable_files(tmp_path, content, expected):
    path = tmp_path / "bad.yaml"
    path.write_bytes(content)
    with pytest.raises(ConfigError, match=expected):
        load_experiment(path)


def test_every_shipped_scenario_is_valid():
    from conftest import CONFIG
    for path in CONFIG.glob("*.yaml"):
        experiment = load_experiment(path)
        assert experiment.n_steps > 1


MORE_CASES = [
    ("curve: {type: parabola", "curve: {type: spiral", "curve.type: unknown name 'spiral'"),
    ("model: first_order_velocity", "model: second_order", "/x/plant.model: unknown name 'second_order'"),
    ("disturbance: {type: constant, value: 1.5e-4}", "disturbance: {type: gusts}", "/x/plant.disturbance.type: unknown name 'gusts'"),
    ("    kp: 1.0\n", "    kp: -1.0\n", "/ccc.kp: expected a value >= 0"),
    ("    kappa: 0.2985\n", "    kappa: 0.0\n", "/x/servo.kappa: expected a positive value"),
    ('axes: ["x", "y"]', 'axes: ["x", "x"]', "axes: axis names must be unique"),
    ('axes: ["x", "y"]', "axes: []", "axes: expected a non-empty list of names"),
    ("    sample_time: 0.001", '    sample_time: "fast"', "sample_time: expected a number"),
    ("    initial_state: on_reference", "    initial_state: somewhere", "initial_state: expected one of"),
    ("    max_iterations: 200\n", "    max_iterations: 2.5\n", "/contour_estimator.max_iterations: expected an integer"),
    ("/ccc:\n  ros__parameters:", "/ccc:\n  parameters:", "/ccc: expected a mapping with the single key 'ros__parameters'"),
    ("    sample_time: 0.001", "    sample_time: 0.001\n    duration: -1.0", "duration: expected a value >= 0"),
    ("    sample_time: 0.001", "    sample_time: 0.001\n    on_invalid_input: ignore", "on_invalid_input: expected one of"),
    ("    observer: true\n    c: 25.0", "    observer: yes please\n    c: 25.0", "/x/servo.observer: expected true or false"),
    ("theta_end: 0.02, duration: 2.0}", "theta_end: 0.02, duration: 0.0}", "schedule.duration: expected a positive value"),
    ("    time_constant: 0.045\n    observer", "    time_constant: .nan\n    observer", "/y/servo.time_constant: expected"),
]


@pytest.mark.parametrize("old,new,expected", MORE_CASES)
def test_more_malformed_experiments(old, new, expected):
    assert old in BASE, old
    with pytest.raises(ConfigError) as info:
        parse_experiment(BASE.replace(old, new, 1), "exp.yaml")
    assert expected in str(info.value) and "\n" not in str(info.value)


def test_axis_count_disagreeing_with_node_sections():
    with pytest.raises(ConfigError, match="/z/servo: unknown node section"):
        parse_experiment(BASE.replace("/y/servo:", "/z/servo:"), "exp.yaml")
    start = BASE.index("/y/servo:")
    without_y_servo = BASE[:start] + BASE[BASE.index("/contour_estimator:"):]
    with pytest.raises(ConfigError, match="/y/servo: missing required node section"):
        parse_experiment(without_y_servo, "exp.yaml")


def test_cli_refuses_every_malformed_file_in_one_line_before_any_node(tmp_path, capsys):
    """Every malformed file of this module through `contouring-ros run`: exit 2, one line, no traceback."""
    from contouring_ros.cli import main
    texts = [BASE.replace(old, new, 1) for old, new, _ in
             test_malformed_experiment_names_the_key.pytestmark[0].args[1] + MORE_CASES]
    texts += ["", "\x00\x01binary", "a: &a [1]\nb: [*a, *a]\n", "key: [unclosed"]
    assert len(texts) >= 25
    for i, text in enumerate(texts):
        path = tmp_path / f"bad{i}.yaml"
        path.write_text(text)
        assert main(["run", str(path), "--bag", str(tmp_path / f"bad{i}.mcap")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(f"error: {path}: ") and "Traceback" not in err
        assert not (tmp_path / f"bad{i}.mcap").exists()


HELIX = (CONFIG / "paper003_helix_natural_local_f15_10.yaml").read_text()


@pytest.mark.parametrize("old,new,expected", [
    ("{type: natural_local}", "{type: newton, k_prime: 500.0, c_prime: 500.0}",
     "/contour_estimator.type: the task_frame_pd controller with approximation 'natural_local' acts on the "
     "errors of the 'natural_local' estimator, got 'newton'"),
    ("approximation: natural_local", "approximation: osculating",
     "/ccc.approximation: expected one of first_order, natural_local, got 'osculating'"),
    ("/x/servo:\n  ros__parameters: {law: direct}",
     "/x/servo:\n  ros__parameters: {law: pid_feedforward, kp: 1.0, ki: 0.0, kd: 0.0, gain: 1.0, time_constant: 0.1}",
     "/x/servo.law: the task_frame_pd controller computes the whole command: every servo law must be 'direct'"),
    ("    f_b: 10.0\n", "", "/ccc.f_b: missing required key (the binormal bandwidth, for 3 axes)"),
    ("mass: [1.0, 1.0, 1.0]", "mass: [1.0, 1.0]", "/ccc.mass: expected one value per axis (3), got 2"),
    ("damping: 225.0", "damping: -1.0", "/y/plant.damping: expected a value >= 0"),
    ("length: 4.5", "length: 0.0", "curve.length: expected a positive value"),
    ("damping: 200.0, gain: 1.0}", "damping: 200.0, gain: 1.0, disturbance_unit: force}",
     "/x/plant.disturbance_unit: expected one of command, acceleration, got 'force'"),
    ("    sample_time: 0.001\n", "    sample_time: 0.001\n    ccc_takes_state: false\n",
     "/**.ccc_takes_state: the task_frame_pd controller uses the reference and the axis states: the CCC must "
     "take them (true)"),
])
def test_refused_combinations_and_task_frame_keys(old, new, expected):
    assert old in HELIX
    with pytest.raises(ConfigError) as info:
        parse_experiment(HELIX.replace(old, new, 1), "helix.yaml")
    assert expected in str(info.value) and "\n" not in str(info.value)


def test_direct_servo_needs_a_whole_command_controller():
    text = BASE.replace("/x/servo:\n  ros__parameters:\n    law: ismc", "/x/servo:\n  ros__parameters:\n    law: direct", 1)
    text = text.replace("    a: 12.5\n    b: 12.5\n    mu: 1.0e-3\n    kappa: 0.2985\n    gain: 10.3\n"
                        "    time_constant: 0.040\n    observer: true\n    c: 25.0\n    d: 25.0\n", "", 1)
    with pytest.raises(ConfigError, match="/x/servo.law: 'direct' passes the contour controller's output through"):
        parse_experiment(text, "exp.yaml")


def test_osculating_circle_and_adaptive_tnb_keys():
    circle = (CONFIG / "paper001_caseI_adaptive_tnb.yaml").read_text()
    with pytest.raises(ConfigError, match=r"/ccc.coupling: expected one value per axis \(2\), got 1"):
        parse_experiment(re.sub(r"coupling: \[[^\]]*\]", "coupling: [1.0]", circle), "c.yaml")
    with pytest.raises(ConfigError, match="the osculating_circle estimate needs a planar contour"):
        parse_experiment(HELIX.replace("{type: natural_local}", "{type: osculating_circle}"), "h.yaml")


def test_the_ccc_takes_reference_and_states_only_where_its_controller_uses_them():
    from contouring_ros.wire import graph
    from contouring_ros.config import controller_uses_state, load_experiment
    from contouring_ros.run.runner import shared_overrides
    default, helix = load_experiment(CONFIG / "paper000_b_ismc_h50_newton.yaml"), parse_experiment(HELIX, "helix")
    assert not controller_uses_state(default) and controller_uses_state(helix)
    assert shared_overrides(default) == {"ccc_takes_state": False} and shared_overrides(helix) == {}
    subscribers = {t.name: t.subscribers for t in graph.topics(["x", "y"], ccc_takes_state=False)}
    assert "/ccc" not in subscribers["/reference"] + subscribers["/x/state"] + subscribers["/y/state"]
    assert "/ccc" in subscribers["/contour_error"]
    assert all("/ccc" in t.subscribers for t in graph.topics(["x", "y"]) if t.name in ("/reference", "/x/state"))


def test_a_controller_entry_must_say_needs_state_as_its_object_does(monkeypatch):
    """The runner and the CCC node read needs_state from the registry entry, the simulation from the built
    object: a plugin Entry that leaves it out while its object needs the states is refused in one line."""
    import dataclasses

    from contouring_ros.config import CONTROLLERS, build_controller, build_curve
    from contouring_ros.experiment.registry import Entry

    class NeedsState:
        needs_state = True

    monkeypatch.setitem(CONTROLLERS._entries, "needs_state_plugin",
                        Entry("needs_state_plugin", {}, lambda s, c: NeedsState(), origin="a_plugin"))
    experiment = load_experiment(DEFAULT)
    experiment = dataclasses.replace(experiment, controller={"type": "needs_state_plugin"})
    with pytest.raises(ConfigError, match=r"object has needs_state = True but its registry entry has False"):
        build_controller(experiment, build_curve(experiment))
    monkeypatch.setitem(CONTROLLERS._entries, "needs_state_plugin",
                        Entry("needs_state_plugin", {}, lambda s, c: NeedsState(), origin="a_plugin", needs_state=True))
    assert build_controller(experiment, build_curve(experiment)).needs_state


def test_a_part_program_is_made_a_tool_path_once_per_load_and_again_once_changed(tmp_path, monkeypatch):
    """Loading an experiment checks its curve and then builds it: a part program is read and made a tool path
    once (a program of many blocks takes seconds to read), each caller gets its own copy, and an edited file
    is read again."""
    import os

    from contouring_ros.core import curves
    from contouring_ros.experiment.build import build_loop
    made = []
    original = curves.ToolPath.from_program.__func__
    monkeypatch.setattr(curves.ToolPath, "from_program",
                        classmethod(lambda cls, *a, **k: made.append(1) or original(cls, *a, **k)))
    program = tmp_path / "part.ngc"
    program.write_text("G21 G90 G61\nG1 X5 Y0 F600\nX5 Y5\n")
    config = tmp_path / "part.yaml"
    config.write_text((CONFIG / "gcode_example_part.yaml").read_text().replace("parts/example_part.ngc", "part.ngc")
                      .replace('axes: ["x", "y", "z"]', 'axes: ["x", "y"]'))
    config.write_text(re.sub(r"/z/\w+:\n  ros__parameters: \{[^}]*\}\n", "", config.read_text()))
    first = build_loop(load_experiment(str(config)))
    assert len(made) == 1
    second = build_loop(load_experiment(str(config)))
    assert len(made) == 1 and second.curve is not first.curve and second.curve.segments is first.curve.segments
    program.write_text("G21 G90 G61\nG1 X6 Y0 F600\nX6 Y6\n")
    os.utime(program, ns=(program.stat().st_atime_ns, program.stat().st_mtime_ns + 10**9))
    third = build_loop(load_experiment(str(config)))
    assert len(made) == 2 and np.allclose(third.curve.point(third.curve.domain[1]), [0.006, 0.006])
