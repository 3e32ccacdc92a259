"""The simulated controller as a node: ros2_control topic contract, sim clock, bad commands."""
import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
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
    heard = {'joints': None, 'clock': None, 'truth': None, 'health': {}}
    ros_node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS,
                                 lambda m: heard['health'].update(
                                     {s.name: s for s in m.status}), 10)
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
    commands = 'flexarm_sim: commands'
    wait_for(lambda: commands in heard['health'] and heard['health'][commands].level
             == DiagnosticStatus.WARN, 10.0, 'the rejection on /diagnostics')
    values = {v.key: v.value for v in heard['health'][commands].values}
    assert values['commands rejected'] == '1' and values['commands accepted'] == '0'
    assert heard['health'][commands].message.startswith('last command rejected: ')
    assert heard['health']['flexarm_sim: controller'].level == DiagnosticStatus.OK


@pytest.mark.parametrize('on', [True, False])
def test_the_payload_changes_at_run_time_with_its_error_source_on(launch, ros_node, wait_for,
                                                                   on):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from rclpy.qos import QoSDurabilityPolicy, QoSProfile
    from sensor_msgs.msg import CameraInfo

    from flexarm_control.kinematics import ArmGeometry
    from flexarm_control.params import load_config
    from flexarm_sim.plant import Plant

    heard = {'truth': None, 'info': None}
    ros_node.create_subscription(TipPose, topics.TIP_POSE_TRUTH,
                                 lambda m: heard.__setitem__('truth', m), 10)
    ros_node.create_subscription(CameraInfo, topics.CAMERA_INFO,
                                 lambda m: heard.__setitem__('info', m), QoSProfile(
                                     depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL))
    # Every source on (the arm rests: no joint errors; the thermal drift is 0.1 um in 10 s).
    launch('flexarm_sim', real_time_factor=10.0, initial_positions=START,
           error_sources={'enabled': on})
    wait_for(lambda: heard['truth'] is not None and heard['info'] is not None, 20.0,
             'the simulator')
    config = load_config('arm.yaml', 'sim.yaml', 'camera.yaml')
    assert list(heard['info'].k)[:3] == [config['camera']['fx'], 0.0, config['camera']['cx']]
    client = AsyncParameterClient(ros_node, 'flexarm_sim')
    assert client.wait_for_services(10.0)

    def set_payload(value: float):
        future = client.set_parameters([Parameter('plant.payload', value=value)])
        wait_for(future.done, 10.0, 'the parameter service')
        return future.result().results[0]

    def settled_y(seconds: float) -> float:
        stamp = heard['truth'].header.stamp.sec
        wait_for(lambda: heard['truth'].header.stamp.sec >= stamp + seconds, 30.0,
                 f'{seconds} s of sim time')
        return heard['truth'].pose.y

    before = settled_y(1)
    result = set_payload(5.0)
    assert result.successful is on
    if not on:
        assert 'error_sources.payload' in result.reason
        assert settled_y(2) == before
        return
    plant = Plant.from_dict(config['plant'], ArmGeometry.from_dict(config['arm']))
    sag = plant.with_payload(5.0).pose(START)[1] - plant.pose(START)[1]
    assert sag < -5e-3
    assert settled_y(12) - before == pytest.approx(sag, abs=1e-5)
    refused = set_payload(-1.0)
    assert not refused.successful and 'payload must be finite and >= 0' in refused.reason
