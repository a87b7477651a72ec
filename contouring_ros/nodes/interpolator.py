"""Interpolator node: publishes the reference of every step, a few steps ahead, and /clock."""
from __future__ import annotations

from .. import cdr, graph
from ..config import build_curve, build_schedule
from ..core.interpolation import reference
from ..core.simulation import step_time
from .lockstep import LockstepNode, run_node


class InterpolatorNode(LockstepNode):
    """Publishes /reference for step k + LOOKAHEAD when the estimate of step k arrives (paced by the
    graph, never more than LOOKAHEAD steps ahead), and /clock = t_k at that moment."""

    role = "interpolator"
    default_name = "interpolator"
    realtime_needs_inputs = False

    def setup(self):
        self.curve = build_curve(self.experiment)
        self.schedule = build_schedule(self.experiment, self.curve)
        self.add_input(graph.CONTOUR_ERROR)
        self.reference_pub = self.add_output(graph.REFERENCE)
        self.clock_pub = self.add_output(graph.CLOCK)
        self.names = self.axes + [graph.THETA_NAME]

    def publish_reference(self, k: int):
        if k >= self.n_steps:
            return
        ref = reference(self.curve, self.schedule, step_time(k, self.experiment.sample_time))
        stamp = self.stamp(k)
        self.reference_pub.publish(cdr.encode_joint_trajectory(
            *stamp, self.names, [*ref.position, float(ref.theta)], [*ref.velocity, float(ref.theta_dot)],
            [*ref.acceleration, float(ref.theta_ddot)]))

    def start(self):
        self.clock_pub.publish(cdr.encode_clock(0, 0))
        for k in range(graph.LOOKAHEAD):
            self.publish_reference(k)

    def on_step(self, k, inputs):
        if k > 0:
            self.clock_pub.publish(cdr.encode_clock(*self.stamp(k)))
        self.publish_reference(k + graph.LOOKAHEAD)


def main(args=None):
    raise SystemExit(run_node(InterpolatorNode, args))


if __name__ == "__main__":
    main()
