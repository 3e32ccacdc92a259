"""The topic contracts send a move only to a controller that listens: a command published
before its subscription matched would be lost, and the move would wait out its time limit."""
import threading

import numpy as np
import pytest
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from flexarm_core import topics
from flexarm_core.params import load_config
from flexarm_motion.ros import joint_commands

pytestmark = pytest.mark.node
START = np.array([0.0, 0.5, -0.5, -0.3])
TARGET = np.array([0.1, 0.6, -0.4, -0.2])
CONTRACTS = {'forward': (Float64MultiArray, topics.JOINT_COMMANDS),
             'trajectory': (JointTrajectory, topics.JOINT_TRAJECTORY)}


def contract(node, kind: str) -> joint_commands.JointCommands:
    config = load_config('arm.yaml', 'motion.yaml')
    return joint_commands.joint_commands(node, {**config['motion'], 'joint_commands': kind},
                                         config['arm'], lambda: 0.0)


@pytest.mark.parametrize('kind', CONTRACTS)
def test_a_move_waits_for_the_controllers_subscription(ros_node, wait_for, kind):
    commands = contract(ros_node, kind)
    sending = threading.Thread(target=commands.send, args=(START, TARGET))
    sending.start()
    sending.join(timeout=0.5)
    assert sending.is_alive()                   # no controller yet: nothing was published
    received = []
    msg_type, topic = CONTRACTS[kind]
    ros_node.create_subscription(msg_type, topic, received.append, 10)   # the controller comes
    wait_for(lambda: received, 10.0, f'the move on {topic}')
    sending.join(timeout=10.0)
    assert not sending.is_alive() and commands.problem == ''
    last = received[0].data if kind == 'forward' else received[0].points[-1].positions
    np.testing.assert_allclose(last, TARGET)


@pytest.mark.parametrize('kind', CONTRACTS)
def test_a_move_without_a_controller_says_so_and_sends_nothing(ros_node, monkeypatch, kind):
    monkeypatch.setattr(joint_commands, 'SERVER_WAIT', 0.2)
    commands = contract(ros_node, kind)
    commands.send(START, TARGET)
    _, topic = CONTRACTS[kind]
    assert commands.problem == (f'no controller subscribes to /{topic}: is it running? '
                                'Nothing was commanded')
    assert ros_node.count_subscribers(topic) == 0
