"""Node-level: no goal holds the arm for ever, and a bad goal never moves it.

A goal whose only client was killed mid-move is cancelled by the compensator within seconds,
the arm held where it was, and the next `flexarm move` runs; a goal beyond the bounds (the
tester's: 10**9 corrections, a 1e-12 m tolerance, phi = 1e9 rad) is refused with INVALID_GOAL
and nothing moves; `flexarm cancel` ends a goal another process sent, says who sent it, and
exits 6 when nothing runs. The goals' senders are raw rclpy action clients in processes of
their own (tests/abandoned_goal.py); this process holds no MoveToPose client while they run,
or it would be one of the goal's possible senders. No camera: the goals end mid-move.
"""
from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
import rclpy
from abandoned_goal import B4, GoalSender, abandoned_goal_s
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import JointState
from test_cli import A1, Cli, no_cli_left  # noqa: F401  (no_cli_left: autouse fixture)

from flexarm_bringup.outcome_text import Exit
from flexarm_control import liveness, topics
from flexarm_control.goal_bounds import SENDER_CHECK
from flexarm_control.kinematics import ArmGeometry, forward
from flexarm_control.params import load_config
from flexarm_msgs.action import MoveToPose

pytestmark = pytest.mark.node
Result = MoveToPose.Result
# [s, wall, scaled] from the kill to the goal's end: a look for its sender every SENDER_CHECK
# s, the hold, the outcome on its way
ABANDONED_WITHIN = SENDER_CHECK + 2.0
MOVED = 1e-7   # [rad, m] a joint that changes by more than this moved


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


@pytest.fixture
def arm(request, launch, domain_id, wait_for) -> Iterator[Joints]:
    """Simulator (real time unless parametrised: a long move lasts seconds) and compensator;
    the arm's joints, at rest."""
    launch('flexarm_sim', real_time_factor=getattr(request, 'param', 1.0))
    launch('flexarm_compensator')
    joints = Joints(domain_id)
    try:
        joints.at_rest(wait_for)
        yield joints
    finally:
        joints.close()


def test_an_abandoned_goal_is_cancelled_within_seconds_and_the_arm_freed(arm, domain_id,
                                                                         wait_for):
    seconds = abandoned_goal_s(domain_id, timeout=15.0)
    assert seconds < liveness.limit(ABANDONED_WITHIN)
    held = forward(ArmGeometry.from_dict(load_config('arm.yaml')['arm']), arm.at_rest(wait_for))
    assert np.linalg.norm(held[:2] - np.array(B4[:2])) > 0.02          # stopped mid-way
    code, err = Cli('move', *A1, '--mode', 'rigid', domain_id=domain_id).finish(60.0)
    assert code == Exit.OK, err


def test_goals_beyond_the_bounds_are_refused_and_nothing_moves(arm, ready_client, wait_for):
    client = ready_client(learner=False)
    before, still_since = arm.q.copy(), arm.moved_at
    phi = math.radians(float(A1[2]))
    for target_phi, goal, reason in [
        (phi, {'max_corrections': 10**9}, 'max_corrections 1000000000 is beyond 10'),
        (phi, {'position_tolerance': 1e-12}, 'position_tolerance 1e-12 m is below 2e-05 m'),
        (1e9, {}, 'target.phi 1e+09 rad is outside [-pi, pi]'),
        (1e9, {'max_corrections': 10**9, 'position_tolerance': 1e-12}, 'target.phi 1e+09'),
    ]:
        result = client.move_to(float(A1[0]) / 1e3, float(A1[1]) / 1e3, target_phi,
                                mode='closed_loop', timeout=30, **goal)
        assert result.error_code == Result.INVALID_GOAL, result.error_string
        assert reason in result.error_string and result.iterations == 0, result.error_string
    arm.later(wait_for, 0.5)
    assert arm.moved_at == still_since
    np.testing.assert_array_equal(arm.q, before)


@pytest.mark.parametrize('arm', [0.25], indirect=True)     # the move outlasts two commands
def test_flexarm_cancel_ends_a_goal_another_process_sent_and_names_it(arm, domain_id):
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
