"""Types of one's own through entry points: the example plugin (examples/contouring_plugin_example, one file)
is installed into a temporary folder and its estimator validated, simulated, run through the node graph
(equal to the simulation), swept and replayed; registries refuse unknown types and name broken plugins."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import pytest

from contouring_ros.config import CONTROLLERS, ESTIMATORS, SERVOS, build_controller, parse_experiment
from contouring_ros.errors import ConfigError
from contouring_ros.experiment.registry import ROLES
from conftest import DEFAULT, ROOT, shortened

EXAMPLE = ROOT / "examples" / "contouring_plugin_example"
PLUGIN_ESTIMATOR = "  ros__parameters:\n    type: two_step_newton\n    steps: 3\n"


def install(target: Path, project: Path = EXAMPLE) -> Path:
    """Install ``project`` into ``target`` as pip --target would: its module and a dist-info with its entry
    points (read from its pyproject.toml), so importlib.metadata finds them with ``target`` on sys.path."""
    meta = tomllib.loads((project / "pyproject.toml").read_text())["project"]
    target.mkdir(parents=True, exist_ok=True)
    for module in project.glob("*.py"):
        shutil.copy(module, target / module.name)
    info = target / f"{meta['name'].replace('-', '_')}-{meta['version']}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {meta['name']}\nVersion: {meta['version']}\n")
    lines = []
    for group, points in meta.get("entry-points", {}).items():
        lines.append(f"[{group}]")
        lines += [f"{name} = {value}" for name, value in points.items()]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    return target


def run_python(code: str, path: Path, cwd: Path, timeout: float = 240) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(path), str(ROOT / "tests"), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)


def with_estimator(text: str, body: str) -> str:
    start = text.index("/contour_estimator:\n") + len("/contour_estimator:\n")
    end = text.index("\n/", start) + 1
    return text[:start] + body + text[end:]


def test_the_example_estimator_runs_through_validation_simulation_graph_sweep_and_replay(tmp_path):
    site = install(tmp_path / "site")
    experiment = tmp_path / "plugin.yaml"
    experiment.write_text(with_estimator(shortened(DEFAULT, 0.06), PLUGIN_ESTIMATOR))
    done = run_python(f"""
        import numpy as np, subprocess, sys
        from contouring_ros.config import ESTIMATORS, build_loop, load_experiment
        from contouring_ros.core.simulation import simulate
        from contouring_ros.run.runner import run_graph
        from contouring_ros import api
        from contouring_ros.records.scoring import read_run
        experiment = load_experiment({str(experiment)!r})
        assert experiment.estimator == {{"type": "two_step_newton", "steps": 3}}, experiment.estimator
        assert ESTIMATORS.entry("two_step_newton").origin.startswith("contouring_plugin_example")
        loop = build_loop(experiment)
        assert type(loop.estimator).__name__ == "TwoStepNewtonEstimator" and loop.estimator.steps == 3
        expected = simulate(loop)
        bag = run_graph({str(experiment)!r}, {str(tmp_path / "run.mcap")!r}, layout="composed")
        recorded = read_run(bag)
        assert recorded.complete_steps == loop.n_steps
        for name in ("estimate_theta", "estimate_vector", "estimate_signed", "correction", "command", "position"):
            np.testing.assert_array_equal(getattr(recorded.result, name), getattr(expected, name), err_msg=name)
        assert np.abs(expected.estimate_signed).max() > 0
        rows = api.sweep_grid(experiment, {{"contour_estimator.steps": [1, 2]}}, workers=1)
        assert len(rows) == 2 and all(r.scores is not None for r in rows), rows
        replay = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "replay", str(bag), "--estimator",
                                 "two_step_newton:steps=1", "--estimator", "tangent_line"],
                                capture_output=True, text=True)
        assert replay.returncode == 0, replay.stderr
        assert "two_step_newton steps=1" in replay.stdout, replay.stdout
        print("plugin ok")
    """, site, tmp_path, timeout=400)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "plugin ok" in done.stdout


def test_a_plugin_is_refused_where_it_does_not_fit(tmp_path):
    site = install(tmp_path / "site")
    text = with_estimator(DEFAULT.read_text(), "  ros__parameters:\n    type: two_step_newton\n    steps: 0\n")
    done = run_python(f"""
        from contouring_ros.config import parse_experiment
        from contouring_ros.errors import ConfigError
        try:
            parse_experiment({text!r}, "p.yaml")
        except ConfigError as error:
            print(error)
    """, site, tmp_path)
    assert done.returncode == 0, done.stderr
    assert "p.yaml: /contour_estimator.steps: expected a positive value" in done.stdout


def test_a_plugin_that_fails_to_load_is_named_in_one_line(tmp_path):
    project = tmp_path / "broken"
    project.mkdir()
    (project / "broken_plugin.py").write_text("raise ImportError('needs a library that is not installed')\n")
    (project / "pyproject.toml").write_text('[project]\nname = "broken-plugin"\nversion = "1.0"\n'
                                            '[project.entry-points."contouring_ros.controllers"]\n'
                                            'shaky = "broken_plugin:ShakyCCC"\n')
    site = install(tmp_path / "site", project)
    text = DEFAULT.read_text().replace("type: unit_vector", "type: shaky", 1)
    done = run_python(f"""
        from contouring_ros.config import parse_experiment, load_experiment
        from contouring_ros.errors import ConfigError
        load_experiment({str(DEFAULT)!r})       # experiments that do not name it are unaffected
        try:
            parse_experiment({text!r}, "p.yaml")
        except ConfigError as error:
            print("ERROR", error)
    """, site, tmp_path)
    assert done.returncode == 0, done.stderr
    line = done.stdout.strip()
    assert line.startswith("ERROR ") and "\n" not in line
    assert "plugin 'shaky' (contouring_ros.controllers: broken_plugin:ShakyCCC) failed to load: ImportError: " \
           "needs a library that is not installed" in line


def test_unknown_types_are_refused_naming_the_known_ones():
    with pytest.raises(ConfigError, match=r"/ccc.type: unknown name 'fuzzy' \(expected one of: none, variable_gain, "
                                          r"unit_vector, task_frame_pd, tvt, adaptive_tnb"):
        parse_experiment(DEFAULT.read_text().replace("type: unit_vector", "type: fuzzy", 1), "e.yaml")
    experiment = parse_experiment(DEFAULT.read_text(), "e.yaml")
    from dataclasses import replace
    with pytest.raises(ConfigError, match="controller type 'fuzzy' is unknown .expected one of: none, "):
        build_controller(replace(experiment, controller={"type": "fuzzy", "kp": 1.0}), None)   # no fallback


def test_every_role_has_a_registry_with_its_entry_point_group():
    from contouring_ros import config
    roles = {r.role: r for r in (config.CURVES, config.SCHEDULES, config.PLANTS, config.DISTURBANCES, SERVOS,
                                  ESTIMATORS, CONTROLLERS)}
    assert set(roles) == set(ROLES)
    for role, registry in roles.items():
        assert registry.group == f"contouring_ros.{role}s"
        for name in registry:
            entry = registry.entry(name)
            assert entry.name == name and callable(entry.build) and isinstance(entry.params, dict)
    assert {n for n in CONTROLLERS if CONTROLLERS.entry(n).whole_command} == {"task_frame_pd", "tvt", "mpcc"}
    assert [n for n in SERVOS if SERVOS.entry(n).direct] == ["direct"]


HOSTILE_PLUGIN = '''
import math
import sys

from contouring_plugin_example import TwoStepNewtonEstimator
from contouring_ros.config import Param


class Hostile(TwoStepNewtonEstimator):
    """The example estimator, until step ``at`` where it does what its subclass says."""
    params = {"at": Param("int", 5)}

    def __init__(self, curve, at: int = 5):
        super().__init__(curve, 2)
        self.at, self.k = at, 0

    def step(self, reference, position):
        estimate = super().step(reference, position)
        self.k += 1
        return self.hostile(estimate) if self.k > self.at else estimate


class Raising(Hostile):
    def hostile(self, estimate):
        return 1 / 0


class Exiting(Hostile):
    def hostile(self, estimate):
        sys.exit(0)


class Vanishing(Hostile):
    def hostile(self, estimate):
        import os
        os._exit(0)


class Infinite(Hostile):
    def hostile(self, estimate):
        return type(estimate)(theta=math.inf, vector=estimate.vector, signed=estimate.signed)


class NotANumber(Hostile):
    def hostile(self, estimate):
        return type(estimate)(theta=estimate.theta, vector=estimate.vector * math.nan, signed=estimate.signed)
'''


HOSTILE_ROLES = '''
import math

import numpy as np

from contouring_ros.config import Param
from contouring_ros.core.curves import Parabola
from contouring_ros.core.disturbances import ConstantDisturbance
from contouring_ros.core.interpolation import UniformSchedule
from contouring_ros.core.plants import FirstOrderVelocityAxis


class OffThePart(Parabola):
    """The parabola, raising past the vertex (theta > 0) on the per-step path (a float theta)."""
    params = {"a": Param("float"), "h": Param("float")}

    def columns(self, t):
        if np.ndim(t) == 0 and t > 0.0:
            raise ValueError("theta is off the part")
        return super().columns(t)


class Hollow(Parabola):
    """The parabola, with a NaN point past the vertex on the per-step path."""
    params = {"a": Param("float"), "h": Param("float")}

    def columns(self, t):
        out = super().columns(t)
        return [(math.nan, math.nan)] + out[1:] if np.ndim(t) == 0 and t > 0.0 else out


class Stalling(UniformSchedule):
    params = {"theta_start": Param("float"), "theta_end": Param("float"), "duration": Param("float")}

    def __call__(self, t):
        if np.ndim(t) == 0 and t > 0.01:
            raise RuntimeError("the feed hold never ends")
        return super().__call__(t)


class Leaking(FirstOrderVelocityAxis):
    """A first-order axis whose position reads NaN from its 6th measurement."""
    params = {"gain": Param("float"), "time_constant": Param("float")}

    def __init__(self, gain, time_constant, sample_time, position, velocity):
        super().__init__(gain, time_constant, sample_time, None, position, velocity)
        self.reads = 0

    def measure(self):
        self.reads += 1
        position, velocity = super().measure()
        return (math.nan if self.reads > 5 else position), velocity


class Spiking(ConstantDisturbance):
    params = {"value": Param("float")}

    def __call__(self, t):
        return math.inf if t > 0.005 else super().__call__(t)
'''
ROLE_PLUGINS = {"curves": {"off_the_part": "OffThePart", "hollow": "Hollow"}, "schedules": {"stalling": "Stalling"},
                "plants": {"leaking": "Leaking"}, "disturbances": {"spiking": "Spiking"}}


@pytest.fixture(scope="module")
def hostile_site(tmp_path_factory):
    root = tmp_path_factory.mktemp("hostile")
    project = root / "hostile"
    project.mkdir()
    (project / "hostile_plugin.py").write_text(HOSTILE_PLUGIN)
    (project / "exits_at_import.py").write_text("import sys\nsys.exit(0)\n")
    points = {"raising": "hostile_plugin:Raising", "exiting": "hostile_plugin:Exiting",
              "infinite": "hostile_plugin:Infinite", "vanishing": "hostile_plugin:Vanishing",
              "not_a_number": "hostile_plugin:NotANumber",
              "exits_at_import": "exits_at_import:Whatever"}
    (project / "hostile_roles.py").write_text(HOSTILE_ROLES)
    (project / "pyproject.toml").write_text('[project]\nname = "hostile-plugin"\nversion = "1.0"\n'
                                            '[project.entry-points."contouring_ros.estimators"]\n'
                                            + "".join(f'{k} = "{v}"\n' for k, v in points.items())
                                            + "".join(f'[project.entry-points."contouring_ros.{group}"]\n'
                                                      + "".join(f'{k} = "hostile_roles:{v}"\n' for k, v in names.items())
                                                      for group, names in ROLE_PLUGINS.items()))
    site = install(root / "site", project)
    for module in EXAMPLE.glob("*.py"):
        shutil.copy(module, site / module.name)
    return site


def cli(site: Path, cwd: Path, *args, timeout: float = 300) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, "-m", "contouring_ros.cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


def simulate_failure_line(site: Path, tmp_path: Path, text: str, named: str) -> str:
    """``simulate`` of the experiment ``text`` with the plugins of ``site``: it must fail (exit 1 or 2) in one
    line, without a traceback, naming ``named``; that line."""
    experiment = tmp_path / "hostile.yaml"
    experiment.write_text(text)
    done = cli(site, tmp_path, "simulate", str(experiment))
    assert done.returncode in (1, 2), (done.returncode, done.stdout, done.stderr)
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and named in lines[0], done.stderr
    return lines[0]


@pytest.mark.parametrize("name, fragment", [
    ("raising", "failed at step 5: ZeroDivisionError: division by zero"),
    ("exiting", "failed at step 5: SystemExit: 0"),
    ("infinite", "returned a theta that is not a finite number at step 5 (inf)"),
    ("not_a_number", "returned a vector that is not a finite number at step 5 ([nan nan])"),
    ("exits_at_import", "failed to load: SystemExit: 0"),
])
def test_a_plugin_failing_in_simulate_ends_in_one_line_naming_it_and_the_step(hostile_site, tmp_path, name,
                                                                               fragment):
    line = simulate_failure_line(hostile_site, tmp_path, with_estimator(
        shortened(DEFAULT, 0.05), f"  ros__parameters:\n    type: {name}\n"), f"plugin {name!r} (contouring_ros.estimators: ")
    assert fragment in line, line


@pytest.mark.parametrize("name, fragment", [
    ("exits_at_import", "failed to load: SystemExit: 0"),
    ("exiting", "failed at step 5: SystemExit: 0"),
])
def test_a_plugin_calling_sys_exit_makes_run_fail_naming_it(hostile_site, tmp_path, name, fragment):
    experiment = tmp_path / "hostile.yaml"
    experiment.write_text(with_estimator(shortened(DEFAULT, 0.05), f"  ros__parameters:\n    type: {name}\n"))
    done = cli(hostile_site, tmp_path, "run", str(experiment), "--bag", str(tmp_path / "run.mcap"),
               "--composed")
    assert done.returncode != 0, (done.stdout, done.stderr)
    assert "Traceback" not in done.stderr
    assert f"plugin {name!r}" in done.stderr and fragment in done.stderr, done.stderr


def test_a_node_that_exits_0_mid_run_is_named_as_having_exited(hostile_site, tmp_path):
    experiment = tmp_path / "vanishing.yaml"
    experiment.write_text(with_estimator(shortened(DEFAULT, 0.05), "  ros__parameters:\n    type: vanishing\n"))
    done = cli(hostile_site, tmp_path, "run", str(experiment), "--bag", str(tmp_path / "run.mcap"), "--process")
    assert done.returncode != 0, (done.stdout, done.stderr)
    assert "Traceback" not in done.stderr
    error = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert error and "node /contour_estimator exited with code 0 before completing its steps" in error[0], done.stderr
    assert "stalled" not in error[0] and "/x/servo" not in error[0], error[0]


def with_replaced(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


ROLE_CASES = {     # plugin -> (the default experiment's text, what replaces it), fragment of the one-line error
    "off_the_part": (("type: parabola", "type: off_the_part"),
                     "(contouring_ros.curves: hostile_roles:OffThePart) failed in columns(0.0"),
    "hollow": (("type: parabola", "type: hollow"), "returned a value that is not a finite number in columns("),
    "stalling": (("type: uniform", "type: stalling"),
                 "failed in __call__(0.011): RuntimeError: the feed hold never ends"),
    "leaking": (("    model: first_order_velocity\n    gain: 10.3\n    time_constant: 0.040\n"
                 "    disturbance: {type: constant, value: 1.5e-4}\n",
                 "    model: leaking\n    gain: 10.3\n    time_constant: 0.040\n"),
                "returned a value that is not a finite number in measure() ([ nan "),
    "spiking": (("disturbance: {type: constant", "disturbance: {type: spiking"),
                "returned a value that is not a finite number in __call__(0.006) (inf)"),
}


@pytest.mark.parametrize("name", list(ROLE_CASES))
def test_a_curve_schedule_plant_or_disturbance_plugin_failing_ends_in_one_line_naming_it(hostile_site, tmp_path,
                                                                                       name):
    """Plugins of every role run under the guard: an exception or a value that is not finite (a NaN curve
    point, a NaN plant state, an infinite load) ends simulate in one line naming the plugin and the call."""
    (old, new), fragment = ROLE_CASES[name]
    line = simulate_failure_line(hostile_site, tmp_path, with_replaced(shortened(DEFAULT, 0.05), old, new),
                                 f"plugin {name!r} (contouring_ros.")
    assert fragment in line, line


def test_a_plugin_value_that_is_not_finite_is_a_diverged_row_of_a_sweep(hostile_site, tmp_path):
    """In a sweep (and so in tuning) a plugin's non-finite value is that combination's divergence, reported on
    its row, as a built-in's is: the other combinations still run."""
    (old, new), _ = ROLE_CASES["leaking"]
    experiment = tmp_path / "leaking.yaml"
    experiment.write_text(with_replaced(shortened(DEFAULT, 0.05), old, new))
    done = cli(hostile_site, tmp_path, "sweep", str(experiment), "--grid", "ccc.kp=1,2", "--out", str(tmp_path / "s.csv"))
    assert done.returncode == 0, (done.stdout, done.stderr)
    rows = (tmp_path / "s.csv").read_text().splitlines()[1:]
    assert len(rows) == 2 and all("diverged: plugin 'leaking'" in row for row in rows), rows


def test_a_registry_is_only_made_for_a_known_role_and_the_catalogue_has_one_per_role():
    from contouring_ros.experiment.catalogue import ROLES as CATALOGUE_ROLES
    from contouring_ros.experiment.registry import Role
    assert tuple(CATALOGUE_ROLES) == ROLES
    with pytest.raises(ValueError, match="unknown role 'widget'"):
        Role("widget")


def test_a_plugin_key_named_like_a_built_in_one_gets_its_own_range_not_the_built_in_s():
    """Ranges belong to each Param: a plugin's 'gain' without bounds gets the float default, not the range of
    the built-in plants' 'gain' (1e-9 .. 1e9)."""
    from contouring_ros.experiment.catalogue import PLANTS
    from contouring_ros.experiment.schema import DEFAULT_BOUNDS, Param, _value
    built_in = PLANTS["first_order_velocity"]["gain"].bounds
    assert built_in[1] < 1e10 <= DEFAULT_BOUNDS["float"][1]
    assert _value("plugin.yaml", "/x/plant.gain", Param("float"), 1e10) == 1e10
    with pytest.raises(ConfigError, match="expected a value from"):
        _value("file.yaml", "/x/plant.gain", PLANTS["first_order_velocity"]["gain"], 1e10)
