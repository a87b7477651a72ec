"""An experiment text is validated once a process: a run read from a bag carries the Experiment it was read
with, and scoring, export, the Python API and ``run`` use that one instead of parsing the text again."""
from __future__ import annotations

import sys

import pytest

from conftest import DEFAULT, shortened

from contouring_ros import api, cli, config
from contouring_ros.records import bag_writer
from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import ConfigError
from contouring_ros.records.scoring import BAG_EXPERIMENT, read_run


@pytest.fixture
def parses(monkeypatch):
    """The ``where`` of each validation made while the test runs: every binding of experiment_from_data in
    the package's modules is counted (parse_experiment and load_experiment go through it)."""
    seen = []
    original = config.experiment_from_data

    def counted(data, where="<experiment>", text=""):
        seen.append(where)
        return original(data, where, text)
    for name, module in list(sys.modules.items()):
        if name.split(".")[0] == "contouring_ros" and getattr(module, "experiment_from_data", None) is original:
            monkeypatch.setattr(module, "experiment_from_data", counted)
    return seen


@pytest.fixture
def recorded(tmp_path):
    """(experiment file, its Experiment, a bag of it written in-process)."""
    path = tmp_path / "short.yaml"
    path.write_text(shortened(DEFAULT, 0.2))
    experiment = load_experiment(path)
    return path, experiment, bag_writer.write_simulation(tmp_path / "short.mcap", experiment,
                                                  simulate(build_loop(experiment)))


@pytest.mark.parametrize("command", [["score"], ["compare"], ["export", "--csv", "OUT"],
                                     ["replay", "--estimator", "tangent_line"]])
def test_a_command_on_a_bag_parses_its_experiment_once(recorded, parses, tmp_path, capsys, command):
    _, _, path = recorded
    arguments = [argument.replace("OUT", str(tmp_path / "out")) for argument in command]
    assert cli.main([arguments[0], str(path), *arguments[1:]]) == 0, capsys.readouterr().err
    assert parses == [BAG_EXPERIMENT]


def test_an_experiment_given_for_bags_is_parsed_once_for_all_of_them(recorded, parses, capsys):
    file, _, path = recorded
    assert cli.main(["score", str(path), str(path), "--experiment", str(file)]) == 0, capsys.readouterr().err
    assert len(parses) == 1 and parses[0].endswith("short.yaml")


def test_the_run_carries_the_experiment_it_was_read_with(recorded, parses):
    _, experiment, path = recorded
    run = read_run(path)
    assert parses == [BAG_EXPERIMENT]
    assert run.experiment.text == run.experiment_text == experiment.text
    assert run.experiment.path == BAG_EXPERIMENT and run.require_experiment() is run.experiment
    again = read_run(path, parsed=experiment)          # the text just parsed: taken as it is
    assert parses == [BAG_EXPERIMENT]
    assert again.experiment == run.experiment
    assert not [warning for warning in again.warnings if "validate" in warning]


def test_the_python_api_reads_a_bag_with_one_parse(recorded, parses):
    file, experiment, path = recorded
    assert api.read_bag(path).experiment.text == experiment.text
    assert parses == [BAG_EXPERIMENT]
    parses.clear()
    api.read_bag(path, experiment)                     # an Experiment given: none at all
    assert parses == []


def test_a_run_whose_experiment_does_not_validate_here_says_why_where_it_is_needed(recorded):
    _, experiment, path = recorded
    invalid = experiment.text.replace("    sample_time: 0.001\n", "    sample_time: 0.001\n    no_such_key: 1\n", 1)
    run = read_run(path, experiment_text=invalid)
    assert run.experiment is None and any("does not validate here" in warning for warning in run.warnings)
    assert isinstance(run.experiment_error, ConfigError) and "no_such_key" in str(run.experiment_error)
    with pytest.raises(ConfigError) as raised:
        run.require_experiment()
    assert raised.value is run.experiment_error


def test_simulate_with_settings_reads_the_file_it_writes_once(recorded, parses, capsys):
    file, _, _ = recorded
    assert cli.main(["simulate", str(file)]) == 0, capsys.readouterr().err
    assert len(parses) == 1
    parses.clear()
    # the file (for its text), the settings applied to its data, the file written with them: each once
    assert cli.main(["simulate", str(file), "--set", "ccc.kp=2.0"]) == 0, capsys.readouterr().err
    assert len(parses) == len(set(parses)) == 3, parses


@pytest.mark.graph
@pytest.mark.slow
def test_run_parses_the_experiment_file_once(recorded, parses, tmp_path, capsys):
    file, _, _ = recorded
    parses.clear()
    assert cli.main(["run", str(file), "--bag", str(tmp_path / "run.mcap")]) == 0, capsys.readouterr().err
    assert len(parses) == 1 and parses[0].endswith("short.yaml"), parses
