"""Malformed experiment files fail at once with one line naming the key."""
import pytest

from contouring_ros.config import load_experiment, parse_experiment
from contouring_ros.errors import ConfigError
from conftest import DEFAULT

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
