"""Servo node (one per axis, namespace = axis name): reference, own state and correction in, command out."""
from __future__ import annotations

from ..wire import cdr, graph
from ..experiment.build import build_servo, initial_state
from .node import LockstepNode
from .process import run_node


class ServoNode(LockstepNode):
    role = "servo"
    default_name = "servo"
    per_axis = True

    def setup(self):
        self.axis = self.own_axis()
        self.index = self.axes.index(self.axis)
        positions, velocities, accelerations = initial_state(self.experiment)
        self.servo = build_servo(self.experiment, self.axis, positions[self.index], velocities[self.index],
                                 accelerations[self.index])
        self.state_topic = graph.state_topic(self.axis)
        for topic in (graph.REFERENCE, self.state_topic, graph.CORRECTION):
            self.add_input(topic)
        self.publisher = self.add_output(graph.command_topic(self.axis))
        self.names = [self.axis]
        self.law = f"the {self.experiment.servos[self.axis]['law']} law"
        self.preview = self.reads_ahead(self.servo, self.law)

    def on_step(self, k, inputs):
        i = self.index
        message = inputs[graph.REFERENCE]
        point = message.points[0]
        state = inputs[self.state_topic]
        if self.preview:            # the reference ahead, published with this step's (a ZPETC's)
            ahead = self.preview_points(k, message, self.preview, self.law)
            self.servo.look_ahead(tuple(later.positions[i] for later in ahead))
        command = self.servo.step(point.positions[i], point.velocities[i], point.accelerations[i],
                                  state.position[0], state.velocity[0], inputs[graph.CORRECTION].effort[i])
        self.publisher.publish(cdr.encode_joint_state(*self.stamp(k), self.names, effort=[float(command)]))


def main(args=None):
    raise SystemExit(run_node(ServoNode, args))


if __name__ == "__main__":
    main()
