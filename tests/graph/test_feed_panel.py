"""The interpolator's hold and resume services (std_srvs/srv/Trigger) and its feed override topic
(std_msgs/msg/Float64, percent) in realtime mode, called over ROS on the node itself; in lockstep the services
refuse (the timed feed_events are the reproducible way)."""
import time

import pytest

from conftest import CONFIG

EXAMPLE = CONFIG / "gcode_example_part.yaml"


def interpolator_and_panel(tmp_path, timing: str):
    """An interpolator node of the example part under namespace /panel (timing ``timing``) on a domain of its
    own, and a client node with the panel's two service clients and the override publisher."""
    import rclpy
    from std_msgs.msg import Float64
    from std_srvs.srv import Trigger
    from contouring_ros.nodes.interpolator import InterpolatorNode
    from contouring_ros.run.runner import DomainLease
    text = EXAMPLE.read_text().replace("file: parts/example_part.ngc", f"file: {CONFIG / 'parts/example_part.ngc'}")
    path = tmp_path / "panel.yaml"
    path.write_text(text.replace("sample_time: 0.001", f"sample_time: 0.001\n    timing: {timing}"))
    lease = DomainLease()
    rclpy.init(args=["--ros-args", "--params-file", str(path)], domain_id=lease.domain_id)
    node = InterpolatorNode(name="interpolator", namespace="/panel")
    client = rclpy.create_node("panel_client")
    services = {what: client.create_client(Trigger, f"/panel/interpolator/{what}") for what in ("hold", "resume")}
    override = client.create_publisher(Float64, "/panel/interpolator/feed_override", 10)
    return lease, node, client, services, override


def call(node, client, service, take):
    """Call a Trigger ``service`` while the node ``take``s what waits, as its ticks do; the response."""
    import rclpy
    from std_srvs.srv import Trigger
    assert service.wait_for_service(timeout_sec=10)
    future = service.call_async(Trigger.Request())
    deadline = time.monotonic() + 10
    while not future.done() and time.monotonic() < deadline:
        take()
        rclpy.spin_once(client, timeout_sec=0.01)
    return future.result()


@pytest.mark.graph
def test_realtime_hold_resume_and_override_over_ros_act_on_the_reference(tmp_path):
    import rclpy
    from std_msgs.msg import Float64
    lease, node, client, services, override = interpolator_and_panel(tmp_path, "realtime")
    try:
        control = node.control
        for k in range(1000):                        # the reference runs along the part for 1 s
            node.publish_reference(k)
        answer = call(node, client, services["hold"], node.take_panel)
        assert answer.success and answer.message == "hold at step 1000"
        again = call(node, client, services["hold"], node.take_panel)
        assert not again.success and again.message == "hold refused: the feed is held already"
        for k in range(1000, 1400):
            node.publish_reference(k)
        assert control.events[0][:2] == (1000, "hold") and control.stop is not None
        for percent in (300.0, 50.0):                # out of range: refused, then 50 %
            override.publish(Float64(data=percent))
        deadline = time.monotonic() + 10
        while not control.queue and time.monotonic() < deadline:
            node.take_panel()
            time.sleep(0.01)
        assert control.queue == [(1400, "override", 0.5)]
        assert call(node, client, services["resume"], node.take_panel).success
        for k in range(1400, 1500):
            node.publish_reference(k)
        assert [what for _, what, _ in control.events] == ["hold", "override 50%", "resume"]
        assert control.override == 0.5 and control.stop is None
        assert not call(node, client, services["resume"], node.take_panel).success    # nothing held now
    finally:
        client.destroy_node()
        node.destroy()
        rclpy.shutdown()
        lease.release()


@pytest.mark.graph
def test_in_lockstep_the_services_refuse_and_name_feed_events(tmp_path):
    import rclpy
    lease, node, client, services, _ = interpolator_and_panel(tmp_path, "lockstep")
    try:
        answer = call(node, client, services["hold"], lambda: node.serve_requests(now=time.monotonic() + 1.0))
        assert not answer.success and "feed_events" in answer.message
        assert node.control is None
    finally:
        client.destroy_node()
        node.destroy()
        rclpy.shutdown()
        lease.release()
