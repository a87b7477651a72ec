"""Experiment files: reading and validating one, the text a bag keeps of it, and the file for nodes started
under a graph namespace."""
from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import yaml

from ..wire import graph
from ..errors import ConfigError
from .model import Experiment
from .ros_yaml import _read_file, read_yaml
from .schema import GLOBAL_SECTION, ROS_PARAMETERS, _printable
from .validate import experiment_from_data

__all__ = ["load_experiment", "recorded_text", "namespaced_parameter_file"]


def namespaced_parameter_file(text: str, namespace: str) -> str:
    """The experiment file ``text`` for nodes started under the graph ``namespace``: each node section's
    key gets the namespace in front (/x/plant: becomes "/m1/x/plant":, which the ROS parameter parser
    matches with the node's fully qualified name); the shared section /** and every value stay as
    written, byte for byte (only the keys' text is replaced, at the positions the YAML parser gives)."""
    if namespace in ("", "/"):
        return text
    root = yaml.compose(text, Loader=yaml.SafeLoader)
    if not isinstance(root, yaml.MappingNode):
        return text
    out = text
    for key, _ in sorted(root.value, key=lambda pair: pair[0].start_mark.index, reverse=True):
        if isinstance(key, yaml.ScalarNode) and key.value.startswith("/") and key.value != GLOBAL_SECTION:
            start, end = key.start_mark.index, key.end_mark.index
            out = out[:start] + f'"{graph.resolve(namespace, key.value)}"' + out[end:]
    return out


def load_experiment(path) -> Experiment:
    """Read and validate an experiment file: a regular file of at most MAX_FILE_BYTES of UTF-8 text without
    NUL, whose values the ROS 2 parameter parser reads as this validator does (the nodes read the same
    file). Every problem is a ConfigError of one line naming the file and the key."""
    path = Path(path)
    where = _printable(path)
    raw = _read_file(path, where)
    if not raw.strip():
        raise ConfigError(f"{where}: the file is empty")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ConfigError(f"{where}: not a text file (not UTF-8 at byte {error.start})") from None
    if "\x00" in text:
        raise ConfigError(f"{where}: not a text file (contains NUL bytes)")
    data = read_yaml(text, where, ros=True)
    experiment = experiment_from_data(data, where, text)
    if experiment.curve["type"] == "gcode":
        given = data[GLOBAL_SECTION][ROS_PARAMETERS]["curve"]["file"]
        experiment = replace(experiment, text=_program_path_in_text(text, given, experiment.curve["file"]))
    return experiment


def recorded_text(path) -> str:
    """The text a bag keeps of the experiment file ``path``: the file's own, with a part program's relative
    ``file`` made absolute (see :func:`load_experiment`)."""
    text = Path(path).read_text()
    try:
        experiment = load_experiment(path)
    except ConfigError:
        return text
    return experiment.text if experiment.curve["type"] == "gcode" else text


def _program_path_in_text(text: str, given: str, resolved: str) -> str:
    """The experiment's YAML with its part program's ``file`` made the absolute path it was resolved to, so
    the text stands alone where it is kept (bags, sweeps); unchanged where the value is absolute already or
    does not appear exactly once."""
    if given == resolved:
        return text
    pattern = re.compile(r"(\bfile:\s*)([\"']?)" + re.escape(given) + r"\2(?=\s*[,}\n]|\s*$)")
    if len(pattern.findall(text)) != 1:
        return text
    quoted = '"' + resolved.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return pattern.sub(lambda match: match.group(1) + quoted, text)
