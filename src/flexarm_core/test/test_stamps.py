"""A node's data time: the newest stamp seen, from messages or their serialized bytes."""
import pytest
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from flexarm_core.ros.stamps import DataTime, raw_stamp_ns, to_ns


def test_data_time_is_zero_until_data_then_the_newest_stamp_never_back() -> None:
    time = DataTime()
    assert time.stamp() == Time()                   # "no time yet"
    time.saw(Time(sec=12, nanosec=500))
    time.saw(Time(sec=11, nanosec=999))             # a late image: older than the newest
    assert time.stamp() == Time(sec=12, nanosec=500)
    time.saw_ns(13_000_000_001)
    assert time.stamp() == Time(sec=13, nanosec=1) and to_ns(time.stamp()) == time.ns


def test_the_stamp_of_a_serialized_clock_or_header_message() -> None:
    clock = Time(sec=1_234_567, nanosec=890)
    assert raw_stamp_ns(serialize_message(Clock(clock=clock))) == to_ns(clock)
    joints = JointState(header=Header(stamp=Time(sec=3, nanosec=7), frame_id='base_link'),
                        name=['joint1'], position=[0.5])
    assert raw_stamp_ns(serialize_message(joints)) == 3_000_000_007
    big_endian = b'\x00\x00\x00\x00' + (2).to_bytes(4, 'big') + (9).to_bytes(4, 'big')
    assert raw_stamp_ns(big_endian) == 2_000_000_009


@pytest.mark.node
def test_graph_time_is_wall_time_by_default(ros_node) -> None:
    import time

    from flexarm_core.ros.stamps import GraphTime

    assert abs(to_ns(GraphTime(ros_node).stamp()) * 1e-9 - time.time()) < 5.0


@pytest.mark.node
@pytest.mark.parametrize('ros_node', [{'sim_clock': True}], indirect=True)
def test_graph_time_on_a_simulated_graph_is_the_newest_clock(ros_node, wait_for) -> None:
    """A node off /clock in a simulated graph stamps what is about now with the newest /clock,
    taken unasked; 0 (no time yet) until one is heard, never the wall clock."""
    from flexarm_core import topics
    from flexarm_core.ros.stamps import GraphTime

    graph = GraphTime(ros_node)
    assert to_ns(graph.stamp()) == 0
    clock = ros_node.create_publisher(Clock, topics.CLOCK, 10)
    wait_for(lambda: ros_node.count_subscribers(topics.CLOCK), 10.0, 'the /clock subscriber')
    for sec in (41, 42):
        clock.publish(Clock(clock=Time(sec=sec, nanosec=5)))
    wait_for(lambda: graph.stamp().sec == 42, 10.0, 'the newest /clock')
    assert graph.stamp() == Time(sec=42, nanosec=5)
