"""Writing MCAP bags in the rosbag2 layout, without rosbag2.

Profile ``ros2``, one schema per message type with encoding ``ros2msg`` named ``pkg/msg/Type`` (the .msg text
with its dependencies, as rosbag2 stores it), CDR payloads exactly as they went over the wire, zstd chunks,
and a summary with statistics, so that rosbag2, Foxglove, PlotJuggler and the ``mcap``/``rosbags`` readers open
it. The experiment's YAML is stored as the metadata record ``contouring_ros.experiment``
(:data:`EXPERIMENT_METADATA`), the wall-clock figures of a recording as ``contouring_ros.run``
(:data:`RUN_METADATA`). Log and publish times are the messages' step stamps. :func:`write_simulation` writes an
in-process run as the recorder would have recorded it.
"""
from __future__ import annotations

import os
import re
import sys
from pathlib import Path

from ..wire import cdr, graph
from ..core.simulation import step_time
from ..errors import BagError
from ..core.interpolation import reference_ahead
from ..experiment.build import build_curve, build_schedule, reference_preview

__all__ = ["EXPERIMENT_METADATA", "RUN_METADATA", "message_definition", "BagWriter", "write_simulation"]

EXPERIMENT_METADATA = "contouring_ros.experiment"
RUN_METADATA = "contouring_ros.run"      # wall-clock figures of the recording
_BUILTINS = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
             "uint32", "int64", "uint64", "string", "wstring"}
_SEPARATOR = "=" * 80
QOS_METADATA = ("- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n"
                "  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n"
                "  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n  liveliness: 1\n"
                "  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n"
                "  avoid_ros_namespace_conventions: false\n")


def _msg_text(package: str, name: str) -> str:
    """The .msg file of a message type, from <prefix>/share/<package>/msg of an ament prefix (a sourced ROS
    install) or of this Python environment (the PyPI message wheels)."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p] + [sys.prefix]
    for prefix in prefixes:
        path = Path(prefix) / "share" / package / "msg" / f"{name}.msg"
        if path.is_file():
            return path.read_text()
    raise BagError(f"no definition of {package}/msg/{name} under {', '.join(prefixes)}")


def _field_types(text: str, package: str):
    """Complex field types ('pkg/Type') a .msg text refers to, in order."""
    for line in text.splitlines():
        tokens = line.split("#", 1)[0].split()
        if len(tokens) < 2 or "=" in tokens[1]:       # blank, or a constant
            continue
        base = re.sub(r"(<=\d+)?(\[.*\])?$", "", tokens[0])
        if base not in _BUILTINS:
            yield base if "/" in base else f"{package}/{base}"


def message_definition(type_name: str) -> str:
    """The ros2msg schema text of 'pkg/msg/Type': its .msg file, then each dependency once, depth first."""
    package, _, name = type_name.split("/")
    parts, seen = [_msg_text(package, name)], set()
    stack = list(_field_types(parts[0], package))
    while stack:
        dep = stack.pop(0)
        if dep in seen:
            continue
        seen.add(dep)
        dep_package, dep_name = dep.split("/")[0], dep.split("/")[-1]
        text = _msg_text(dep_package, dep_name)
        parts.append(f"{_SEPARATOR}\nMSG: {dep_package}/{dep_name}\n{text}")
        stack.extend(_field_types(text, dep_package))
    return "\n".join(part.rstrip("\n") for part in parts) + "\n"


class BagWriter:
    """Write CDR messages to an MCAP file in the rosbag2 layout; use as a context manager.

    Parameters
    ----------
    path : path-like
        The .mcap file to create.
    topics : iterable of (name, 'pkg/msg/Type')
    metadata : dict of str -> dict of str to str
        Metadata records written at the start.
    background : bool
        Write (and compress) on a thread of its own: :meth:`write` only queues the message, so the caller
        (the recorder's take loop, or the composed layout's one loop) never waits for a chunk to compress.
    """

    BATCH = 256    # messages a background writer collects before handing them to its thread

    def __init__(self, path, topics, *, metadata=None, chunk_size: int = 256 * 1024, background: bool = False):
        from mcap.writer import CompressionType, Writer
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "wb")
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="contouring_ros")
        schemas, self._channels, self._sequence = {}, {}, {}
        for topic, type_name in topics:
            if type_name not in schemas:
                schemas[type_name] = self._writer.register_schema(
                    name=type_name, encoding="ros2msg", data=message_definition(type_name).encode())
            self._channels[topic] = self._writer.register_channel(
                topic=topic, message_encoding="cdr", schema_id=schemas[type_name],
                metadata={"offered_qos_profiles": QOS_METADATA})
            self._sequence[topic] = 0
        for name, record in (metadata or {}).items():
            self._writer.add_metadata(name, record)
        self.closed = False
        self._queue = self._thread = self._gate = None
        self._batch = []
        if background:
            import queue
            import threading
            self._queue = queue.SimpleQueue()
            self._thread = threading.Thread(target=self._drain, name="bag writer", daemon=True)
            self._thread.start()

    def _drain(self):
        while True:
            batch = self._queue.get()
            if batch is None:
                return
            for call in batch:
                gate = self._gate
                if gate is not None:
                    gate.wait()
                call[0](*call[1:])

    def write_only_while(self, gate):
        """From now on the writer thread (background writers) writes only while the threading.Event ``gate``
        is set; None: whenever it has something to write. The composed layout's realtime loop sets its gate
        while it waits for its next tick and clears it while it ticks: the thread's Python work then never
        competes with a tick for the interpreter (unpaced, a batch written during ticks made them up to 2 ms
        longer, every 256 messages). What is queued while the gate is closed waits, in memory."""
        previous, self._gate = self._gate, gate
        if previous is not None:
            previous.set()       # release a thread waiting on the old gate

    def _do(self, *call):
        if self._queue is not None:
            self._batch.append(call)
            if len(self._batch) >= self.BATCH:
                self.flush()
        else:
            call[0](*call[1:])

    def flush(self):
        """Hand what :meth:`write` collected to the writer thread (background writers; else nothing)."""
        if self._queue is not None and self._batch:
            self._queue.put(self._batch)
            self._batch = []

    def add_metadata(self, name: str, record: dict):
        """Add a metadata record (str -> str) before the bag is closed."""
        self._do(self._writer.add_metadata, name, record)
        self.flush()

    def write(self, topic: str, stamp_ns: int, data: bytes):
        """Append one serialised message, logged at its stamp (a background writer collects BATCH
        messages before it hands them to its thread: waking the thread for each message cost the caller
        about 40 us a message, most of the recorder's cost in the composed layout)."""
        self._do(self._write, topic, stamp_ns, data)

    def _write(self, topic: str, stamp_ns: int, data: bytes):
        self._writer.add_message(self._channels[topic], log_time=stamp_ns, data=data, publish_time=stamp_ns,
                                 sequence=self._sequence[topic])
        self._sequence[topic] += 1

    def close(self):
        """Write what is queued, then the summary (statistics, indexes), and close the file."""
        if not self.closed:
            self.closed = True
            if self._thread is not None:
                self.write_only_while(None)
                self.flush()
                self._queue.put(None)
                self._thread.join()
            self._writer.finish()
            self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()



def write_simulation(path, experiment, result) -> Path:
    """Write an in-process run as the recorder would have recorded it (same topics, types and payloads).

    Used to record long runs without the node graph (benchmarks, sweeps) and as a second writer in tests.
    """
    axes = list(experiment.axes)
    ts_ns = int(round(experiment.sample_time * 1e9))
    names = axes + [graph.THETA_NAME]
    metadata = {EXPERIMENT_METADATA: {"yaml": experiment.text, "axes": ",".join(axes),
                                      "steps": str(len(result.time)), "sample_time": repr(experiment.sample_time)}}
    preview = reference_preview(experiment)
    curve = build_curve(experiment) if preview else None
    schedule = build_schedule(experiment, curve)
    with BagWriter(path, [(t.name, t.type) for t in graph.topics(axes)], metadata=metadata) as writer:
        for k in range(len(result.time)):
            stamp = graph.step_to_stamp(k, ts_ns)
            ns = k * ts_ns
            # theta's rates as the interpolator computes them (the result keeps theta alone)
            _, theta_dot, theta_ddot = schedule(step_time(k, experiment.sample_time))
            writer.write(graph.CLOCK, ns, cdr.encode_clock(*stamp))
            # the preview a servo reading ahead got (the plan's times without exact stops' holds)
            ahead = cdr.preview_points(reference_ahead(curve, schedule, k, result.time[k], preview,
                                                       experiment.sample_time), ts_ns) if preview else ()
            writer.write(graph.REFERENCE, ns, cdr.encode_joint_trajectory(
                *stamp, names, [*result.reference_position[k], result.theta[k]],
                [*result.reference_velocity[k], float(theta_dot)], [*result.reference_acceleration[k], float(theta_ddot)],
                preview=ahead))
            for i, axis in enumerate(axes):
                writer.write(graph.state_topic(axis), ns, cdr.encode_joint_state(
                    *stamp, [axis], [result.position[k, i]], [result.velocity[k, i]]))
            writer.write(graph.CONTOUR_ERROR, ns, cdr.encode_joint_state(
                *stamp, graph.estimate_names(axes),
                [*result.estimate_vector[k], result.estimate_signed[k], result.estimate_theta[k]]))
            writer.write(graph.CORRECTION, ns, cdr.encode_joint_state(*stamp, axes, effort=result.correction[k]))
            for i, axis in enumerate(axes):
                writer.write(graph.command_topic(axis), ns, cdr.encode_joint_state(
                    *stamp, [axis], effort=[result.command[k, i]]))
    return Path(path)
