"""The simulated controller as a node: ros2_control topic contract, sim clock, bad commands.

The tests that only command the simulator share one (:class:`SharedSim`): each bad command
test finds the arm at START and counts its own rejection; the test whose command moves the arm
retires it, and the payload tests, which set up their own error sources, run alone.
"""
import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from flexarm_core import topics
from flexarm_msgs.msg import TipPose

pytestmark = [pytest.mark.node, pytest.mark.duration(15)]
START = [0.0, 0.6, -0.5, -0.5]
COMMANDS = 'flexarm_sim: commands'


class SharedSim:
    """The module's simulator at 10x real time from START, started when a test first needs it
    and shared until a test retires it (it moved the arm or had a command accepted) or needs
    the domain to itself; a test that fails retires it too. ``rejected``: the bad commands
    sent to the running one; ``spent``: the test changed it, it is retired after the test."""

    def __init__(self, launcher) -> None:
        self._launcher = launcher
        self.running, self.spent = False, False
        self.rejected = 0

    def use(self, request: pytest.FixtureRequest) -> None:
        """Start it unless it runs; retire it after the test if the test spent it or failed."""
        if not self.running:
            self._launcher('flexarm_sim', real_time_factor=10.0, initial_positions=START)
            self.running, self.rejected = True, 0
        self.spent, failed = False, request.session.testsfailed

        def after() -> None:
            if self.spent or request.session.testsfailed > failed:
                self.retire()
        request.addfinalizer(after)

    def retire(self) -> None:
        """Stop it (and check it was reaped): the next test that needs it gets a fresh one."""
        self._launcher.stop_all()
        self._launcher.started.clear()
        self.running = False


@pytest.fixture(scope='module')
def shared_sim(module_launch):
    shared = SharedSim(module_launch)
    yield shared
    shared.retire()


@pytest.fixture
def alone(shared_sim):
    """No shared simulator on the domain: the test starts its own."""
    shared_sim.retire()


@pytest.fixture
def sim(shared_sim, ros_node, wait_for, request):
    """The shared sim node (10x real time, from START), and what the test node hears from it."""
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
    shared_sim.use(request)
    wait_for(lambda: heard['joints'] is not None and heard['clock'] is not None
             and command.get_subscription_count(), 20.0,
             'the simulator')
    return heard, command


def positions(msg: JointState) -> np.ndarray:
    return np.array(msg.position)


def seconds(msg: Clock) -> float:
    return msg.clock.sec + msg.clock.nanosec * 1e-9


@pytest.mark.parametrize('bad', [
    [0.1, 0.6, -0.5],                       # wrong length
    [0.1, float('nan'), -0.5, -0.5],        # not finite
    [0.1, 0.95, -0.5, -0.5],                # joint2 beyond its 0.8 m limit
    [0.1, 0.6, 1.5, -0.5],                  # joint3 beyond +60 deg
])
def test_bad_command_is_refused_and_nothing_moves(sim, shared_sim, wait_for, bad):
    heard, command = sim
    command.publish(Float64MultiArray(data=bad))
    shared_sim.rejected += 1                # this one, after the shared sim's earlier ones
    stamp = heard['clock'].clock.sec
    wait_for(lambda: heard['clock'].clock.sec >= stamp + 2, 20.0, '2 s of sim time')
    np.testing.assert_allclose(positions(heard['joints']), START)
    assert not any(heard['joints'].velocity)

    def values(status: DiagnosticStatus) -> dict[str, str]:
        return {v.key: v.value for v in status.values}

    def rejection() -> DiagnosticStatus | None:   # the status that counts this one
        status = heard['health'].get(COMMANDS)
        return status if status and int(values(status)['commands rejected']
                                        ) >= shared_sim.rejected else None

    status = wait_for(rejection, 10.0, 'the rejection on /diagnostics')
    assert status.level == DiagnosticStatus.WARN
    counts = values(status)
    assert counts['commands rejected'] == str(shared_sim.rejected)
    assert counts['commands accepted'] == '0'
    assert status.message.startswith('last command rejected: ')
    assert heard['health']['flexarm_sim: controller'].level == DiagnosticStatus.OK


def test_command_moves_the_joints_there(sim, shared_sim, wait_for):
    heard, command = sim
    msg, started = heard['joints'], seconds(heard['clock'])
    assert list(msg.name) == ['joint1', 'joint2', 'joint3', 'joint4']
    np.testing.assert_allclose(positions(msg), START)
    target = [0.2, 0.65, -0.6, -0.3]
    shared_sim.spent = True                 # the arm moves and a command is accepted
    command.publish(Float64MultiArray(data=target))
    wait_for(lambda: np.allclose(positions(heard['joints']), target, atol=1e-9), 20.0,
             'the joints to reach the command')
    # /clock advances with the move (1.6 s of sim time); its messages may come after the
    # joint states that end the move, so this waits for them rather than reading the latest
    wait_for(lambda: seconds(heard['clock']) >= started + 1, 20.0, '/clock to advance 1 s')
    truth = heard['truth']
    assert truth.valid and math.isfinite(truth.pose.x)


@pytest.mark.parametrize('on', [True, False])
def test_the_payload_changes_at_run_time_with_its_error_source_on(alone, launch, ros_node,
                                                                   wait_for, on):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from rclpy.qos import QoSDurabilityPolicy, QoSProfile
    from sensor_msgs.msg import CameraInfo

    from flexarm_core.kinematics import ArmGeometry
    from flexarm_core.params import load_config
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
