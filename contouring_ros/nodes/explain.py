"""What a node started by hand says about itself: its ``--help``, and why it cannot run with the experiment
file and namespace it was given (no file, a per-axis node outside every axis' namespace, an axis the file
does not have), naming the file's own sections instead of a missing key.

The node reads only the parameters ROS hands it (its own section and ``/**``); to say what the file holds it
reads the ``--params-file`` arguments of its own command line itself.
"""
from __future__ import annotations

import sys

from ..errors import ContouringError
from ..experiment.ros_yaml import read_yaml
from ..experiment.schema import GLOBAL_SECTION, ROS_PARAMETERS
from ..wire import catalogue

__all__ = ["wants_help", "help_text", "parameter_files", "explain"]


def _ros_arguments(argv) -> tuple:
    """(the arguments before ``--ros-args``, those after it up to ``--``)."""
    argv = list(argv or [])
    if "--ros-args" not in argv:
        return argv, []
    i = argv.index("--ros-args")
    rest = argv[i + 1:]
    return argv[:i], rest[:rest.index("--")] if "--" in rest else rest


def wants_help(argv) -> bool:
    """Whether the node's command line asks for help (``-h`` or ``--help`` before any ``--ros-args``)."""
    own, _ = _ros_arguments(argv)
    return any(arg in ("-h", "--help") for arg in own[1:])


def help_text(role: str) -> str:
    """What the ``role`` node is, what it takes and publishes, and how to start it by hand."""
    node = catalogue.NODE[role]
    name = catalogue.doc_name(node)
    inputs = ", ".join(dict.fromkeys("every topic of the graph" if i.topic == catalogue.EVERY_TOPIC else i.topic
                                     for i in node.inputs)) or "none"
    outputs = ", ".join(node.outputs) or ("the MCAP bag" if role == "recorder" else "none")
    namespace = " -r __ns:=/<axis>" if node.per_axis else ""
    extra = " -p bag:=run.mcap -p experiment_file:=EXPERIMENT.yaml" if role == "recorder" else ""
    lines = [
        f"{name}: the {role} node of a contouring_ros graph" + (" (one per axis)" if node.per_axis else ""),
        f"  takes:      {inputs}",
        f"  publishes:  {outputs}",
        "usage:",
        f"  ros2 run contouring_ros {node.console_script} --ros-args{namespace} --params-file EXPERIMENT.yaml{extra}",
        f"  ({node.pip_script} after a pip install; EXPERIMENT.yaml: an experiment file, its section "
        f"\"{name}\" and /** the node's parameters)",
    ]
    if node.per_axis:
        lines.append("  -r __ns:=/x runs it for axis x (/x/" + role + "), which must be one of the file's axes")
    lines.append("contouring-ros run EXPERIMENT.yaml starts the whole graph; see the README, \"With a ROS 2 Jazzy "
                 "install\"")
    return "\n".join(lines)


def parameter_files(argv) -> list:
    """The files given to ``--params-file`` on the node's command line, in order."""
    _, ros = _ros_arguments(argv)
    return [ros[i + 1] for i, arg in enumerate(ros[:-1]) if arg == "--params-file"]


def _sections(files) -> tuple:
    """(every section name of ``files``, the axes their /** names or None); nothing for a file it cannot
    read (the node's own error then stands)."""
    sections, axes = [], None
    for path in files:
        try:
            with open(path, encoding="utf-8") as stream:
                data = read_yaml(stream.read(1 << 20), str(path))
        except (OSError, UnicodeDecodeError, ContouringError):    # an unreadable file: say nothing of it
            continue
        if not isinstance(data, dict):
            continue
        sections += [str(key) for key in data if key not in sections]
        shared = data.get(GLOBAL_SECTION, {})
        given = shared.get(ROS_PARAMETERS, {}).get("axes") if isinstance(shared, dict) else None
        if isinstance(given, list):
            axes = [str(axis) for axis in given]
    return sections, axes


def explain(node_name: str, role: str, argv=None) -> str | None:
    """Why the node ``node_name`` (fully qualified) of ``role`` found no section or shared keys in what it was
    given, in the user's terms, or None where that is not why (the node's own error then stands)."""
    argv = sys.argv if argv is None else argv
    files = parameter_files(argv)
    node = catalogue.NODE[role]
    if not files:
        return (f"{node_name}: no experiment file: start it with --ros-args --params-file EXPERIMENT.yaml"
                + (" -r __ns:=/<axis>" if node.per_axis else "") + f" ({node.console_script} --help says more)")
    sections, axes = _sections(files)
    if not sections:
        return None
    if not node.per_axis:      # a section missing under a namespace: the validator's own hint says why
        return None
    ours = [s for s in sections if s.rstrip("/").endswith(f"/{role}") and s != node_name]
    parts = node_name.strip("/").split("/")
    axis = parts[-2] if len(parts) > 1 else None
    namespaces = [s.rsplit("/", 1)[0] for s in ours]
    if axis is None:
        where = " and ".join(ours) if ours else "no " + role + " section"
        return (f"{node_name}: a {role} serves one axis: this file has {where}: start it under one of those "
                f"namespaces (-r __ns:={namespaces[0] if namespaces else '/<axis>'})")
    if axes is not None and axis not in axes:
        return (f"{node_name}: {axis} is not an axis of this experiment (its axes: {', '.join(axes)}): start it "
                f"under one of " + ", ".join(namespaces or [f"/{a}" for a in axes]))
    return None
