"""The composed layout: every node of the graph as its own rclpy node, all in one process on one lean loop
(or under one SingleThreadedExecutor: the stock callback path of
:class:`~contouring_ros.nodes.node.LockstepNode`). The same loop over a subset of the nodes is one
process of the grouped layout (``--nodes``; the runner starts the other nodes elsewhere).

Same nodes, same topics, same step semantics as the process layout, hence the same bag payloads.
Usage (the runner does this):
python -m contouring_ros.run.composed EXPERIMENT.yaml BAG.mcap [lean|stock] [--start-time UNIX_TIME] [--nodes A,B]
(``--start-time``: tick 0 of a realtime run; ``--nodes``: only these nodes, one group of the grouped layout)
"""
from __future__ import annotations

import sys
import tempfile
import threading
import time
from pathlib import Path

from ..wire import graph
from ..experiment.files import load_experiment
from ..errors import ContouringError, RunError
from ..nodes.rclpy_adapter import SubscriptionWaitSet
from ..wire import catalogue
from ..nodes.process import interrupted_code, track_signals
from ..nodes.realtime import COMPOSED_LOOP, realtime_loop, wait_until
from ..nodes.recorder import REALTIME_GRACE
from .runner import group_label, override_arguments, shared_overrides, write_parameter_file

__all__ = ["main", "loop_order"]


#: realtime: the last part of each tick's wait is busy-waited, so tick k starts on time rather than a timed
#: wait's wake-up later (one thread does every node's work, so its lateness delays them all)
REALTIME_SPIN = 0.0003   # s
#: realtime: how soon the bag writer's thread hands the interpreter back to the tick loop (with Python's
#: default of 5 ms a tick that needs it while the writer runs can wait five ticks)
REALTIME_SWITCH_INTERVAL = 0.0001   # s

def _node_classes():
    """Node concern -> its class, as wire.catalogue names them."""
    return {node.name: catalogue.load_class(node) for node in catalogue.NODES}


def loop_order(axes, names=None) -> list:
    """The nodes one composed loop creates and steps, in this order: ``names`` (the graph's own full names;
    default every node: the composed layout) in graph order (:func:`graph.node_names`), recorder last."""
    every = graph.node_names(axes)
    return every if names is None else [n for n in every if n in set(names)]


def _wait_set(nodes) -> SubscriptionWaitSet:
    """One persistent wait set over every subscription of ``nodes``."""
    return SubscriptionWaitSet([sub for node in nodes for sub in node.subscriptions()], nodes[0].node.context)


def _lean_spin_once(nodes, wait_set, timeout_ns: int):
    """One turn of the lean loop over every node's subscriptions: wait, take, dispatch."""
    wait_set.wait(timeout_ns)
    for node in nodes:
        node.take_all(node.admitted)


def run_composed(experiment_path: str, bag: str, executor_kind: str = "lean", start_time: float = 0.0,
                 names=None, namespace: str = "/"):
    """Create the nodes ``names`` (the graph's own full names, e.g. /x/plant; default every node of the
    graph: the composed layout) in this process under the graph ``namespace``, run the lockstep to the
    end, close the bag if the recorder is one of them.

    ``executor_kind`` ``lean`` waits on one wait set holding every node's subscriptions and dispatches
    serialised messages directly; ``stock`` spins rclpy's SingleThreadedExecutor over the same nodes'
    subscription callbacks (the path for users who embed the nodes in their own executor). A subset of the
    graph is one group of the grouped layout: the other nodes run in other processes (the runner starts
    them), and the same loop serves it.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    experiment = load_experiment(experiment_path)
    names = loop_order(experiment.axes, names)
    label = COMPOSED_LOOP if names == graph.node_names(experiment.axes) else f"the group {group_label(names)}"
    namespace = graph.normalize_namespace(namespace)
    directory = tempfile.TemporaryDirectory(prefix="contouring_ros_")
    parameter_file = write_parameter_file(Path(experiment_path), namespace, directory.name)
    arguments = ["--ros-args", "--params-file", str(parameter_file)] + override_arguments(shared_overrides(experiment))
    if start_time:
        arguments += ["-p", f"start_time:={start_time!r}"]
    rclpy.init(args=arguments)
    classes, nodes = _node_classes(), []
    executor = SingleThreadedExecutor()
    try:
        specs = {spec.full_name: spec for spec in graph.node_specs(experiment.axes, None, str(bag),
                                                                   str(experiment_path), namespace)}
        for name in names:
            spec = specs[graph.resolve(namespace, name)]
            overrides = [Parameter(key, value=value) for key, value in spec.overrides]
            node = classes[spec.name](name=spec.name, namespace=spec.namespace, parameter_overrides=overrides,
                                      callbacks=True)
            nodes.append(node)
            executor.add_node(node.node)
        recorder = nodes[-1] if nodes[-1].role == "recorder" else None
        for node in nodes:
            node.wait_for_graph()
        for node in nodes:
            node.start()
        spin_once = _spin_once(nodes, executor, executor_kind == "lean" or experiment.timing == "realtime")
        if experiment.timing == "realtime":
            _run_realtime(nodes, label)
        _run_to_end(nodes, spin_once, executor_kind == "lean", label, experiment.stall_timeout)
        _finish(nodes, recorder, spin_once)
    finally:
        for node in reversed(nodes):      # the recorder first: its bag is closed whatever comes after
            try:
                node.destroy()
            except Exception:             # a node whose context a signal shut down
                if rclpy.ok():
                    raise
        rclpy.try_shutdown()
        directory.cleanup()


def _spin_once(nodes, executor, lean: bool):
    """``spin_once(timeout_sec)`` of the loop: one turn of the lean loop over one wait set of every node's
    subscriptions (``lean``), else the stock ``executor``'s."""
    if not lean:
        return executor.spin_once
    wait_set = _wait_set(nodes)

    def spin_once(timeout_sec):
        _lean_spin_once(nodes, wait_set, int(timeout_sec * 1e9))
    return spin_once


def _run_to_end(nodes, spin_once, lean: bool, label: str, stall_timeout: float):
    """Spin until every node has finished its steps (``lean``: each node then serves its requests); raise
    RunError naming the nodes still waiting, and for what, once nothing has moved for ``stall_timeout`` s."""
    last, last_progress = -1, time.monotonic()
    while not all(node.finished for node in nodes):
        spin_once(timeout_sec=0.2)
        if lean:
            for node in nodes:
                node.serve_requests()
        # the steps of every node, and the messages the last node (the recorder, where one of them) has taken
        progress = sum(node.next_step for node in nodes) + sum(getattr(nodes[-1], "counts", {}).values())
        if progress != last:
            last, last_progress = progress, time.monotonic()
        elif time.monotonic() - last_progress > stall_timeout:
            stuck = [node for node in nodes if not node.finished]
            raise RunError(f"{label} stalled for {stall_timeout:g} s: "
                           + "; ".join(f"{n.name} at step {n.next_step}, no message on "
                                       f"{', '.join(n.missing_inputs())}" for n in stuck if n.missing_inputs()))


def _finish(nodes, recorder, spin_once):
    """Finish every node, the ``recorder`` (None: not one of them) last, once it has taken the end-of-run
    diagnostics."""
    for node in nodes:
        if node is not recorder:
            node.finish()
    if recorder is not None:
        deadline = time.monotonic() + 0.3        # let the recorder take the end-of-run diagnostics
        while time.monotonic() < deadline:
            spin_once(timeout_sec=0.02)
        recorder.finish()


def _run_realtime(nodes, label: str):
    """The nodes' realtime ticks in one loop (:func:`~contouring_ros.nodes.realtime.realtime_loop`): wait for
    tick k on all subscriptions, then tick each node in graph order (interpolator, plants, estimator, CCC,
    servos); the recorder, if one of them, takes what arrives after each tick."""
    import rclpy
    lockstep_nodes = [node for node in nodes if node.role != "recorder"]
    recorder = nodes[-1] if nodes[-1].role == "recorder" else None
    for node in lockstep_nodes:
        node.realtime_setup()
    wait_set = _wait_set(nodes)
    context = nodes[0].node.context
    record = (lambda: recorder.take_all(recorder.admitted)) if recorder is not None else None

    def take():
        for node in lockstep_nodes:
            node.take_all(node.keep_newest)
        if record is not None:
            record()

    switch_interval = sys.getswitchinterval()
    sys.setswitchinterval(REALTIME_SWITCH_INTERVAL)
    # the bag writer's thread writes while the loop waits for its next tick, never while it ticks
    idle = threading.Event() if recorder is not None else None
    if recorder is not None:
        recorder.writer.write_only_while(idle)
    try:
        if lockstep_nodes:
            realtime_loop(lockstep_nodes, label, wait_set, take, spin=REALTIME_SPIN, after_tick=record,
                          idle=idle)
    finally:
        sys.setswitchinterval(switch_interval)
        if recorder is not None:
            recorder.writer.write_only_while(None)
    if recorder is None:
        return
    experiment = recorder.experiment
    end = max(time.time() + 1.0, experiment.start_time + experiment.n_steps * experiment.sample_time
              + REALTIME_GRACE)
    while not recorder.complete() and time.time() < end and rclpy.ok(context=context):
        wait_until(time.time() + 0.01, wait_set, take, context)
    recorder.finished = True


def main(argv=None) -> int:
    import argparse
    parser = argparse.ArgumentParser(prog="python -m contouring_ros.run.composed")
    parser.add_argument("experiment")
    parser.add_argument("bag")
    parser.add_argument("executor", nargs="?", default="lean", choices=["lean", "stock"])
    parser.add_argument("--start-time", type=float, default=0.0, help="Unix time of tick 0 (realtime runs)")
    parser.add_argument("--nodes", help="comma-separated full node names: run only these (one group of the "
                        "grouped layout; default every node)")
    parser.add_argument("--namespace", default="/", help="the graph's namespace (default: the root)")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    received = track_signals()
    try:
        run_composed(args.experiment, args.bag, args.executor, args.start_time,
                     args.nodes.split(",") if args.nodes else None, args.namespace)
    except BaseException as error:     # 130 (SIGINT) or 143 (SIGTERM) in any state, one line for an error
        code = interrupted_code(error, received)
        if code is None and isinstance(error, ContouringError):
            print(f"error: {error}", file=sys.stderr)
            return 1
        if code is None:
            raise
        return code
    return 0


if __name__ == "__main__":
    sys.exit(main())
