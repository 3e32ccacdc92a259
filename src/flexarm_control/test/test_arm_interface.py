"""ArmInterface waits under use_sim_time: they count sim time, starting at the first /clock;
a move re-sends its command until the joints arrive."""
import threading
import time

import numpy as np
import pytest
import rclpy
from rclpy.clock import ClockType
from rosgraph_msgs.msg import Clock

from flexarm_control import topics
from flexarm_control.arm_interface import ArmInterface

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


def test_a_move_re_sends_its_command_until_the_joints_arrive(ros_node):
    from std_msgs.msg import Float64MultiArray

    from flexarm_control import arm_interface

    heard = []
    ros_node.create_subscription(Float64MultiArray, topics.JOINT_COMMANDS,
                                 lambda m: heard.append(time.monotonic()), 10)
    arm = ArmInterface(ros_node)
    time.sleep(0.5)                                  # the command topic matched
    started = time.monotonic()
    assert not arm.move([0.1, 0.6, 0.0, 0.0], np.full(4, 1e-4), timeout=1.7)  # nobody moves
    time.sleep(0.2)
    sent = [t - started for t in heard]
    assert len(sent) >= 1 + int(1.7 / arm_interface.RESEND) - 1, sent
    assert all(b - a >= 0.8 * arm_interface.RESEND for a, b in zip(sent, sent[1:])), sent
