"""Contour estimator node: reference and every axis state of step k in, contour error estimate out."""
from __future__ import annotations

import numpy as np

from ..wire import cdr, graph
from ..experiment.build import build_curve, build_estimator, build_schedule
from ..core.simulation import diverged_message, path_bound, step_time
from ..errors import RunError
from .node import LockstepNode
from .process import run_node


class ContourEstimatorNode(LockstepNode):
    role = "contour_estimator"
    default_name = "contour_estimator"

    def setup(self):
        curve = build_curve(self.experiment)
        self.estimator = build_estimator(self.experiment, curve)
        # the run stops where the in-process simulation would: an axis out of bounds (docs/ARCHITECTURE.md)
        self.bound = path_bound(curve, build_schedule(self.experiment, curve), self.experiment.divergence_factor)
        self.add_input(graph.REFERENCE)
        self.state_topics = [graph.state_topic(a) for a in self.axes]
        for topic in self.state_topics:
            self.add_input(topic)
        self.publisher = self.add_output(graph.CONTOUR_ERROR)
        self.names = graph.estimate_names(self.axes)

    def counters(self) -> dict:
        """Branch-check restarts, and the steps whose iterative estimate (Newton flow, foot-point search)
        reached its iteration cap without converging to its tolerance."""
        return {"branch recoveries": getattr(self.estimator, "recoveries", 0),
                "iteration cap reached": getattr(self.estimator, "cap_reached", 0)}

    def on_step(self, k, inputs):
        ref = graph.reference_from_msg(inputs[graph.REFERENCE], len(self.axes))
        position = np.array([inputs[topic].position[0] for topic in self.state_topics])
        distance = float(np.max(np.abs(position - ref.position)))
        if not distance <= self.bound:
            raise RunError(f"{self.name}: " + diverged_message(step_time(k, self.experiment.sample_time), k,
                                                               distance, self.bound))
        estimate = self.estimator.step(ref, position)
        self.publisher.publish(cdr.encode_joint_state(*self.stamp(k), self.names, graph.estimate_values(estimate)))


def main(args=None):
    raise SystemExit(run_node(ContourEstimatorNode, args))


if __name__ == "__main__":
    main()
