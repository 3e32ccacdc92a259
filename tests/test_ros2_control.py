"""Node-level: the ``ros2_control`` robot entry drives an arm through joint_trajectory_controller's
FollowJointTrajectory action on wall time, with no simulator node and no ``/clock``. The steps
of docs/connecting-your-arm.md's recipe, as written: a stand-in for the controller_manager and
the camera driver (flexarm_test_support.ros2_control_standin) starts first, in the domain, and
brings its controllers up only once ``/robot_description`` reaches it; then ``flexarm up
--robot ros2_control --domain-id N``, whose state publisher serves it. The arm is learned and
reaches a PREDICTIVE goal through the action; a goal beyond the stand-in's hardware limits
(narrower than flexarm's) fails with the controller's reason. The tests share one graph
(learning it is what takes the time).
"""
import math
import os
import signal
import subprocess
import sys

import pytest
from action_msgs.msg import GoalStatus, GoalStatusArray
from rclpy.qos import QoSDurabilityPolicy, QoSProfile

from flexarm_bringup.launcher import NodeProcess, NodeSpec, ros_env, stop_all
from flexarm_core import liveness, topics
from flexarm_msgs.action import MoveToPose
from flexarm_test_support.learned_goal import learn_and_reach

pytestmark = [pytest.mark.node, pytest.mark.duration(65)]
TARGET = (1.30, -0.20, math.radians(-61))            # Table 10, B6
ROBOT = 'ros2_control'
# The stand-in's joint1 stops at 1 rad (flexarm's at pi): region B and TARGET lie within,
# this pose (joint1 1.62 rad) does not.
JOINT1_LIMIT = 1.0
BEYOND = (0.30, 1.20, math.radians(90))
ACTION = topics.absolute(topics.FOLLOW_JOINT_TRAJECTORY)
# Runs the command line of its arguments in this process once a line came on stdin: started
# in the domain before the run lends it (conftest's DomainPool.lent).
GATED = 'import os, sys; sys.stdin.readline(); os.execv(sys.argv[1], sys.argv[1:])'


@pytest.fixture(scope='module')
def stand_in(domain_id, tmp_path_factory):
    """The stand-in arm as a node process of its own, on the module's domain."""
    folder = tmp_path_factory.mktemp('stand_in')
    env = ros_env(domain_id, folder / 'ros_log')
    upper = [JOINT1_LIMIT, 0.80, 1.0471975511965976, 2.0943951023931953]
    spec = NodeSpec(name='ros2_control_standin',
                    module='flexarm_test_support.ros2_control_standin')
    node = NodeProcess(spec, env, folder / 'ros2_control_standin.log', {'arm.upper': upper})
    node.start()
    yield node
    assert stop_all([node])[node.spec.name] is not None, 'the stand-in could not be stopped'


@pytest.fixture(scope='module')
def graph(stand_in, domain_id, domain_pool):
    """``flexarm up --robot ros2_control --domain-id N`` (in the run's state folder), once
    ready; stopped as Ctrl-C stops it."""
    up = subprocess.Popen(
        [sys.executable, '-c', GATED, sys.executable, '-m', 'flexarm_cli', 'up',
         '--robot', ROBOT, '--domain-id', str(domain_id), '--timeout',
         str(liveness.limit(60.0))], env={**os.environ, 'PYTHONUNBUFFERED': '1'},
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    with domain_pool.lent(domain_id):
        up.stdin.write('go\n')
        up.stdin.flush()
        try:
            started, ready = up.stdout.readline(), up.stdout.readline()
            assert 'graph ready' in ready, (started, ready, '' if ready else up.stderr.read())
            yield up
        finally:
            up.send_signal(signal.SIGINT)
            try:
                up.communicate(timeout=liveness.limit(30.0))
            except subprocess.TimeoutExpired:
                up.kill()
                pytest.fail('flexarm up did not stop on SIGINT')


def goal_statuses(client):
    """The FollowJointTrajectory goals' final statuses the test's client hears, by goal id."""
    ended: dict[bytes, int] = {}
    finals = {GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_ABORTED,
              GoalStatus.STATUS_CANCELED}

    def heard(msg: GoalStatusArray) -> None:
        for status in msg.status_list:
            if status.status in finals:
                ended[bytes(status.goal_info.goal_id.uuid)] = status.status
    client.create_subscription(
        GoalStatusArray, f'{ACTION}/_action/status', heard,
        QoSProfile(depth=100, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL))
    return ended


def test_a_ros2_control_arm_is_learned_and_reached_through_the_action_without_a_clock(
        graph, ready_client):
    client = ready_client()
    ended = goal_statuses(client)

    learn_and_reach(client, 8, 'arm', TARGET, collect_timeout=240)

    assert client.count_publishers(topics.CLOCK) == 0
    assert client.count_publishers(topics.absolute(topics.JOINT_COMMANDS)) == 0
    assert client.count_publishers(topics.absolute(topics.JOINT_TRAJECTORY)) == 0
    senders = {name for name, ns in client.get_node_names_and_namespaces()
               if f'{ACTION}/_action/send_goal' in dict(
                   client.get_client_names_and_types_by_node(name, ns))}
    assert senders == {'flexarm_learner', 'flexarm_compensator'}
    # every pose's approach and final leg, and the goal's: each a goal the controller ran
    # (succeeded, or preempted by the next once flexarm saw the joints arrive)
    assert len(ended) >= 2 * (8 + 1), ended


def test_a_goal_beyond_the_controllers_limits_fails_with_its_reason(graph, ready_client):
    client = ready_client()
    moved = client.move_to(*BEYOND, mode='rigid', timeout=60)
    assert moved.error_code == MoveToPose.Result.CONTROLLER_TIMEOUT, moved.error_string
    assert ('joint_trajectory_controller aborted the move: INVALID_GOAL (joint1 position'
            in moved.error_string), moved.error_string
    assert f'beyond the hardware limits [-3.1416, {JOINT1_LIMIT:.4f}]' in moved.error_string
