"""Node-level: no goal holds the arm for ever, and a bad goal never moves it.

A goal whose only client was killed mid-move is cancelled by the compensator within seconds
(also when a network interface came up between their starts, which gives them different Fast
DDS host ids), the arm held where it was, and the next `flexarm move` runs; a goal beyond the
bounds (the tester's: 10**9 corrections, a 1e-12 m tolerance, phi = 1e9 rad) is refused with
INVALID_GOAL and nothing moves; `flexarm cancel` ends a goal another process sent, says who
sent it, and exits 6 when nothing runs. The goals' senders are raw rclpy action clients in
processes of their own (flexarm_test_support.abandoned_goal); this process holds no MoveToPose
client while they run, or it would be one of the goal's possible senders. No camera: the goals
end mid-move, and a goal that completes its move waits for a tip measurement that never comes.

The tests that leave the arm at rest and no goal running share one graph (:class:`Graph`, at
real time): the abandoned goal runs first, while no client of this process has ever been in
the domain. The cancel test needs a slower simulator: a graph of its own.
"""
from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator

import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import JointState

from flexarm_control.execution.goal_bounds import SENDER_CHECK
from flexarm_core import liveness, topics
from flexarm_core.kinematics import ArmGeometry, forward
from flexarm_core.params import load_config
from flexarm_msgs.action import MoveToPose
from flexarm_recording.results.outcome_text import Exit
from flexarm_test_support.abandoned_goal import B4, GoalSender, abandoned_goal_s
from flexarm_test_support.cli_process import Cli, no_cli_left  # noqa: F401  (autouse fixture)
from flexarm_test_support.remote_peer import RemoteHost

pytestmark = [pytest.mark.node, pytest.mark.duration(50)]
A1 = ('1450', '-150', '-45')   # [mm, mm, deg] Table 10, as the command line takes it
Result = MoveToPose.Result
# [s, wall, scaled] from the kill to the goal's end: a look for its sender every SENDER_CHECK
# s, the hold, the outcome on its way
ABANDONED_WITHIN = SENDER_CHECK + 2.0
MOVED = 1e-7   # [rad, m] a joint that changes by more than this moved
# [s, sim time] the shared graph's compensator waits for a tip measurement after a move (the
# shipped 30 s, config/motion.yaml): none comes without a camera, and an unchecked move
# succeeds without one all the same (`moved; no valid settled tip measurement`)
NO_CAMERA_WAIT = 1.0


class Joints:
    """The arm on /joint_states, seen by a plain node of this process (spun while a wait
    looks): the latest joints and stamp [s, sim time], and the stamp of the last motion."""

    def __init__(self, domain_id: int) -> None:
        self._context = Context()
        rclpy.init(context=self._context, domain_id=domain_id)
        self._node = rclpy.create_node('joint_watch', context=self._context)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        self.q: np.ndarray | None = None
        self.stamp = self.moved_at = 0.0
        self._node.create_subscription(JointState, topics.JOINT_STATES, self._on_joints, 10)

    def _on_joints(self, msg: JointState) -> None:
        q = np.array(msg.position)
        self.stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        if self.q is None or np.max(np.abs(q - self.q)) > MOVED:
            self.moved_at = self.stamp
        self.q = q

    def _spun(self) -> bool:
        self._executor.spin_once(timeout_sec=0.05)
        return True

    def at_rest(self, wait_for, still: float = 0.3) -> np.ndarray:
        """The joints once they have not moved for ``still`` s of the simulator's time."""
        wait_for(lambda: self._spun() and self.q is not None
                 and self.stamp - self.moved_at >= still, 60.0, 'the arm to come to rest')
        return self.q.copy()

    def later(self, wait_for, seconds: float) -> None:
        """Return once ``seconds`` of the simulator's time have passed."""
        since = self.stamp
        wait_for(lambda: self._spun() and self.stamp >= since + seconds, 30.0,
                 f'{seconds} s of sim time')

    def close(self) -> None:
        self._executor.shutdown(timeout_sec=1.0)
        self._node.destroy_node()
        rclpy.try_shutdown(context=self._context)


class Graph:
    """The module's simulator and compensator (started by ``module_launch``) and the arm's
    joints (:class:`Joints`), one graph at a time in the domain (two simulators would both
    publish ``/clock`` and ``/joint_states``): the running one serves the next test that asks
    for the same settings, else it is stopped (and its processes reaped) before the new one
    starts."""

    def __init__(self, launcher, domain_id: int) -> None:
        self._launcher, self._domain_id = launcher, domain_id
        self._settings: tuple | None = None
        self._nodes: list = []
        self._joints: Joints | None = None

    def start(self, real_time_factor: float, **compensator) -> Joints:
        """The graph of these settings, running; its arm's joints."""
        settings = (real_time_factor, sorted(compensator.items()))
        if (settings != self._settings or self._joints is None
                or any(n.returncode is not None for n in self._nodes)):
            self.stop()
            self._nodes = [self._launcher('flexarm_sim', real_time_factor=real_time_factor),
                           self._launcher('flexarm_compensator', **compensator)]
            self._settings, self._joints = settings, Joints(self._domain_id)
        return self._joints

    def stop(self) -> None:
        if self._joints is not None:
            self._joints.close()
            self._joints = None
        self._launcher.stop_all()


@pytest.fixture(scope='module')
def graph(module_launch, domain_id) -> Iterator[Graph]:
    graph = Graph(module_launch, domain_id)
    yield graph
    graph.stop()


@pytest.fixture
def arm(graph, wait_for) -> Joints:
    """Simulator at real time (a long move lasts seconds) and compensator, the graph of the
    tests that leave the arm at rest and no goal running; a move waits :data:`NO_CAMERA_WAIT`
    for a tip measurement. The arm, at rest."""
    joints = graph.start(1.0, motion={'measurement_timeout': NO_CAMERA_WAIT})
    joints.at_rest(wait_for)
    return joints


@pytest.fixture
def slow_blind_arm(graph, wait_for) -> Joints:
    """Simulator at a quarter of real time (a long move lasts some 10 s), and the compensator
    of :func:`arm`, a move waiting :data:`NO_CAMERA_WAIT` for a tip measurement; the arm, at
    rest."""
    joints = graph.start(0.25, motion={'measurement_timeout': NO_CAMERA_WAIT})
    joints.at_rest(wait_for)
    return joints


@pytest.fixture
def slow_arm(graph, wait_for) -> Joints:
    """Simulator at a quarter of real time (a long move outlasts two commands) and the
    compensator as shipped; the arm, at rest."""
    joints = graph.start(0.25)
    joints.at_rest(wait_for)
    return joints


def test_goals_beyond_the_bounds_are_refused_and_nothing_moves(arm, ready_client, wait_for):
    client = ready_client(learner=False)
    before, still_since = arm.q.copy(), arm.moved_at
    x, y, phi = B4      # far from where the arm rests: the start pose, or A1 (a test before)
    for target_phi, goal, reason in [
        (phi, {'max_corrections': 10**9}, 'max_corrections 1000000000 is beyond 10'),
        (phi, {'position_tolerance': 1e-12}, 'position_tolerance 1e-12 m is below 2e-05 m'),
        (1e9, {}, 'target.phi 1e+09 rad is outside [-pi, pi]'),
        (1e9, {'max_corrections': 10**9, 'position_tolerance': 1e-12}, 'target.phi 1e+09'),
    ]:
        result = client.move_to(x, y, target_phi, mode='closed_loop', timeout=30, **goal)
        assert result.error_code == Result.INVALID_GOAL, result.error_string
        assert reason in result.error_string and result.iterations == 0, result.error_string
    arm.later(wait_for, 0.5)
    assert arm.moved_at == still_since
    np.testing.assert_array_equal(arm.q, before)


@pytest.mark.parametrize('interface_came_up', [False, True], ids=['', 'interface_came_up'])
def test_an_abandoned_goal_is_cancelled_within_seconds_and_the_arm_freed(
        slow_blind_arm, domain_id, wait_for, interface_came_up):
    """At a quarter of real time the move to B4 lasts some 10 s: the sender's death is seen
    mid-move however late a loaded machine lets the sender say it moves (at real time the
    2.4 s move once ended first, and the goal failed its measurement instead). Then a short
    move from where the arm stopped: it is free. ``interface_came_up``: a network interface
    with an address came up after the compensator started and before the sender did, which
    gives the sender another Fast DDS host id; its process tells that it left all the same."""
    with RemoteHost.made() if interface_came_up else contextlib.nullcontext():
        seconds = abandoned_goal_s(domain_id, timeout=15.0)
    assert seconds < liveness.limit(ABANDONED_WITHIN)
    held = forward(ArmGeometry.from_dict(load_config('arm.yaml')['arm']),
                   slow_blind_arm.at_rest(wait_for))
    assert np.linalg.norm(held[:2] - np.array(B4[:2])) > 0.02          # stopped mid-way
    x, y = (held[:2] + [0.0, 0.02]) * 1e3                              # [mm], 20 mm up
    code, err = Cli('move', f'{x:.1f}', f'{y:.1f}', f'{math.degrees(held[2]):.2f}', '--mode',
                    'rigid', domain_id=domain_id).finish(60.0)
    assert code == Exit.OK, err


def test_flexarm_cancel_ends_a_goal_another_process_sent_and_names_it(slow_arm, domain_id):
    sender = GoalSender(domain_id, name='goal_sender')
    try:
        sender.wait_for('moving', liveness.limit(30.0))
        code, err = Cli('move', *A1, '--mode', 'rigid', domain_id=domain_id).finish(60.0)
        assert code == Exit.BUSY and 'end it with `flexarm cancel`' in err, err
        cancel = Cli('cancel', domain_id=domain_id)
        code, err = cancel.finish(60.0)
        assert code == Exit.OK, err
        said = '\n'.join(cancel.out)
        assert '/move_to_pose goal ' in said and '(sent by /goal_sender)' in said, said
        assert 'cancelled; arm stopped at x=' in said, said
        result = sender.wait_for('result', liveness.limit(15.0))
        assert result.startswith(f'result {Result.CANCELED} canceled; arm held; goal sent by '
                                 '/goal_sender'), result
    finally:
        sender.kill()
    code, err = Cli('cancel', domain_id=domain_id).finish(60.0)
    assert code == Exit.NOTHING_TO_CANCEL and 'nothing to cancel' in err, err
