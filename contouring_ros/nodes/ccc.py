"""Cross-coupled controller node: the contour error estimate of step k in, per-axis corrections out."""
from __future__ import annotations

from .. import cdr, graph
from ..config import build_controller, build_curve
from .lockstep import LockstepNode, run_node


class CCCNode(LockstepNode):
    role = "ccc"
    default_name = "ccc"

    def setup(self):
        self.controller = build_controller(self.experiment, build_curve(self.experiment))
        self.add_input(graph.CONTOUR_ERROR)
        self.publisher = self.add_output(graph.CORRECTION)
        self.names = list(self.axes)

    def on_step(self, k, inputs):
        estimate = graph.estimate_from_msg(inputs[graph.CONTOUR_ERROR], len(self.axes))
        correction = self.controller.step(estimate)
        self.publisher.publish(cdr.encode_joint_state(*self.stamp(k), self.names,
                                                      effort=[float(v) for v in correction]))


def main(args=None):
    raise SystemExit(run_node(CCCNode, args))


if __name__ == "__main__":
    main()
