"""Interpolator node: publishes the reference of every step, a few steps ahead, and /clock; where exact stops
wait for the axes (in-position check), it takes every axis state too. Where a servo reads the reference
ahead (ZPETC), each /reference message carries after its point the positions of the steps after it
(docs/ARCHITECTURE.md, "Reference preview").

In realtime mode the interpolator is also a control's operator panel: the services ~/hold and ~/resume
(std_srvs/srv/Trigger: feed hold and resume) and the topic ~/feed_override (std_msgs/msg/Float64, percent, 0
to 200) act on the reference from the next step it computes, as the same events of ``feed_events`` do
(:meth:`contouring_ros.core.feed_control.FeedControl.command`). In lockstep the services refuse (the timed
``feed_events`` are the reproducible way) and the topic is not read."""
from __future__ import annotations

from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from ..wire import cdr, graph
from .rclpy_adapter import take_request, taker
from ..experiment.build import (build_clock, build_curve, build_feed_control, build_monitor, build_schedule,
                                interpolator_takes_state, reference_preview)
from ..core.interpolation import reference, reference_ahead
from ..records.blocks import breach_line
from ..core.simulation import step_time
from .node import LockstepNode
from .process import run_node


class InterpolatorNode(LockstepNode):
    """Publishes /reference for step k + LOOKAHEAD when the estimate of step k arrives (paced by the
    graph, never more than LOOKAHEAD steps ahead), and /clock = t_k at that moment. With the in-position
    check (``experiment.build.build_clock``) it also takes every /<axis>/state: the reference of step k + LOOKAHEAD
    holds at an exact stop until the positions of step k are within the window."""

    role = "interpolator"
    default_name = "interpolator"
    realtime_needs_inputs = False

    def setup(self):
        self.curve = build_curve(self.experiment)
        self.schedule = build_schedule(self.experiment, self.curve)
        self.clock = build_clock(self.experiment, self.curve, self.schedule)
        self.monitor = build_monitor(self.experiment)
        self.live = self.experiment.timing == "realtime"
        self.control = build_feed_control(self.experiment, self.curve, self.schedule, self.clock, self.monitor,
                                          live=self.live)
        self.panel = [self.node.create_service(Trigger, "~/" + what, lambda request, response, what=what:
                                               self.on_command(response, what)) for what in ("hold", "resume")]
        self.override_sub = self.node.create_subscription(Float64, "~/feed_override", self.on_override, 10)
        self.take_override = taker(self.override_sub, Float64, raw=False)
        self.add_input(graph.CONTOUR_ERROR)
        self.state_topics = [graph.state_topic(a) for a in self.axes] \
            if interpolator_takes_state(self.experiment) else []
        self.published = {}          # step -> (reference positions, theta) of the steps the monitor reads
        for topic in self.state_topics:
            self.add_input(topic)
        self.reference_pub = self.add_output(graph.REFERENCE)
        self.clock_pub = self.add_output(graph.CLOCK)
        self.names = self.axes + [graph.THETA_NAME]
        self.preview = reference_preview(self.experiment)

    def publish_reference(self, k: int, position=None, velocity=None):
        if k >= self.n_steps:
            return
        if self.control is not None:        # holds, resumes, the stop after a breach, in-position checks
            ref = self.control.reference(k, position, velocity)
            t = None
        else:
            t = step_time(k, self.experiment.sample_time) if self.clock is None else \
                self.clock.time(k, position, velocity)
            ref = reference(self.curve, self.schedule, t)
        if self.monitor is not None:
            self.published[k] = (ref.position, float(ref.theta))
        stamp = self.stamp(k)
        preview = cdr.preview_points(reference_ahead(self.curve, self.schedule, k, t, self.preview,
                                                     self.experiment.sample_time, self.clock),
                                     self.sample_time_ns) if self.preview else ()
        self.reference_pub.publish(cdr.encode_joint_trajectory(
            *stamp, self.names, [*ref.position, float(ref.theta)], [*ref.velocity, float(ref.theta_dot)],
            [*ref.acceleration, float(ref.theta_ddot)], preview=preview))

    def on_command(self, response, what: str, percent: float | None = None):
        """A hold, resume (``response``: the Trigger service's) or override from the panel interfaces."""
        if not self.live:
            ok, message = False, (f"{what} refused: in timing: lockstep the run's feed_events are the way to hold, "
                                  "resume and override (reproducibly)")
        elif self.control is None:
            ok, message = False, (f"{what} refused: feed hold and override need a tool path planned by the feed plan "
                                  "whose reference no servo reads ahead")
        else:
            ok, message = self.control.command(what, percent)
        if ok:                 # (rclpy refuses two severities from one line of code)
            self.node.get_logger().info(message)
        else:
            self.node.get_logger().warning(message)
        if response is not None:
            response.success, response.message = ok, message
        return response

    def on_override(self, message):
        """A feed override [percent] on ~/feed_override."""
        self.on_command(None, "override", float(message.data))

    def take_panel(self):
        """Answer the hold and resume requests and read the overrides that wait (the lean loops run no
        executor: each realtime tick takes them before it computes its reference)."""
        for service in self.panel:
            while True:
                request, header = take_request(service)
                if header is None:
                    break
                service.send_response(service.callback(request, Trigger.Response()), header)
        while (taken := self.take_override()) is not None:
            self.on_override(taken[0])

    def start(self):
        self.clock_pub.publish(cdr.encode_clock(0, 0))
        for k in range(graph.LOOKAHEAD):
            self.publish_reference(k)

    def on_step(self, k, inputs):
        if self.live:
            self.take_panel()
        if k > 0:
            self.clock_pub.publish(cdr.encode_clock(*self.stamp(k)))
        states = [inputs.get(topic) for topic in self.state_topics]
        positions = [state.position[0] for state in states] if states and None not in states else None
        if self.monitor is not None:        # step k's estimate and states against step k's reference
            estimate = inputs[graph.CONTOUR_ERROR]
            reference_position, theta = self.published.pop(k)
            breach = self.monitor.check(k, estimate.position[:len(self.axes)], reference_position,
                                        positions if positions is not None else reference_position, theta)
            if breach is not None:
                self.node.get_logger().warning(f"{breach_line(breach, self.curve, self.axes, self.experiment.sample_time)}"
                                               "; stopping on the path")
        clock_states = (positions, [state.velocity[0] for state in states]) \
            if positions is not None and (self.clock if self.control is None else self.control.clock) is not None \
            else (None, None)
        self.publish_reference(k + graph.LOOKAHEAD, *clock_states)


def main(args=None):
    raise SystemExit(run_node(InterpolatorNode, args))


if __name__ == "__main__":
    main()
