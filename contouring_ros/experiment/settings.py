"""An experiment file's settings by grid key: ``<node section>.<key>[.<subkey>]`` for a node's parameter
(``ccc.kp``, ``x/servo.a``, ``contour_estimator.k_prime``) or ``<key>[.<subkey>]`` for a shared one
(``curve.h``, ``schedule.duration``), as sweeps (``--grid``), runs (``--set``) and comparisons of runs use them.
"""
from __future__ import annotations

import copy
from pathlib import Path

from ..errors import ConfigError
from .files import load_experiment, recorded_text
from .ros_yaml import read_yaml
from .schema import GLOBAL_SECTION, ROS_PARAMETERS
from .validate import experiment_from_data

__all__ = ["parse_grid", "grid_key_location", "apply_settings", "grid_keys", "differences", "settings_name",
           "name_settings", "settings_file", "written_settings"]


def parse_grid(specs: list) -> dict:
    """['ccc.kp=0.5,1,2', 'curve.h=50,100'] -> {'ccc.kp': [0.5, 1, 2], 'curve.h': [50, 100]}."""
    grid = {}
    for spec in specs:
        key, sep, values = spec.partition("=")
        if not sep or not key or not values:
            raise ConfigError(f"--grid {spec}: expected key=value1,value2,...")
        grid[key] = [read_yaml(value, f"--grid {key}") for value in values.split(",")]
    return grid


def grid_key_location(data: dict, key: str) -> tuple:
    """(the parameter mapping a grid key starts in, the key's path inside it): a node's section for
    ``<node>.<key>...`` when the file has that node, else the shared /** section."""
    section, _, rest = key.partition(".")
    node = f"/{section}"
    if node in data and rest:
        return data[node][ROS_PARAMETERS], rest.split(".")
    return data[GLOBAL_SECTION][ROS_PARAMETERS], key.split(".")


def _set(data: dict, key: str, value):
    target, path = grid_key_location(data, key)
    for part in path[:-1]:
        target = target.setdefault(part, {})
        if not isinstance(target, dict):
            raise ConfigError(f"--grid {key}: {part} is not a mapping")
    target[path[-1]] = value


def apply_settings(data: dict, settings: dict) -> dict:
    """Set each of ``settings`` in the experiment file's ``data`` (in place; returned). A key starting with
    '/' names a node section and replaces that node's whole parameter mapping (``{'/ccc': {'type': 'none'}}``);
    any other key is a grid key (see the module docstring)."""
    for key, value in settings.items():
        if key.startswith("/"):
            if not isinstance(value, dict):
                raise ConfigError(f"{key}: a node section needs a mapping of parameters, got {value!r}")
            data[key] = {ROS_PARAMETERS: copy.deepcopy(value)}
        else:
            _set(data, key, value)
    return data


def grid_keys(data: dict) -> dict:
    """Every leaf of an experiment file's ``data`` by its grid key (the inverse of :func:`apply_settings`):
    ``curve.h`` for a shared key, ``ccc.kp`` or ``x/servo.a`` for a node's; lists are leaves."""
    out = {}

    def walk(prefix, value):
        if isinstance(value, dict) and value:
            for key, inner in value.items():
                walk(f"{prefix}.{key}" if prefix else str(key), inner)
        else:
            out[prefix] = value
    for section, content in data.items():
        parameters = content.get(ROS_PARAMETERS, {}) if isinstance(content, dict) else {}
        walk("" if section == GLOBAL_SECTION else str(section).strip("/"), parameters)
    return out


def differences(datas: list) -> dict:
    """Grid key -> each file's value (None where a file lacks it) for every key whose value is not the same in
    all of ``datas`` (experiment files' data), in the first file's key order."""
    flat = [grid_keys(data) for data in datas]
    keys = list(dict.fromkeys(key for one in flat for key in one))
    return {key: [one.get(key) for one in flat] for key in keys if len({repr(one.get(key)) for one in flat}) > 1}


def settings_name(name: str, settings: dict) -> str:
    """An experiment's name with what ``settings`` change (grid key -> value) added, as run names, bags,
    legends and reports show it: ``paper000_b_ismc_h50_newton`` with ccc.kp = 2.0 is
    ``paper000_b_ismc_h50_newton_ccc.kp-2.0`` (letters, digits, '_', '-' and '.', as the name's check asks;
    cut at 100 characters, then with a digest of the settings so that different settings keep different names)."""
    import hashlib
    import re
    parts = [f"{key.strip('/').replace('/', '-')}-{value}" for key, value in settings.items()]
    text = re.sub(r"[^A-Za-z0-9_.-]+", "_", "_".join([name, *parts])).replace("..", ".")
    if len(text) > 100:
        digest = hashlib.sha256(repr(sorted(settings.items(), key=str)).encode()).hexdigest()[:8]
        text = f"{text[:90].rstrip('_.-')}_{digest}"
    return text


def name_settings(data: dict, settings: dict, base: str) -> dict:
    """``data`` (an experiment file's, settings applied) named after ``settings`` (:func:`settings_name` of
    its own name, else ``base``), unless the settings name it themselves (``experiment.name``)."""
    if not settings or "experiment.name" in settings:
        return data
    shared = data.setdefault(GLOBAL_SECTION, {}).setdefault(ROS_PARAMETERS, {})
    experiment = shared.get("experiment")
    if not isinstance(experiment, dict):
        experiment = shared["experiment"] = {}
    experiment["name"] = settings_name(str(experiment.get("name") or base), settings)
    return data


def settings_file(path, specs: list, directory) -> Path:
    """The experiment file ``path`` with ``specs`` (``['x/servo.kp=10', 'curve.h=80']``, the grid's key syntax,
    one value each) applied, written as ``directory``/<same name> for the nodes to read; validated like any
    experiment file, the ROS 2 parameter parser's reading included (ConfigError naming the setting)."""
    return written_settings(path, specs, directory)[0]


def written_settings(path, specs: list, directory) -> tuple:
    """(file, Experiment): the file :func:`settings_file` writes, and the Experiment its validation read from
    it (so that the caller does not read the file again). The experiment is named after the settings
    (:func:`name_settings`): its bag, legends and reports tell it from the file's own runs."""
    import yaml

    class _Quoted(yaml.SafeDumper):
        """Every string double-quoted: the ROS parser then reads 'y' or 'on' as the strings they are."""

    _Quoted.add_representer(str, lambda dumper, value: dumper.represent_scalar("tag:yaml.org,2002:str", value,
                                                                                 style='"'))
    path = Path(path)
    settings = {}
    for spec in specs:
        key, sep, value = spec.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise ConfigError(f"--set {spec}: expected key=value (keys as the sweep's: x/servo.kp, ccc.kp, curve.h)")
        settings[key.strip()] = read_yaml(value, f"--set {key}")
    data = read_yaml(recorded_text(path), str(path))
    try:
        name_settings(apply_settings(data, settings), settings, path.stem)
        experiment_from_data(copy.deepcopy(data), f"{path} with --set {', '.join(specs)}")
    except ConfigError as error:
        raise ConfigError(f"--set {', '.join(specs)}: {error}") from None
    out = Path(directory) / path.name
    out.write_text(yaml.dump(data, Dumper=_Quoted, sort_keys=False, default_flow_style=False))
    return out, load_experiment(out)      # what the ROS parser will read is what was validated
