"""ArmInterface waits under use_sim_time: they count sim time, starting at the first /clock."""
import threading
import time

import pytest
import rclpy
from rclpy.clock import ClockType
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from flexarm_control import topics
from flexarm_control.arm_interface import ArmInterface

pytestmark = pytest.mark.node
START = 1000.0      # [s] sim time of the first /clock


@pytest.fixture
def sim_time_node(domain_id):
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = rclpy.create_node('arm_interface_test', context=context,
                             parameter_overrides=[Parameter('use_sim_time', value=True)])
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    try:
        yield node
    finally:
        executor.shutdown(timeout_sec=2.0)
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_a_wait_begun_before_the_first_clock_lasts_its_timeout_in_sim_time(sim_time_node):
    node = sim_time_node
    arm = ArmInterface(node)
    clock = node.create_publisher(Clock, topics.CLOCK, 10)
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
    assert node.get_clock().now().nanoseconds == 0          # no /clock yet
    thread.start()
    try:
        assert not arm.wait_until(lambda: False, timeout=2.0)
        ended = node.get_clock().now().nanoseconds * 1e-9
    finally:
        running.set()
        thread.join(timeout=2.0)
    assert ended >= START + 2.0               # not cut short by the jump from 0 to START
