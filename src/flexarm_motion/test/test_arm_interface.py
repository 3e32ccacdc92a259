"""ArmInterface waits under use_sim_time: they count sim time, starting at the first /clock."""
import threading
import time
from collections.abc import Iterator

import pytest
import rclpy
from rclpy.clock import ClockType
from rosgraph_msgs.msg import Clock

from flexarm_core import topics
from flexarm_motion.ros.arm_interface import ArmInterface

pytestmark = pytest.mark.node
START = 1000.0      # [s] sim time of the first /clock


@pytest.fixture
def sim_clock(ros_node) -> Iterator[None]:
    """/clock from START at 10x, after 0.3 s of silence, while the test runs."""
    clock = ros_node.create_publisher(Clock, topics.CLOCK, 10)
    running = threading.Event()

    def publish_clock() -> None:
        time.sleep(0.3)
        begin = time.monotonic()
        while not running.is_set():
            t = START + 10 * (time.monotonic() - begin)
            clock.publish(Clock(clock=rclpy.time.Time(
                seconds=t, clock_type=ClockType.ROS_TIME).to_msg()))
            time.sleep(0.005)

    thread = threading.Thread(target=publish_clock, daemon=True)
    assert ros_node.get_clock().now().nanoseconds == 0          # no /clock yet
    thread.start()
    yield
    running.set()
    thread.join(timeout=2.0)


def sim_now(node) -> float:
    return node.get_clock().now().nanoseconds * 1e-9


@pytest.mark.parametrize('ros_node', [{'use_sim_time': True}], indirect=True)
def test_a_wait_begun_before_the_first_clock_lasts_its_timeout_in_sim_time(ros_node, sim_clock):
    arm = ArmInterface(ros_node)
    assert not arm.wait_until(lambda: False, timeout=2.0)
    assert sim_now(ros_node) >= START + 2.0       # not cut short by the jump from 0 to START


@pytest.mark.parametrize('ros_node', [{'use_sim_time': True}], indirect=True)
def test_a_wait_counts_its_timeout_from_when_counting_begins(ros_node, sim_clock):
    """A sensor just subscribed (its discovery takes wall time) is not timed out meanwhile."""
    arm = ArmInterface(ros_node)
    opens, began = time.monotonic() + 1.0, []

    def counting() -> bool:
        if time.monotonic() < opens:
            return False
        began.append(sim_now(ros_node))
        return True

    assert not arm.wait_until(lambda: False, timeout=2.0, counting=counting)
    assert began and began[0] > START and sim_now(ros_node) >= began[0] + 2.0
    assert len(began) == 1                       # asked until it first holds, then no more
