"""The bag writer's background thread: everything written reaches the file, in order; paced by a gate (the
composed layout's realtime loop), it writes only while the gate is open, and closing never waits on a
closed gate."""
import threading
import time

from mcap.reader import make_reader

from contouring_ros.wire import cdr
from contouring_ros.records.bag_writer import BagWriter

TOPICS = [("/x/state", "sensor_msgs/msg/JointState")]


def _messages(count: int) -> list:
    return [(k * 1_000_000, cdr.encode_joint_state(0, k * 1_000_000, ["x"], [float(k)], [0.0])) for k in range(count)]


def _recorded(path) -> list:
    with open(path, "rb") as stream:
        return [(message.log_time, message.data) for _, _, message in make_reader(stream).iter_messages()]


def _size_when_settled(path) -> int:
    time.sleep(0.2)
    return path.stat().st_size


def test_background_writer_keeps_every_message_in_order(tmp_path):
    messages = _messages(3 * BagWriter.BATCH + 7)      # full batches and a partial one
    with BagWriter(tmp_path / "a.mcap", TOPICS, background=True) as writer:
        for stamp, data in messages:
            writer.write("/x/state", stamp, data)
    assert _recorded(tmp_path / "a.mcap") == messages


def test_gated_writer_writes_only_while_the_gate_is_open(tmp_path):
    path = tmp_path / "gated.mcap"
    messages = _messages(4 * BagWriter.BATCH)
    writer = BagWriter(path, TOPICS, background=True, chunk_size=1024)   # small chunks: writes reach the file
    gate = threading.Event()
    writer.write_only_while(gate)
    empty = _size_when_settled(path)
    for stamp, data in messages:
        writer.write("/x/state", stamp, data)
    assert _size_when_settled(path) == empty             # the loop is ticking: nothing written
    gate.set()
    assert _size_when_settled(path) > empty              # the loop waits: the thread writes
    writer.close()
    assert _recorded(path) == messages


def test_closing_a_gated_writer_writes_everything_without_waiting_for_the_gate(tmp_path):
    path = tmp_path / "closed.mcap"
    messages = _messages(2 * BagWriter.BATCH + 1)
    writer = BagWriter(path, TOPICS, background=True)
    writer.write_only_while(threading.Event())           # never opened
    for stamp, data in messages:
        writer.write("/x/state", stamp, data)
    closing = threading.Thread(target=writer.close)
    closing.start()
    closing.join(timeout=10)
    assert not closing.is_alive()
    assert _recorded(path) == messages
