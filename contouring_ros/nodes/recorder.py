"""Recorder node: takes every topic of the graph undecoded and writes one MCAP bag.

The CDR payloads are written as they arrived; each message is logged at its step stamp (read from the
fixed CDR layout of the header, without deserialising), so a bag's payloads are identical run to run. The
experiment's YAML is stored in the bag. The recorder stops once every topic has delivered all its steps;
on SIGINT/SIGTERM it closes the bag with its summary.
"""
from __future__ import annotations

import struct
from pathlib import Path

from .. import __version__, graph
from ..bag import EXPERIMENT_METADATA, BagWriter
from ..errors import ConfigError
from .lockstep import LockstepNode, run_node

_STAMP = struct.Struct("<iI")   # builtin_interfaces/Time right after the 4-byte CDR encapsulation header


class RecorderNode(LockstepNode):
    role = "recorder"
    default_name = "recorder"

    def setup(self):
        options = self.experiment.info["node"]
        if not options["bag"]:
            raise ConfigError(f"{self.name}: parameter 'bag' (the .mcap file to write) is required")
        text = Path(options["experiment_file"]).read_text() if options["experiment_file"] else ""
        self.topic_list = graph.topics(self.axes)
        for topic in self.topic_list:
            self.add_input(topic.name, raw=True)
        self.counts = {topic.name: 0 for topic in self.topic_list}
        self.writer = BagWriter(options["bag"], [(t.name, t.type) for t in self.topic_list], metadata={
            EXPERIMENT_METADATA: {"yaml": text, "axes": ",".join(self.axes), "steps": str(self.n_steps),
                                  "sample_time": repr(self.experiment.sample_time),
                                  "contouring_ros_version": __version__}})

    def file_message(self, topic, data):
        sec, nanosec = _STAMP.unpack_from(data, 4)
        self.writer.write(topic, sec * 1_000_000_000 + nanosec, data)
        self.counts[topic] += 1

    def spin(self):
        self.wait_for_graph()

        def take():
            before = sum(self.counts.values())
            self._take_all()
            return sum(self.counts.values()) > before

        self.wait_loop(lambda: min(self.counts.values()) >= self.n_steps, take,
                       lambda: "incomplete topics " + ", ".join(t for t, n in self.counts.items() if n < self.n_steps))
        self.finished = True

    def destroy(self):
        self.writer.close()
        super().destroy()


def main(args=None):
    raise SystemExit(run_node(RecorderNode, args))


if __name__ == "__main__":
    main()
