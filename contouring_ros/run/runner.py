"""Run an experiment through the node graph: every node its own process, on a private ROS domain.

The runner validates the experiment before any node starts, starts the recorder and every node with the
experiment file as their ``--params-file``, watches them, and stops all of them as soon as one fails
(naming it). Discovery stays on localhost.
"""
from __future__ import annotations

import fcntl
import os
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from ..wire import graph
from ..wire.graph import parse_groups
from ..experiment.build import reference_preview
from ..experiment.files import load_experiment, namespaced_parameter_file
from ..experiment.model import Experiment
from ..experiment.validate import controller_uses_state, split_groups
from ..errors import Interrupted, RunError
from .interruptions import Terminated, note_interruptions, raise_pending_termination, restore_signals
from .shared_memory import clean_shared_memory

__all__ = ["NodeProcess", "DomainLease", "graph_commands", "grouped_commands", "parse_groups", "write_parameter_file",
           "private_environment", "run_graph", "default_bag_path"]

FASTDDS_PROFILE = Path(__file__).resolve().parent / "fastdds_profile.xml"
SHUTDOWN_GRACE = 10.0
REALTIME_START_DELAY = 5.0   # s from launch to tick 0 of a realtime run: every node is up and matched by then
OFF_CRITICAL_PATH = {"/recorder"}
OFF_CRITICAL_PATH_NICENESS = 5   # s the nodes get to exit on their own once the recorder has the whole run


@dataclass
class NodeProcess:
    name: str
    command: list
    process: subprocess.Popen | None = None
    log: object = None

    def lower_priority(self):
        """Run off-critical-path nodes (the recorder) at a lower CPU priority: the lockstep nodes then
        get the cores first, and the recorder catches up in between (keep-all QoS holds what it has
        not taken yet, so nothing is lost)."""
        if self.name in OFF_CRITICAL_PATH:
            os.nice(OFF_CRITICAL_PATH_NICENESS)

    def preexec(self, runner_pid: int):
        """In the child before exec: die with the runner (SIGTERM when the runner's thread that started us
        ends, even by SIGKILL: the nodes then stop as on Ctrl-C and the recorder closes the bag), then
        :meth:`lower_priority`."""
        if _LIBC is not None:
            _LIBC.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
            if os.getppid() != runner_pid:     # the runner died before prctl took effect
                os.kill(os.getpid(), signal.SIGTERM)
        self.lower_priority()

    def last_error_line(self) -> str:
        if self.log is None:
            return ""
        self.log.seek(0)
        lines = [line.strip() for line in self.log.read().decode(errors="replace").splitlines() if line.strip()]
        errors = [line for line in lines if line.startswith("error:")]
        return (errors or lines or [""])[-1]

    def exited_early(self) -> bool:
        """Exited 0 without saying it completed its steps (every node logs "completed N steps" as it
        finishes): a node that left the run mid-way (os._exit(0) in a plugin, say)."""
        if self.log is None or self.process is None or self.process.poll() != 0:
            return False
        self.log.seek(0)
        return b"completed " not in self.log.read()


def default_bag_path(experiment: Experiment, directory="bags") -> Path:
    """``directory``/<experiment name>_<time>.mcap, always a file directly inside ``directory``: the name
    (validated in the file, but the file's stem where it gives none) keeps only letters, digits, '_', '-'
    and '.', at most 100 characters, and never starts with a dot."""
    import re
    stamp = datetime.now().strftime("%Y%m%d_%H%M%S_%f")
    name = re.sub(r"[^A-Za-z0-9_.-]", "_", str(experiment.name))[:100].lstrip(".") or "experiment"
    path = Path(directory) / f"{name}_{stamp}.mcap"
    if path.resolve().parent != Path(directory).resolve():
        raise RunError(f"the bag name {name!r} would leave the bag folder {directory}")
    return path


def private_environment(domain_id: int, network: bool = False) -> dict:
    """The environment for one run's nodes: its own ROS domain and the package's Fast DDS profile (unless
    FASTRTPS_DEFAULT_PROFILES_FILE is set already).

    By default the profile ``fastdds_profile.xml`` keeps every socket on loopback (shared memory and UDPv4
    on 127.0.0.1 only, discovery by unicast to 127.0.0.1), and ROS_AUTOMATIC_DISCOVERY_RANGE is
    SYSTEM_DEFAULT so that rmw_fastrtps leaves the profile's transports alone (its LOCALHOST range adds a
    UDPv4 transport bound to 0.0.0.0 and every interface). A profile of the user's own gets the LOCALHOST
    range instead (discovery on this machine, as far as rmw_fastrtps restricts it). An experiment with
    ``network: true`` gets ``fastdds_profile_network.xml`` (Fast DDS' built-in transports on every
    interface) and the SUBNET range: its nodes can then be reached from the network, protected only by
    the domain id (see the README). The nodes run the pure Python path of the Newton estimate
    (CONTOURING_ROS_NUMBA=0 unless the user's environment sets it, :mod:`contouring_ros.core.kernels`):
    the same numbers, without seconds of numba's import and compilation as a node starts, for a step that
    message passing dominates anyway."""
    env = dict(os.environ)
    env.setdefault("CONTOURING_ROS_NUMBA", "0")
    env["ROS_DOMAIN_ID"] = str(domain_id)
    own_profile = bool(env.get("FASTRTPS_DEFAULT_PROFILES_FILE"))
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET" if network else "LOCALHOST" if own_profile else "SYSTEM_DEFAULT"
    env.pop("ROS_STATIC_PEERS", None)
    env.pop("ROS_LOCALHOST_ONLY", None)
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    if not own_profile:
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(
            FASTDDS_PROFILE.with_name("fastdds_profile_network.xml") if network else FASTDDS_PROFILE)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def shared_overrides(experiment: Experiment) -> dict:
    """Shared keys the runner sets for every node from the whole experiment: ``ccc_takes_state`` false where
    the controller does not use the reference and states (the CCC then does not subscribe to them);
    ``reference_preview``, the steps of reference ahead the servos read (the interpolator publishes them); a part
    program's ``curve.file`` as the absolute path the experiment resolved (a node reads its parameters, not
    the experiment file's location)."""
    out = {} if controller_uses_state(experiment) else {"ccc_takes_state": False}
    preview = reference_preview(experiment)
    if preview != experiment.reference_preview:
        out["reference_preview"] = preview
    if experiment.curve["type"] == "gcode":
        out["curve.file"] = experiment.curve["file"]
    return out


def override_arguments(overrides) -> list:
    """ROS command-line arguments (-p name:=value) setting each (name, value) of ``overrides``."""
    out = []
    for name, value in dict(overrides).items():
        text = ("true" if value else "false") if isinstance(value, bool) else \
            repr(value) if isinstance(value, float) else str(value)
        out += ["-p", f"{name}:={text}"]
    return out


def graph_commands(experiment_path, experiment: Experiment, bag: Path, start_time: float = 0.0,
                   namespace: str = "/", parameter_file=None) -> list:
    """One NodeProcess per node of the graph (recorder first, see :func:`graph.node_specs`), each a
    `python -m` of its node module under the graph ``namespace``; realtime runs also get the shared
    ``start_time`` of tick 0. The nodes read ``parameter_file`` (default: the experiment file; under a
    namespace, :func:`namespaced_parameter_file`'s copy of it); the recorder stores the experiment file."""
    shared = shared_overrides(experiment)
    if start_time:
        shared = {"start_time": start_time, **shared}
    out = []
    for spec in graph.node_specs(experiment.axes, shared, str(bag), str(experiment_path), namespace):
        command = [sys.executable, "-m", spec.module, "--ros-args",
                   "-r", f"__ns:={spec.namespace}", "-r", f"__node:={spec.name}", "--params-file",
                   str(parameter_file or experiment_path)]
        command += override_arguments(spec.overrides)
        out.append(NodeProcess(spec.full_name, command))
    return out


def write_parameter_file(experiment_path: Path, namespace: str, directory) -> Path:
    """The parameter file the nodes of a graph under ``namespace`` read: the experiment file itself at the
    root, else its copy with the namespace before each node section (in ``directory``)."""
    if namespace in ("", "/"):
        return experiment_path
    path = Path(directory) / experiment_path.name
    path.write_text(namespaced_parameter_file(experiment_path.read_text(), namespace))
    return path


def _load_libc():
    import ctypes
    try:
        return ctypes.CDLL(None, use_errno=True) if sys.platform.startswith("linux") else None
    except OSError:
        return None


_LIBC = _load_libc()      # loaded before any fork: the child's preexec only calls prctl
_PR_SET_PDEATHSIG = 1


def _stop(nodes, grace: float = 5.0):
    """SIGINT every node still running, then SIGKILL whatever is left after ``grace`` seconds, or at once
    when another SIGINT or SIGTERM reaches the runner meanwhile (a second Ctrl-C escalates, never skips)."""
    escalate, previous = [], {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, lambda *_: escalate.append(True))
    try:
        running = [node.process for node in nodes if node.process is not None and node.process.poll() is None]
        for process in running:
            process.send_signal(signal.SIGINT)
        deadline = time.monotonic() + grace
        while not escalate and time.monotonic() < deadline and any(p.poll() is None for p in running):
            time.sleep(0.02)
        for node in nodes:
            if node.process is not None and node.process.poll() is None:
                node.process.kill()
        for node in nodes:
            if node.process is not None:
                node.process.wait()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _exit_description(code: int) -> str:
    if code < 0:
        try:
            return f"was killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"was killed by signal {-code}"
    return f"exited with code {code}"


class DomainLease:
    """A ROS domain id held for one run: an exclusive lock file per id, so that concurrent runs on this
    machine never share a domain (and so never hear each other)."""

    DIRECTORY = Path(tempfile.gettempdir()) / "contouring_ros_domains"
    IDS = range(1, 101)   # Fast DDS port arithmetic allows up to 232; 100 concurrent runs are plenty

    def __init__(self, domain_id: int | None = None, shared: bool = False):
        """Hold ``domain_id`` (default: a free one, exclusively). ``shared``: hold the given id together
        with other shared holders (graphs under different namespaces in one domain), never with a run that
        holds it exclusively."""
        self.DIRECTORY.mkdir(parents=True, exist_ok=True)
        candidates = [domain_id] if domain_id is not None else random.SystemRandom().sample(list(self.IDS),
                                                                                              len(self.IDS))
        self._file = None
        for candidate in candidates:
            handle = open(self.DIRECTORY / f"{candidate}.lock", "w")
            try:
                fcntl.flock(handle, (fcntl.LOCK_SH if shared and domain_id is not None else fcntl.LOCK_EX)
                            | fcntl.LOCK_NB)
            except OSError:
                handle.close()
                continue
            self.domain_id, self._file = candidate, handle
            return
        if domain_id is not None:
            raise RunError(f"ROS domain {domain_id} is held by another run of this machine "
                           f"({'exclusively' if shared else 'already'}; lock files in {self.DIRECTORY})")
        raise RunError(f"no free ROS domain id among {list(candidates)[:5]}... (lock files in {self.DIRECTORY})")

    def lock_fds(self) -> tuple:
        """The lock file's descriptor, for child processes to inherit (and so hold the lock as long as
        they live: flock belongs to the open file, shared by every process holding it)."""
        return (self._file.fileno(),) if self._file is not None else ()

    def release(self):
        if self._file is not None:
            self._file.close()      # closing drops the lock
            self._file = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()


def _composed_process(label: str, experiment_path, bag: Path, start_time: float, namespace: str,
                      nodes=None) -> NodeProcess:
    """A process of :mod:`contouring_ros.run.composed`: every node of the graph, or the ``nodes`` of one group."""
    return NodeProcess(label, [sys.executable, "-m", "contouring_ros.run.composed", str(experiment_path), str(bag)]
                       + (["--nodes", ",".join(nodes)] if nodes else [])
                       + (["--start-time", repr(start_time)] if start_time else [])
                       + (["--namespace", namespace] if namespace not in ("", "/") else []))


def composed_command(experiment_path, bag: Path, start_time: float = 0.0, namespace: str = "/") -> list:
    """The composed layout: one process running every node under one executor."""
    return [_composed_process("/composed", experiment_path, bag, start_time, namespace)]


def group_label(names) -> str:
    """How a group's process is named: its nodes' full names joined by commas."""
    return ",".join(names)


def grouped_commands(experiment_path, experiment: Experiment, bag: Path, groups, start_time: float = 0.0,
                     namespace: str = "/", parameter_file=None) -> list:
    """The grouped layout: one process per group of two or more nodes (the composed loop over that subset,
    ``python -m contouring_ros.run.composed --nodes``), and every node in no such group in its own process as
    in the process layout, all under the graph ``namespace``. ``groups`` as :func:`parse_groups` returns
    them (the graph's own names)."""
    shared = [group for group in groups if len(group) > 1]
    grouped = {graph.resolve(namespace, name) for group in shared for name in group}
    out = [node for node in graph_commands(experiment_path, experiment, bag, start_time, namespace, parameter_file)
           if node.name not in grouped]
    out += [_composed_process(group_label(group), experiment_path, bag, start_time, namespace, group)
            for group in shared]
    return out


def _bag_destination(bag, experiment: Experiment) -> tuple:
    """(where the run's bag ends, where the recorder writes it meanwhile): ``bag``, or :func:`default_bag_path`,
    its folder made (RunError in one line where it is a folder or cannot be written), and its
    :func:`recording_path`. The recorder writes beside the bag's name and the bag is moved into place as the
    run ends: a file already there stays whole until then (and, if the run never opens its bag, after it)."""
    final = Path(bag) if bag is not None else default_bag_path(experiment)
    if final.is_dir():
        raise RunError(f"the bag {final} is a folder: name a file")
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise RunError(f"the bag {final} cannot be written ({error.strerror or type(error).__name__})") from None
    return final, recording_path(final)


def _namespace(namespace: str) -> str:
    """The graph namespace normalised (:func:`graph.normalize_namespace`); RunError in one line for a bad one."""
    try:
        return graph.normalize_namespace(namespace)
    except ValueError as error:
        raise RunError(str(error)) from None


def _layout(experiment: Experiment, layout: str | None, groups) -> tuple:
    """(layout, groups) of a run: those given, else the experiment file's (``layout``, ``groups``)."""
    if layout is None and not groups:        # the experiment file's layout
        groups = split_groups(experiment.groups) if experiment.layout == "grouped" else None
        layout = "composed" if experiment.layout == "composed" else "process"
    layout = layout or "process"
    if layout not in ("process", "composed"):
        raise RunError(f"unknown layout {layout!r} (expected process or composed)")
    if groups and layout != "process":
        raise RunError("groups are a layout of their own: give them with layout process (the default)")
    return layout, groups


def _layout_commands(experiment_path: Path, experiment: Experiment, bag: Path, layout: str, groups,
                     start_time: float, namespace: str, parameter_file) -> list:
    """The NodeProcesses of the layout: :func:`grouped_commands`, :func:`graph_commands` or
    :func:`composed_command`."""
    if groups:
        return grouped_commands(experiment_path, experiment, bag, parse_groups(groups, experiment.axes), start_time,
                                namespace, parameter_file)
    if layout == "process":
        return graph_commands(experiment_path, experiment, bag, start_time, namespace, parameter_file)
    return composed_command(experiment_path, bag, start_time, namespace)


def _environment(lease: DomainLease, experiment: Experiment, directory) -> tuple:
    """(the nodes' environment on the ``lease``'s domain, the file in ``directory`` the recorder writes its
    progress to, empty)."""
    env = private_environment(lease.domain_id, network=experiment.network)
    progress_file = Path(directory) / "progress"
    progress_file.write_bytes(b"")
    env[graph.PROGRESS_ENV] = str(progress_file)
    return env, progress_file


def _starting_message(experiment: Experiment, nodes: list, namespace: str, domain_id: int, shared: bool) -> str:
    """``starting N nodes [in ... processes] [under NAMESPACE] on ROS domain D [(shared)]: S steps``."""
    count = len(graph.node_names(experiment.axes))
    processes = "" if len(nodes) == count else " in one process" if len(nodes) == 1 else f" in {len(nodes)} processes"
    under = f" under {namespace}" if namespace != "/" else ""
    return (f"starting {count} nodes{processes}{under} on ROS domain {domain_id}"
            + (" (shared)" if shared else "") + f": {experiment.n_steps} steps")


def _start(nodes: list, env: dict, lease: DomainLease) -> None:
    """Start every node's process with ``env``, its output in a temporary log; a SIGINT or SIGTERM noted
    meanwhile raises Terminated after the node it came during."""
    runner_pid = os.getpid()
    for node in nodes:
        node.log = tempfile.TemporaryFile()
        # every node holds the domain's lock file open too: the lock is released once the
        # runner and every node have exited, never while a node of this run still runs
        node.process = subprocess.Popen(node.command, env=env, stdout=node.log,
                                        stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                        pass_fds=lease.lock_fds(),
                                        preexec_fn=lambda node=node: node.preexec(runner_pid))
        raise_pending_termination()


def _interrupted(interrupt: BaseException, nodes: list, bag: Path, final: Path) -> Interrupted:
    """Stop every node after a SIGINT or SIGTERM (``interrupt``) and say what of the bag exists."""
    terminated = getattr(interrupt, "signum", signal.SIGINT) == signal.SIGTERM
    _stop(nodes)          # every node gone (the recorder has closed the bag) before we say what exists
    what = "SIGTERM" if terminated else "SIGINT"
    if bag.is_file() and bag.stat().st_size > 0:
        state = f"the bag {final} holds the steps recorded so far"
    else:
        state = f"no bag yet (the recorder had not opened {final})"
    return Interrupted(f"interrupted by {what}: stopped every node; {state}",
                       bag=final if bag.is_file() else None, code=143 if terminated else 130)


def _interrupted_at_end(signum: int, final: Path) -> Interrupted:
    """A SIGINT or SIGTERM (``signum``) noted after the last poll of the nodes, every node gone: the bag
    ``final`` holds the whole run."""
    return Interrupted(f"interrupted by {signal.Signals(signum).name} as the run ended: every node had "
                       f"exited; the bag {final} holds the whole run", bag=final,
                       code=143 if signum == signal.SIGTERM else 130)


def _stop_and_close(nodes: list, wall_started: float) -> None:
    """Stop every node, close the logs, and remove the shared memory a killed node left (created since
    ``wall_started``, a time.time())."""
    _stop(nodes)
    for node in nodes:
        if node.log is not None:
            node.log.close()
    if any(node.process is not None and (node.process.returncode or 0) < 0 for node in nodes):
        clean_shared_memory(wall_started - 1.0)


def run_graph(experiment_path, bag=None, *, timeout: float | None = None, domain_id: int | None = None,
              progress=None, on_started=None, layout: str | None = None, groups=None, namespace: str = "/",
              shared_domain: bool = False, experiment: Experiment | None = None, on_step=None) -> Path:
    """Run the experiment through the process graph and return the bag's path.

    On any failure (a node dying, a stall, a timeout, SIGINT or SIGTERM) every node is stopped, the
    recorder closes the bag with its summary where it still can, and a RunError names the cause; its
    ``bag`` attribute is the (partial) bag.

    Parameters
    ----------
    experiment_path : path-like
    bag : path-like, optional
        Where to write the bag (default: bags/<experiment>_<time>.mcap).
    timeout : float, optional
        Wall-clock limit in seconds (default: generous for the run's length).
    domain_id : int, optional
        ROS domain (default: a free one, held exclusively for the run).
    shared_domain : bool
        With ``domain_id``: share that domain with other runs that share it (each under its own
        ``namespace``) and with whatever else listens there (ROS tools), instead of holding it alone.
    progress : callable(str), optional
        Receives one-line status messages.
    on_step : callable(int), optional
        Called 20 times a second while the nodes run with the steps the recorder has recorded in full (0
        until the graph is up), for a progress bar: :class:`contouring_ros.notices.progress_of`.
    on_started : callable(list of NodeProcess), optional
        Called once every node process has been started.
    layout : str, optional
        ``process`` (every node its own process) or ``composed`` (all nodes in one process); default (with no
        ``groups``): the experiment's ``layout`` and ``groups`` keys.
    groups : list, optional
        The grouped layout (with ``layout`` ``process`` or None): each group, a list of node names or a string
        ``x/plant,x/servo``, runs in one process on the composed loop; every other node in its own process.
    namespace : str
        Graph namespace: every node and topic under it (``m1``: /m1/x/plant publishes /m1/x/state).
    experiment : Experiment, optional
        The file's Experiment where the caller has validated it already (:func:`contouring_ros.experiment.files.load_experiment`):
        not read again; default: read and validated here.
    """
    experiment_path = Path(experiment_path)
    if experiment is None:
        experiment = load_experiment(experiment_path)
    final, bag = _bag_destination(bag, experiment)
    timeout = timeout if timeout is not None else 60.0 + experiment.n_steps / 50.0
    layout, groups = _layout(experiment, layout, groups)
    namespace = _namespace(namespace)
    start_time = time.time() + REALTIME_START_DELAY if experiment.timing == "realtime" else 0.0
    parameter_directory = tempfile.TemporaryDirectory(prefix="contouring_ros_")
    parameter_file = write_parameter_file(experiment_path.resolve(), namespace, parameter_directory.name)
    nodes = _layout_commands(experiment_path.resolve(), experiment, bag.resolve(), layout, groups, start_time,
                             namespace, parameter_file)
    say = progress or (lambda message: None)
    replaced_handlers = note_interruptions() if threading.current_thread() is threading.main_thread() else {}
    started, wall_started = time.monotonic(), time.time()
    try:
        with DomainLease(domain_id, shared=shared_domain) as lease:
            env, progress_file = _environment(lease, experiment, parameter_directory.name)
            say(_starting_message(experiment, nodes, namespace, lease.domain_id, shared_domain))
            try:
                _start(nodes, env, lease)
                if on_started is not None:
                    on_started(nodes)
                _watch(nodes, timeout, started, say,
                       (lambda: on_step(graph.read_progress(progress_file) or 0)) if on_step else None)
            except (KeyboardInterrupt, Terminated) as interrupt:
                raise _interrupted(interrupt, nodes, bag, final) from None
            except RunError as error:
                _stop(nodes)      # the recorder closed (or killed) before we say whether a bag exists
                raise RunError(str(error), bag=final if bag.is_file() else None) from None
            finally:
                _stop_and_close(nodes, wall_started)
    finally:
        _move_into_place(bag, final)
        parameter_directory.cleanup()
        late = restore_signals(replaced_handlers)
    if late:        # it landed after the last poll: the run is whole, and the signal is still answered
        raise _interrupted_at_end(late[0], final)
    say(f"ran {experiment.n_steps} steps in {time.monotonic() - started:.1f} s wall time")
    return final


def recording_path(bag) -> Path:
    """Where the recorder writes the bag ``bag`` while the run lasts: ``.<name>.recording`` beside it."""
    bag = Path(bag)
    return bag.with_name(f".{bag.name}.recording")


def _move_into_place(recording: Path, final: Path) -> None:
    """The recorder's file, written beside the bag's name, moved onto it (whole or partial: the run's bag);
    nothing there is touched when the recorder never opened its file."""
    if recording.is_file():
        try:
            os.replace(recording, final)
        except OSError as error:
            raise RunError(f"the bag {final} cannot be written ({error.strerror or type(error).__name__}); the run "
                           f"is kept in {recording}") from None


def _watch(nodes, timeout, started, say, poll_progress=None):
    """Poll the node processes until the run completes (and ``poll_progress()`` at each poll); raise RunError
    naming the cause of a failure."""
    recorder_done = None
    while True:
        raise_pending_termination()
        if poll_progress is not None:
            poll_progress()
        codes = {node.name: node.process.poll() for node in nodes}
        early = [node for node in nodes if codes[node.name] == 0 and node.exited_early()]
        if early:           # the others would stall for want of its messages: name it, not them
            time.sleep(0.2)
            raise RunError("; ".join(f"node {node.name} exited with code 0 before completing its steps (its last "
                                     f"line: {node.last_error_line() or 'none'})" for node in early))
        if any(code not in (None, 0) for code in codes.values()):
            first = {name for name, code in codes.items() if code not in (None, 0)}
            time.sleep(0.2)     # let the other nodes report too, then name the root cause first: a node
            # that failed first, before one that failed meanwhile (perhaps for want of the first), and a
            # stall (the consequence of another node's failure) last
            failed = [node for node in nodes if node.process.poll() not in (None, 0)]
            failed.sort(key=lambda node: (node.name not in first, "stalled" in node.last_error_line()))
            reasons = []
            for node in failed:
                detail = node.last_error_line()
                reasons.append(f"node {node.name} {_exit_description(node.process.poll())}"
                               + (f": {detail}" if detail and node.process.poll() > 0 else ""))
            if (codes.get("/recorder") or 0) < 0:
                reasons.append("the recorder could not close the bag: it has no summary and is readable up to "
                               "its last complete chunk")
            raise RunError("; ".join(reasons))
        if all(code == 0 for code in codes.values()):
            return
        if codes.get("/recorder") == 0:
            # The bag is complete; a node still shutting down after its last step is stopped by the caller.
            recorder_done = recorder_done or time.monotonic()
            if time.monotonic() - recorder_done > SHUTDOWN_GRACE:
                lingering = [name for name, code in codes.items() if code is None]
                say(f"stopping {', '.join(lingering)}: still running {SHUTDOWN_GRACE:.0f} s after the bag "
                    "was complete")
                return
        if time.monotonic() - started > timeout:
            running = [node for node in nodes if codes[node.name] is None]
            raise RunError(f"the run did not finish within {timeout:.0f} s (still running: "
                           + ", ".join(f"{node.name}, its last line: {node.last_error_line() or 'none'}"
                                       for node in running) + ")")
        time.sleep(0.05)
