"""Nodes of one process (the composed and grouped layouts) decode and check a message once: what the shared
decoded messages must keep (each node still gets the message, a bad message is still refused by every node
that takes it, a topic checked against another layout is checked again)."""
import math

import pytest

from contouring_ros.wire import cdr, graph
from contouring_ros.errors import RunError
from contouring_ros.nodes import intake
from contouring_ros.nodes.node import LockstepNode


class _Experiment:
    on_invalid_input = "stop"
    namespaced_clock = False


def _node(name: str, axes, counter: list) -> LockstepNode:
    """A node with the decoding half of LockstepNode only (no ROS graph): it takes /x/state."""
    node = LockstepNode.__new__(LockstepNode)
    node.name, node.experiment, node.next_step, node.graph_namespace = name, _Experiment(), 0, "/"
    node._topics = {t.name: t for t in graph.recorded_topics(axes)}
    node.rejected, node._last_valid, node.strangers = {}, {}, 0
    node.report = lambda *args, **kwargs: None

    def counting_decode(data):
        counter.append(name)
        return cdr.decode_joint_state(data)

    topic = graph.state_topic("x")
    node._inputs = [(topic, None, None, counting_decode)]
    node._decoded_keys = {topic: node.decoded_key(topic)}
    return node


@pytest.fixture(autouse=True)
def _empty_shared_decoding():
    intake._DECODED.clear()
    yield
    intake._DECODED.clear()


def test_a_message_two_nodes_take_is_decoded_once():
    decoded = []
    estimator, servo = _node("/contour_estimator", ["x", "y"], decoded), _node("/x/servo", ["x", "y"], decoded)
    topic = graph.state_topic("x")
    for k in range(3):
        data = cdr.encode_joint_state(*graph.step_to_stamp(k, 1_000_000), ["x"], [0.1 * k], [1.0])
        first, second = estimator._checked_inputs(k, {topic: data}), servo._checked_inputs(k, {topic: data})
        assert first[topic].position == second[topic].position == pytest.approx([0.1 * k])
    assert decoded == ["/contour_estimator"] * 3     # the servo never decoded: it got the estimator's message


def test_a_bad_message_is_refused_by_every_node_that_takes_it():
    decoded = []
    nodes = [_node("/contour_estimator", ["x", "y"], decoded), _node("/x/servo", ["x", "y"], decoded)]
    topic = graph.state_topic("x")
    bad = cdr.encode_joint_state(0, 0, ["x"], [math.nan], [1.0])
    for node in nodes:
        with pytest.raises(RunError, match=r"non-finite"):
            node._checked_inputs(0, {topic: bad})
        assert node.rejected == {topic: 1}
    assert len(decoded) == 1


def test_the_same_bytes_under_another_topic_layout_are_checked_again():
    """The same /x/state bytes, valid in one graph, are decoded and checked again, not taken from the shared
    decoding, by a node of another graph in the same process whose /x/state must carry other joint names."""
    decoded = []
    one_graph = _node("/contour_estimator", ["x", "y"], decoded)
    other_graph = _node("/contour_estimator", ["x", "y", "z"], decoded)
    topic = graph.state_topic("x")
    other_graph._topics[topic] = graph.Topic(topic, "sensor_msgs/msg/JointState", "/x/plant", (), (("position", 1),),
                                            names=("u",))
    other_graph._decoded_keys[topic] = other_graph.decoded_key(topic)
    data = cdr.encode_joint_state(0, 0, ["x"], [0.0], [1.0])
    one_graph._checked_inputs(0, {topic: data})
    with pytest.raises(RunError, match=r"joint names \['x'\], expected \['u'\]"):
        other_graph._checked_inputs(0, {topic: data})
    assert len(decoded) == 2
