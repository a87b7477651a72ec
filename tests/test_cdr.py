"""The nodes' CDR codec agrees with rclpy's serializer both ways.

The bytes are compared through the other side's decoder: rclpy leaves its alignment padding and a few
trailing bytes uninitialised, where the codec writes zeros or nothing.
"""
import pytest

from contouring_ros import cdr

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
