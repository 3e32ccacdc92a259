"""ArmInterface waits under use_sim_time: they count sim time, starting at the first /clock."""
import threading
import time

import pytest
import rclpy
from rclpy.clock import ClockType
from rosgraph_msgs.msg import Clock

from flexarm_control.ros.arm_interface import ArmInterface
from flexarm_core import topics

pytestmark = pytest.mark.node
START = 1000.0      # [s] sim time of the first /clock


@pytest.mark.parametrize('ros_node', [{'use_sim_time': True}], indirect=True)
def test_a_wait_begun_before_the_first_clock_lasts_its_timeout_in_sim_time(ros_node):
    arm = ArmInterface(ros_node)
    clock = ros_node.create_publisher(Clock, topics.CLOCK, 10)
    running = threading.Event()

    def publish_clock() -> None:               # 0.3 s of silence, then sim time at 10x
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
    try:
        assert not arm.wait_until(lambda: False, timeout=2.0)
        ended = ros_node.get_clock().now().nanoseconds * 1e-9
    finally:
        running.set()
        thread.join(timeout=2.0)
    assert ended >= START + 2.0               # not cut short by the jump from 0 to START

