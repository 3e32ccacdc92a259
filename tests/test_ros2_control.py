"""Node-level: the ``ros2_control`` robot entry drives an arm through joint_trajectory_controller's
contract on wall time, with no simulator node and no ``/clock``: a stand-in for the
controller_manager and the camera driver (tests/ros2_control_standin.py) plays the arm, the
graph's own nodes start with config/graph.yaml's ``ros2_control`` settings, and the arm is
learned and reaches a PREDICTIVE goal.
"""
import math
from pathlib import Path

import pytest
from learned_goal import learn_and_reach

from flexarm_bringup.launcher import NodeProcess, NodeSpec, ros_env, stop_all
from flexarm_core import topics

pytestmark = [pytest.mark.node, pytest.mark.duration(90)]
TARGET = (1.30, -0.20, math.radians(-61))            # Table 10, B6
ROBOT = 'ros2_control'


@pytest.fixture
def stand_in(domain_id, tmp_path):
    """The stand-in arm as a node process of its own, on the test's domain."""
    env = ros_env(domain_id, tmp_path / 'ros_log')
    env['PYTHONPATH'] = f'{Path(__file__).parent}:{env.get("PYTHONPATH", "")}'
    node = NodeProcess(NodeSpec(name='ros2_control_standin', module='ros2_control_standin'),
                       env, tmp_path / 'ros2_control_standin.log')
    node.start()
    yield node
    assert stop_all([node])[node.spec.name] is not None, 'the stand-in could not be stopped'


def test_a_ros2_control_arm_is_learned_and_reached_through_trajectories_without_a_clock(
        stand_in, launch, ready_client, tmp_path):
    launch('flexarm_vision', robot=ROBOT, tool_calibration_file=str(tmp_path / 'none.json'),
           camera_calibration_file=str(tmp_path / 'none_camera.json'))
    launch('flexarm_learner', robot=ROBOT, data_directory=str(tmp_path / 'data'),
           model_directory=str(tmp_path / 'models'))
    launch('flexarm_compensator', robot=ROBOT)
    client = ready_client()

    learn_and_reach(client, 8, 'arm', TARGET, collect_timeout=240)

    assert client.count_publishers(topics.CLOCK) == 0
    assert client.count_publishers(topics.absolute(topics.JOINT_COMMANDS)) == 0
    trajectories = client.get_publishers_info_by_topic(topics.absolute(topics.JOINT_TRAJECTORY))
    assert {p.node_name for p in trajectories} == {'flexarm_learner', 'flexarm_compensator'}
