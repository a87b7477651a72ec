"""Plant node (one per axis, namespace = axis name): applies commands, publishes the axis state."""
from __future__ import annotations

from ..wire import cdr, graph
from ..experiment.build import build_plant, initial_state
from ..core.simulation import step_time
from .node import LockstepNode
from .process import run_node


class PlantNode(LockstepNode):
    role = "plant"
    default_name = "plant"
    per_axis = True
    realtime_offset = -1

    def setup(self):
        self.axis = self.own_axis()
        index = self.axes.index(self.axis)
        positions, velocities, _ = initial_state(self.experiment)
        self.plant = build_plant(self.experiment, self.axis, positions[index], velocities[index])
        self.add_input(graph.command_topic(self.axis))
        self.publisher = self.add_output(graph.state_topic(self.axis))
        self.names = [self.axis]

    def publish_state(self, k: int):
        position, velocity = self.plant.measure()
        self.publisher.publish(cdr.encode_joint_state(*self.stamp(k), self.names, [position], [velocity]))

    def start(self):
        self.publish_state(0)

    def on_step(self, k, inputs):
        command = inputs[graph.command_topic(self.axis)].effort[0]
        self.plant.step(command, step_time(k, self.experiment.sample_time))
        if k + 1 < self.n_steps:
            self.publish_state(k + 1)


def main(args=None):
    raise SystemExit(run_node(PlantNode, args))


if __name__ == "__main__":
    main()
