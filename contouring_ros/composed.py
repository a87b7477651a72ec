"""The composed layout: every node of the graph as its own rclpy node, all in one process under one
SingleThreadedExecutor (the stock callback path of :class:`~contouring_ros.nodes.lockstep.LockstepNode`).

Same nodes, same topics, same step semantics as the process layout, hence the same bag payloads.
Usage (the runner does this):
python -m contouring_ros.composed EXPERIMENT.yaml BAG.mcap [lean|stock] [--start-time UNIX_TIME]
(``--start-time``: tick 0 of a realtime run)
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from . import graph
from .config import load_experiment
from .errors import ContouringError, RunError
from .runner import override_arguments, shared_overrides, write_parameter_file

__all__ = ["main"]


#: realtime: the last part of each tick's wait is busy-waited, so tick k starts on time rather than a timed
#: wait's wake-up later (one thread does every node's work, so its lateness delays them all)
REALTIME_SPIN = 0.0003   # s
#: realtime: how soon the bag writer's thread hands the interpreter back to the tick loop (with Python's
#: default of 5 ms a tick that needs it while the writer runs can wait five ticks)
REALTIME_SWITCH_INTERVAL = 0.0001   # s

def _node_classes():
    from .nodes.ccc import CCCNode
    from .nodes.contour_estimator import ContourEstimatorNode
    from .nodes.interpolator import InterpolatorNode
    from .nodes.plant import PlantNode
    from .nodes.recorder import RecorderNode
    from .nodes.servo import ServoNode
    return {"interpolator": InterpolatorNode, "plant": PlantNode, "servo": ServoNode,
            "contour_estimator": ContourEstimatorNode, "ccc": CCCNode, "recorder": RecorderNode}


def _lean_spin_once(nodes, wait_set, handles, timeout_ns: int):
    """One turn of the lean loop over every node's subscriptions: wait, take, dispatch."""
    from .nodes.lockstep import wait_on
    wait_on(wait_set, handles, timeout_ns)
    for node in nodes:
        node.take_all(node.admitted)


def run_composed(experiment_path: str, bag: str, executor_kind: str = "lean", start_time: float = 0.0,
                 namespace: str = "/"):
    """Create every node in this process, run the lockstep to the end, close the bag.

    ``executor_kind`` ``lean`` waits on one wait set holding every node's subscriptions and dispatches
    serialised messages directly; ``stock`` spins rclpy's SingleThreadedExecutor over the same nodes'
    subscription callbacks (the path for users who embed the nodes in their own executor).
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    experiment = load_experiment(experiment_path)
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
        specs = graph.node_specs(experiment.axes, None, str(bag), str(experiment_path), namespace)
        for spec in specs[1:] + specs[:1]:        # the recorder last: it takes what the others published
            overrides = [Parameter(key, value=value) for key, value in spec.overrides]
            node = classes[spec.executable](name=spec.name, namespace=spec.namespace, parameter_overrides=overrides,
                                            callbacks=True)
            nodes.append(node)
            executor.add_node(node.node)
        for node in nodes:
            node.wait_for_graph()
        for node in nodes:
            node.start()
        if executor_kind == "lean" or experiment.timing == "realtime":
            from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
            handles = [sub.handle for node in nodes for _, sub, _, _ in node._inputs]
            wait_set = _rclpy.WaitSet(len(handles), 0, 0, 0, 0, 0, nodes[0].node.context.handle)

            def spin_once(timeout_sec):
                _lean_spin_once(nodes, wait_set, handles, int(timeout_sec * 1e9))
        else:
            spin_once = executor.spin_once
        if experiment.timing == "realtime":
            _run_realtime(nodes, nodes[0].experiment)
        last, last_progress = -1, time.monotonic()
        while not all(node.finished for node in nodes):
            spin_once(timeout_sec=0.2)
            if executor_kind == "lean":
                for node in nodes:
                    node.serve_requests()
            progress = sum(node.next_step for node in nodes) + sum(getattr(node, "counts", {}).values())
            if progress != last:
                last, last_progress = progress, time.monotonic()
            elif time.monotonic() - last_progress > experiment.stall_timeout:
                stuck = [node for node in nodes if not node.finished]
                raise RunError(f"composed graph stalled for {experiment.stall_timeout:g} s: "
                               + "; ".join(f"{n.name} at step {n.next_step}, no message on "
                                           f"{', '.join(n.missing_inputs())}" for n in stuck if n.missing_inputs()))
        recorder = nodes[-1]
        for node in nodes[:-1]:
            node.finish()
        deadline = time.monotonic() + 0.3            # let the recorder take the end-of-run diagnostics
        while time.monotonic() < deadline:
            spin_once(timeout_sec=0.02)
        recorder.finish()
    finally:
        for node in reversed(nodes):
            node.destroy()
        rclpy.try_shutdown()
        directory.cleanup()


def _run_realtime(nodes, experiment):
    """Every node's realtime ticks in one loop: wait for tick k on all subscriptions, then tick each node
    in graph order (interpolator, plants, estimator, CCC, servos); the recorder takes what arrives.
    ``experiment`` is a node's (it holds the run's start_time)."""
    import rclpy
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from .nodes.lockstep import wait_until
    lockstep_nodes, recorder = nodes[:-1], nodes[-1]
    for node in lockstep_nodes:
        node.realtime_setup()
    handles = [sub.handle for node in nodes for _, sub, _, _ in node._inputs]
    wait_set = _rclpy.WaitSet(len(handles), 0, 0, 0, 0, 0, nodes[0].node.context.handle)

    def take():
        for node in lockstep_nodes:
            node.take_all(node.keep_newest)
        recorder.take_all(recorder.admitted)

    switch_interval = sys.getswitchinterval()
    sys.setswitchinterval(REALTIME_SWITCH_INTERVAL)
    try:
        for tick in range(experiment.n_steps):
            wait_until(lockstep_nodes[0].tick_time(tick), wait_set, handles, take, nodes[0].node.context,
                       spin=REALTIME_SPIN)
            for node in lockstep_nodes:
                node.realtime_tick(tick)
            recorder.take_all(recorder.admitted)
    finally:
        sys.setswitchinterval(switch_interval)
    end = time.time() + 1.0
    while not recorder.complete() and time.time() < end and rclpy.ok(context=nodes[0].node.context):
        wait_until(time.time() + 0.01, wait_set, handles, take, nodes[0].node.context)
    recorder.finished = True


def main(argv=None) -> int:
    import argparse
    parser = argparse.ArgumentParser(prog="python -m contouring_ros.composed")
    parser.add_argument("experiment")
    parser.add_argument("bag")
    parser.add_argument("executor", nargs="?", default="lean", choices=["lean", "stock"])
    parser.add_argument("--start-time", type=float, default=0.0, help="Unix time of tick 0 (realtime runs)")
    parser.add_argument("--namespace", default="/", help="the graph's namespace (default: the root)")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    try:
        run_composed(args.experiment, args.bag, args.executor, args.start_time, args.namespace)
    except KeyboardInterrupt:
        return 130
    except ContouringError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
