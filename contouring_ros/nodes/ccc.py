"""Cross-coupled controller node: the contour error estimate of step k in, per-axis corrections out.

The node also takes /reference and every /<axis>/state of the step when the shared key
``ccc_takes_state`` is true (the default; ``contouring-ros run`` sets it false for controllers that do not
use them, so that every node knows the topic table from the shared keys alone). The controllers that use
them (``needs_state``, e.g. the task-frame PD of paper 003) need it true; the others never decode them.
They arrive before the estimate, so the critical path stays plant -> estimator -> CCC -> servo.
"""
from __future__ import annotations

import numpy as np

from ..wire import cdr, graph
from ..experiment.build import build_controller, build_curve
from ..experiment.validate import check_ccc_takes_state, controller_uses_state
from .node import LockstepNode
from .process import run_node


class CCCNode(LockstepNode):
    role = "ccc"
    default_name = "ccc"

    def setup(self):
        self.controller = build_controller(self.experiment, build_curve(self.experiment))
        self.needs_state = controller_uses_state(self.experiment)
        check_ccc_takes_state(self.name, self.experiment, self.needs_state)
        self.add_input(graph.CONTOUR_ERROR)
        self.state_topics = [graph.state_topic(a) for a in self.axes]
        if self.experiment.ccc_takes_state:
            self.add_input(graph.REFERENCE, used=self.needs_state)
            for topic in self.state_topics:
                self.add_input(topic, used=self.needs_state)
        self.publisher = self.add_output(graph.CORRECTION)
        self.kind = f"the {self.experiment.controller['type']} controller"
        self.preview = self.reads_ahead(self.controller, self.kind)
        self.names = list(self.axes)

    def on_step(self, k, inputs):
        estimate = graph.estimate_from_msg(inputs[graph.CONTOUR_ERROR], len(self.axes))
        if self.needs_state:
            message = inputs[graph.REFERENCE]
            ref = graph.reference_from_msg(message, len(self.axes))
            if self.preview:        # the reference ahead, published with this step's (an MPCC's horizon)
                ahead = self.preview_points(k, message, self.preview, self.kind)
                self.controller.look_ahead(np.array([point.positions[:len(self.axes)] for point in ahead]))
            position = np.array([inputs[topic].position[0] for topic in self.state_topics])
            velocity = np.array([inputs[topic].velocity[0] for topic in self.state_topics])
            correction = self.controller.step(estimate, ref, position, velocity)
        else:
            correction = self.controller.step(estimate)
        self.publisher.publish(cdr.encode_joint_state(*self.stamp(k), self.names,
                                                      effort=[float(v) for v in correction]))


def main(args=None):
    raise SystemExit(run_node(CCCNode, args))


if __name__ == "__main__":
    main()
