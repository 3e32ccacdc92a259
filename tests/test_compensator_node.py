"""Node-level: the MoveToPose action server with the simulator and the vision node.

The server and this test's client are separate processes (the interfaces work across
processes). The predictor is fitted here on the simulator's own deflection, so PREDICTIVE is
judged on the node's behaviour, not on learning.
"""
import math
import threading
import time

import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from sensor_msgs.msg import JointState

from flexarm_control import topics
from flexarm_control.client import FlexarmClient, GoalRejected
from flexarm_control.kinematics import ArmGeometry, inverse
from flexarm_control.params import load_config
from flexarm_control.predictors import make_predictor
from flexarm_control.sampling import regions_from_dict, sample_poses
from flexarm_sim.plant import Plant
from flexarm_msgs.action import MoveToPose

pytestmark = pytest.mark.node
Result = MoveToPose.Result
TARGET = (1.30, -0.20, math.radians(-61))          # Table 10, B6


def spin_for(client: FlexarmClient, seconds: float) -> None:
    """Let the client's subscriptions run (the joint states update only while it spins)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        client.spin_once(0.05)


@pytest.fixture(scope='module')
def model_path(tmp_path_factory):
    config = load_config('arm.yaml', 'sim.yaml')
    geometry = ArmGeometry.from_dict(config['arm'])
    plant = Plant.from_dict(config['plant'], geometry)
    region = regions_from_dict(load_config('learner.yaml', node_name='flexarm_learner')[
        'regions'])['B']
    _, joints = sample_poses(geometry, region, 60)
    path = tmp_path_factory.mktemp('model') / 'b.model'
    make_predictor('gp').fit(joints, plant.deflection(joints)).save(path)
    return path


@pytest.fixture
def graph(request, launch, domain_id, model_path):
    """Simulator (10x real time unless parametrised), vision, compensator; a client and the
    latest joint state."""
    launch('flexarm_sim', real_time_factor=getattr(request, 'param', 10.0))
    launch('flexarm_vision')
    launch('flexarm_compensator', model_path=str(model_path))
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    client = FlexarmClient('test_client', context=context)
    joints = {}
    client.create_subscription(JointState, topics.JOINT_STATES,
                               lambda m: joints.__setitem__('q', np.array(m.position)), 10)
    try:
        client.wait_until_ready(timeout=30.0, learner=False)
        deadline = time.monotonic() + 20
        while 'q' not in joints and time.monotonic() < deadline:
            client.spin_once(0.05)
        yield client, joints
    finally:
        client.destroy_node()
        rclpy.try_shutdown(context=context)


def test_rigid_and_predictive_goals_succeed(graph):
    client, _ = graph
    rigid = client.move_to(*TARGET, mode='rigid', timeout=120)
    assert rigid.error_code == Result.SUCCESSFUL, rigid.error_string
    assert rigid.measured and rigid.position_error > 5e-3        # the arm sags ~13 mm
    predictive = client.move_to(*TARGET, mode='predictive', timeout=120)
    assert predictive.error_code == Result.SUCCESSFUL, predictive.error_string
    assert predictive.measured and predictive.position_error < 0.5e-3
    assert predictive.compensation_iterations >= 2
    assert abs(predictive.predicted_deflection.y) > 5e-3


@pytest.mark.parametrize('target, code', [
    ((float('nan'), 0.0, 0.0), Result.INVALID_GOAL),
    ((2.5, 0.0, 0.0), Result.UNREACHABLE),
])
def test_invalid_goal_is_refused_and_nothing_moves(graph, target, code):
    client, joints = graph
    before = joints['q'].copy()
    result = client.move_to(*target, mode='predictive', timeout=30)
    assert result.error_code == code and result.error_string
    spin_for(client, 1.0)
    np.testing.assert_array_equal(joints['q'], before)


@pytest.mark.parametrize('graph', [1.0], indirect=True)      # real time: a 3 s move
def test_cancel_stops_the_arm_and_a_second_goal_is_rejected(graph):
    client, joints = graph
    far = (1.0, -0.5, math.radians(-100))            # B4: a long move from the start pose
    outcome, phases = {}, []
    thread = threading.Thread(target=lambda: outcome.setdefault('result', client.move_to(
        *far, mode='rigid', timeout=120, feedback=lambda fb: phases.append(fb.phase))))
    thread.start()
    deadline = time.monotonic() + 20
    while MoveToPose.Feedback.PHASE_MOVING not in phases and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(0.5)                                   # the arm is on its way
    context = Context()
    rclpy.init(context=context, domain_id=client.context.get_domain_id())
    second = FlexarmClient('second_client', context=context)
    try:
        with pytest.raises(GoalRejected, match='busy'):
            second.move_to(*TARGET, mode='rigid', timeout=20)
    finally:
        second.destroy_node()
        rclpy.try_shutdown(context=context)
    client.cancel()
    thread.join(timeout=30)
    assert outcome['result'].error_code == Result.CANCELED
    spin_for(client, 3.0)                             # braking (and settling back) is over
    stopped = joints['q'].copy()
    spin_for(client, 1.0)
    np.testing.assert_allclose(joints['q'], stopped, atol=1e-9)
    goal = inverse(ArmGeometry.from_dict(load_config('arm.yaml')['arm']), np.array(far))
    assert np.max(np.abs(joints['q'] - goal)) > 0.05
