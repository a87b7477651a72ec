"""Cross-coupled controller node: the contour error estimate of step k in, per-axis corrections out."""
from __future__ import annotations

from sensor_msgs.msg import JointState

from .. import graph
from ..config import build_controller, build_curve
from .lockstep import LockstepNode, run_node


class CCCNode(LockstepNode):
    role = "ccc"
    default_name = "ccc"

    def setup(self):
        self.controller = build_controller(self.experiment, build_curve(self.experiment))
        self.add_input(graph.CONTOUR_ERROR)
        self.publisher = self.add_output(graph.CORRECTION)
        self.msg = JointState(name=list(self.axes))

    def on_step(self, k, inputs):
        estimate = graph.estimate_from_msg(inputs[graph.CONTOUR_ERROR], len(self.axes))
        correction = self.controller.step(estimate)
        self.stamp(self.msg.header, k)
        self.msg.effort = [float(v) for v in correction]
        self.publisher.publish(self.msg)


def main(args=None):
    raise SystemExit(run_node(CCCNode, args))


if __name__ == "__main__":
    main()
