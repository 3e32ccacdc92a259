"""Node-level: simulator camera -> vision node -> /tip_pose agrees with the ground truth."""
import math

import numpy as np
import pytest

from flexarm_control import topics
from flexarm_msgs.msg import TipPose

pytestmark = pytest.mark.node


def test_settled_tip_pose_matches_the_truth(launch, ros_node, wait_for):
    measured: list[TipPose] = []
    truth: dict[float, np.ndarray] = {}

    def on_truth(msg: TipPose) -> None:
        truth[msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9] = np.array(
            [msg.pose.x, msg.pose.y, msg.pose.phi])

    ros_node.create_subscription(TipPose, topics.TIP_POSE, measured.append, 10)
    ros_node.create_subscription(TipPose, topics.TIP_POSE_TRUTH, on_truth, 100)
    launch('flexarm_sim', real_time_factor=2.0)
    launch('flexarm_vision')
    wait_for(lambda: sum(m.valid and m.settled for m in measured) >= 5, 40.0,
             '5 valid, settled tip poses')
    compared = 0
    for m in [m for m in measured if m.valid and m.settled]:
        stamp = m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
        if stamp not in truth:
            continue
        error = np.array([m.pose.x, m.pose.y, m.pose.phi]) - truth[stamp]
        assert math.hypot(error[0], error[1]) < 0.2e-3          # issue 4: max 0.2 mm
        assert abs(error[2]) < math.radians(0.01)
        assert m.holes_used >= 9 and m.status == ''
        compared += 1
    assert compared >= 3
