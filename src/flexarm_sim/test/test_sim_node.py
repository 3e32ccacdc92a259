"""The simulated controller as a node: ros2_control topic contract, sim clock, bad commands."""
import math

import numpy as np
import pytest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from flexarm_control import topics
from flexarm_msgs.msg import TipPose

pytestmark = pytest.mark.node
START = [0.0, 0.6, -0.5, -0.5]


@pytest.fixture
def sim(launch, ros_node, wait_for):
    """The sim node at 10x real time, and what the test node hears from it."""
    heard = {'joints': None, 'clock': None, 'truth': None}
    ros_node.create_subscription(JointState, topics.JOINT_STATES,
                                 lambda m: heard.__setitem__('joints', m), 10)
    ros_node.create_subscription(Clock, topics.CLOCK, lambda m: heard.__setitem__('clock', m), 10)
    ros_node.create_subscription(TipPose, topics.TIP_POSE_TRUTH,
                                 lambda m: heard.__setitem__('truth', m), 10)
    command = ros_node.create_publisher(Float64MultiArray, topics.JOINT_COMMANDS, 10)
    launch('flexarm_sim', real_time_factor=10.0, initial_positions=START)
    wait_for(lambda: heard['joints'] is not None and heard['clock'] is not None
             and command.get_subscription_count(), 20.0,
             'the simulator')
    return heard, command


def positions(msg: JointState) -> np.ndarray:
    return np.array(msg.position)


def test_command_moves_the_joints_there(sim, wait_for):
    heard, command = sim
    msg = heard['joints']
    assert list(msg.name) == ['joint1', 'joint2', 'joint3', 'joint4']
    np.testing.assert_allclose(positions(msg), START)
    target = [0.2, 0.65, -0.6, -0.3]
    command.publish(Float64MultiArray(data=target))
    wait_for(lambda: np.allclose(positions(heard['joints']), target, atol=1e-9), 20.0,
             'the joints to reach the command')
    assert heard['clock'].clock.sec >= 1                       # sim time advances
    truth = heard['truth']
    assert truth.valid and math.isfinite(truth.pose.x)


@pytest.mark.parametrize('bad', [
    [0.1, 0.6, -0.5],                       # wrong length
    [0.1, float('nan'), -0.5, -0.5],        # not finite
    [0.1, 0.95, -0.5, -0.5],                # joint2 beyond its 0.8 m limit
    [0.1, 0.6, 1.5, -0.5],                  # joint3 beyond +60 deg
])
def test_bad_command_is_refused_and_nothing_moves(sim, wait_for, bad):
    heard, command = sim
    command.publish(Float64MultiArray(data=bad))
    stamp = heard['clock'].clock.sec
    wait_for(lambda: heard['clock'].clock.sec >= stamp + 2, 20.0, '2 s of sim time')
    np.testing.assert_allclose(positions(heard['joints']), START)
    assert not any(heard['joints'].velocity)
