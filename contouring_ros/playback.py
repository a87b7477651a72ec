"""Republish a bag onto ROS topics, at its recorded rate (or a multiple) or as fast as possible.

Every channel of the bag is published with its own type, raw (the recorded CDR bytes go out unchanged),
and /clock follows the messages' log times, so use_sim_time nodes and tools see the recorded time.
"""
from __future__ import annotations

import time
from pathlib import Path

from . import cdr, graph
from .bag import _iter_records
from .errors import BagError

__all__ = ["play_bag"]

DISCOVERY_PAUSE = 1.0   # s between creating the publishers and the first message, so subscribers match


def play_bag(path, rate: float = 1.0, progress: bool = False, say=print) -> int:
    """Publish every message of the bag at ``path``; ``rate`` 1 is real time, 0 as fast as possible.

    Returns the number of messages published.
    """
    import rclpy
    from mcap.records import Channel, Schema
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    from .nodes.lockstep import message_class
    qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                     history=HistoryPolicy.KEEP_LAST, depth=1000)
    path = Path(path)
    if not path.is_file():
        raise BagError(f"{path}: no such bag")
    rclpy.init()
    node = rclpy.create_node("bag_player")
    schemas, publishers, warnings = {}, {}, []
    clock = node.create_publisher(message_class("rosgraph_msgs/msg/Clock"), graph.CLOCK, qos)
    sent, first_log, wall_start, last_clock = 0, None, None, None
    has_clock = False
    try:
        for record in _iter_records(path, warnings, progress):
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                try:
                    cls = message_class(schemas[record.schema_id].name)
                except (KeyError, ImportError, AttributeError, ValueError):
                    say(f"skipping {record.topic}: no message type {schemas.get(record.schema_id)}")
                    continue
                if record.topic == graph.CLOCK:
                    has_clock = True
                    publishers[record.id] = clock
                else:
                    publishers[record.id] = node.create_publisher(cls, record.topic, qos)
            elif hasattr(record, "log_time") and record.channel_id in publishers:
                if wall_start is None:
                    time.sleep(DISCOVERY_PAUSE)
                    first_log, wall_start = record.log_time, time.monotonic()
                if rate > 0:
                    delay = wall_start + (record.log_time - first_log) * 1e-9 / rate - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
                if not has_clock and record.log_time != last_clock:
                    clock.publish(cdr.encode_clock(*divmod(record.log_time, 1_000_000_000)))
                    last_clock = record.log_time
                publishers[record.channel_id].publish(bytes(record.data))
                sent += 1
        for warning in warnings:
            say(f"warning: {warning}")
        time.sleep(0.5)       # let reliable subscribers take the tail
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    say(f"published {sent} messages from {path}")
    return sent
