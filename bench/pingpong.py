"""One side of the rclpy ping-pong that measures this machine's floor per message hop.

Run by bench/all.py, two processes on a private ROS domain: ``ping`` publishes a stamped JointState on
/ping, ``pong`` answers each on /pong, ``ping`` sends the next on each answer. Both use the graph's lean
loop pieces (persistent wait set, serialised messages taken directly, the graph's QoS), so the time per
hop is what one message between two of our nodes costs at least. ping prints "hop_us <value>" and
"cpu_us_per_round <value>" (its CPU time per message taken and answered).
Usage: pingpong.py ping|pong ROUNDS [lean|events|single]: the third argument runs the same exchange on
rclpy's EventsExecutor or SingleThreadedExecutor (subscription callbacks) instead of the lean loop.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import rclpy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from contouring_ros.wire import cdr  # noqa: E402
from contouring_ros.nodes.base import GRAPH_QOS  # noqa: E402
from contouring_ros.nodes.rclpy_adapter import SubscriptionWaitSet, taker  # noqa: E402


def main():
    role, rounds = sys.argv[1], int(sys.argv[2])
    executor = sys.argv[3] if len(sys.argv) > 3 else "lean"
    rclpy.init()
    node = rclpy.create_node(role)
    out_topic, in_topic = ("/ping", "/pong") if role == "ping" else ("/pong", "/ping")
    publisher = node.create_publisher(JointState, out_topic, GRAPH_QOS)
    handler = []      # the executors' path: the subscription callback (set by _spin_executor)
    subscription = node.create_subscription(JointState, in_topic, lambda data: handler[0](data), GRAPH_QOS,
                                            raw=True)
    node.handler = handler
    deadline = time.monotonic() + 30.0
    while publisher.get_subscription_count() < 1 or subscription.get_publisher_count() < 1:
        if time.monotonic() > deadline:
            raise SystemExit(f"{role}: the other side did not appear")
        time.sleep(0.01)
    time.sleep(0.5)       # let discovery settle on both sides

    def send(k):
        publisher.publish(cdr.encode_joint_state(k // 1000, (k % 1000) * 1_000_000, ["x"], [float(k)], [0.0]))

    if executor != "lean":
        cpu = time.process_time()
        elapsed = _spin_executor(executor, node, subscription, send, role, rounds)
        if role == "ping":
            _report(elapsed, time.process_time() - cpu, rounds)
        time.sleep(0.3)
        node.destroy_node()
        rclpy.try_shutdown()
        return
    wait_set, take = SubscriptionWaitSet([subscription], node.context), taker(subscription, JointState)
    received, start, cpu = -1, time.perf_counter(), time.process_time()
    if role == "ping":
        send(0)
    while received < rounds - 1:
        wait_set.wait(1_000_000_000)
        while True:
            taken = take()
            if taken is None:
                break
            stamp = cdr.stamp_ns(taken[0])
            received = stamp // 1_000_000_000 * 1000 + stamp % 1_000_000_000 // 1_000_000
            if role == "pong":
                send(received)
            elif received + 1 < rounds:
                send(received + 1)
        if time.monotonic() > deadline + 120.0:
            raise SystemExit(f"{role}: stalled at round {received}")
    elapsed = time.perf_counter() - start
    if role == "ping":
        _report(elapsed, time.process_time() - cpu, rounds)
    time.sleep(0.3)
    node.destroy_node()
    rclpy.try_shutdown()


def _report(elapsed: float, cpu: float, rounds: int):
    """ping's result: wall time per hop, and its CPU time (every thread of the process) per round, one
    message taken and one published: what a message costs a node, less sensitive to a busy machine."""
    print(f"hop_us {elapsed / (2 * rounds) * 1e6:.1f}", flush=True)
    print(f"cpu_us_per_round {cpu / rounds * 1e6:.1f}", flush=True)


def _spin_executor(kind: str, node, subscription, send, role: str, rounds: int) -> float:
    """The same ping-pong on rclpy's own executors (``events``: EventsExecutor, ``single``:
    SingleThreadedExecutor), each message reaching a subscription callback; returns the seconds taken."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.experimental import EventsExecutor
    from rclpy.task import Future
    done = Future()

    def on_message(data):
        stamp = cdr.stamp_ns(data)
        received = stamp // 1_000_000_000 * 1000 + stamp % 1_000_000_000 // 1_000_000
        if role == "pong":
            send(received)
        elif received + 1 < rounds:
            send(received + 1)
        if received >= rounds - 1:
            done.set_result(True)

    node.handler.append(on_message)
    executor = EventsExecutor() if kind == "events" else SingleThreadedExecutor()
    executor.add_node(node)
    start = time.perf_counter()
    if role == "ping":
        send(0)
    executor.spin_until_future_complete(done, timeout_sec=150.0)
    elapsed = time.perf_counter() - start
    executor.shutdown()
    if not done.done():
        raise SystemExit(f"{role}: stalled on the {kind} executor")
    return elapsed


if __name__ == "__main__":
    main()
