"""The nodes' CDR codec agrees with rclpy's serializer both ways.

The bytes are compared through the other side's decoder: rclpy leaves its alignment padding and a few
trailing bytes uninitialised, where the codec writes zeros or nothing.
"""
import pytest

from contouring_ros.wire import cdr

rclpy_serialization = pytest.importorskip("rclpy.serialization")


@pytest.mark.parametrize("names,position,velocity,effort", [
    (["x"], [0.1], [-2.5e-3], []),
    (["x", "y", "contour_error", "foot_point_parameter"], [1e-6, -3.0, 0.5, 0.0199], [], []),
    (["ab", "c"], [], [], [1.25, -7.0]),
    ([], [], [], []),
])
def test_joint_state_matches_rclpy(names, position, velocity, effort):
    from sensor_msgs.msg import JointState
    msg = JointState(name=names, position=position, velocity=velocity, effort=effort)
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345_000_000
    expected = rclpy_serialization.serialize_message(msg)
    data = cdr.encode_joint_state(12, 345_000_000, names, position, velocity, effort)
    assert rclpy_serialization.deserialize_message(data, JointState) == msg
    decoded = cdr.decode_joint_state(expected)
    assert (decoded.header.stamp.sec, decoded.header.stamp.nanosec) == (12, 345_000_000)
    assert decoded.name == names
    assert list(decoded.position) == position and list(decoded.velocity) == velocity
    assert list(decoded.effort) == effort
    assert cdr.stamp_ns(data) == 12_345_000_000


@pytest.mark.parametrize("names", [["x", "y", "theta"], ["x", "y", "z", "theta"]])
def test_joint_trajectory_matches_rclpy(names):
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    n = len(names)
    positions = [0.1 * i - 0.02 for i in range(n)]
    velocities = [1e-3 * i for i in range(n)]
    accelerations = [-0.5 * i for i in range(n)]
    point = JointTrajectoryPoint(positions=positions, velocities=velocities, accelerations=accelerations)
    point.time_from_start.sec, point.time_from_start.nanosec = 1, 7_000_000
    msg = JointTrajectory(joint_names=names, points=[point])
    msg.header.stamp.sec, msg.header.stamp.nanosec = 1, 7_000_000
    expected = rclpy_serialization.serialize_message(msg)
    data = cdr.encode_joint_trajectory(1, 7_000_000, names, positions, velocities, accelerations, (1, 7_000_000))
    assert rclpy_serialization.deserialize_message(data, JointTrajectory) == msg
    decoded = cdr.decode_joint_trajectory(expected)
    assert decoded.joint_names == names
    assert list(decoded.points[0].positions) == positions
    assert list(decoded.points[0].accelerations) == accelerations


def test_clock_matches_rclpy():
    from rosgraph_msgs.msg import Clock
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = 3, 999_000_000
    assert cdr.encode_clock(3, 999_000_000) == rclpy_serialization.serialize_message(msg)


def _full(decode_full, data):
    return decode_full(cdr._Reader(data))


def test_cached_layouts_decode_exactly_like_a_full_parse():
    # the same topic again and again (fast path), then messages that differ outside the values: other
    # names of the same length, another frame, a big-endian encapsulation, other array lengths
    first = cdr.encode_joint_state(1, 2, ["x", "y"], [0.5, -1.0], [2.0, 3.0])
    assert cdr.decode_joint_state(first) == _full(cdr._read_joint_state, first)
    for k in range(3):
        data = cdr.encode_joint_state(k, 5 * k, ["x", "y"], [0.1 * k, -k], [k + 0.5, 1e-9])
        assert cdr.decode_joint_state(data) == _full(cdr._read_joint_state, data)
    others = [cdr.encode_joint_state(1, 2, ["a", "b"], [0.5, -1.0], [2.0, 3.0]),
              cdr.encode_joint_state(1, 2, ["x", "y"], [0.5, -1.0], [], [2.0, 3.0]),
              cdr.encode_joint_state(1, 2, ["x", "y"], [0.5, -1.0, 7.0], [2.0])]
    frame = bytearray(first)
    frame[12 + 4] = ord("f")          # the frame_id's NUL replaced: a malformed string, parsed in full
    for data in others + [bytes(frame)]:
        try:
            expected = _full(cdr._read_joint_state, data)
        except Exception as error:
            with pytest.raises(type(error)):
                cdr.decode_joint_state(data)
        else:
            assert cdr.decode_joint_state(data) == expected
    swapped = b"\x00\x00" + first[2:]
    assert all(layout.read(swapped) is None for layout in cdr._JOINT_STATE.layouts[len(first)])


def test_cached_trajectory_templates_and_layouts_round_trip():
    for k in range(3):
        data = cdr.encode_joint_trajectory(k, 0, ["x", "y", "theta"], [k, 1.0, 2.0], [0.0, k, 0.5], [1.0, 2.0, k],
                                           (0, k))
        decoded = cdr.decode_joint_trajectory(data)
        assert decoded == _full(cdr._read_joint_trajectory, data)
        assert decoded.points[0].velocities == (0.0, k, 0.5)
        assert (decoded.points[0].time_from_start.nanosec, decoded.header.stamp.sec) == (k, k)


def test_decoded_messages_do_not_share_the_cached_template():
    data = cdr.encode_joint_state(0, 0, ["p", "q"], [1.0, 2.0])
    first = cdr.decode_joint_state(data)
    first.name.append("changed")
    assert cdr.decode_joint_state(data).name == ["p", "q"]


def test_topics_of_one_length_keep_their_own_layouts():
    x, y = (cdr.encode_joint_state(0, 0, [axis], [1.0], [2.0]) for axis in "xy")
    for _ in range(2):
        assert cdr.decode_joint_state(x).name == ["x"] and cdr.decode_joint_state(y).name == ["y"]
    assert len(cdr._JOINT_STATE.layouts[len(x)]) == 2
