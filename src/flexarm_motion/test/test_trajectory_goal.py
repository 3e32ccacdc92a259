"""What a FollowJointTrajectory goal asks of joint_trajectory_controller, and how its answer
reads as a move's failure."""
import pytest
from action_msgs.msg import GoalStatus
from trajectory_msgs.msg import JointTrajectory

from control_msgs.action import FollowJointTrajectory
from flexarm_core.kinematics import JOINT_NAMES
from flexarm_core.params import load_config
from flexarm_motion.ros.trajectory_goal import (
    TrajectoryTolerances,
    failure,
    goal_message,
    rejection,
)

Result = FollowJointTrajectory.Result


@pytest.fixture(scope='module')
def configured():
    config = load_config('arm.yaml', 'motion.yaml')
    return TrajectoryTolerances.from_dicts(config['arm'], config['motion'])


def test_the_goal_carries_the_configured_tolerances_per_joint(configured):
    config = load_config('arm.yaml', 'motion.yaml')
    names = ['joint3', 'joint1', 'joint4', 'joint2']        # the trajectory's own order
    goal = goal_message(JointTrajectory(joint_names=names), configured)
    assert [t.name for t in goal.path_tolerance] == names
    assert [t.name for t in goal.goal_tolerance] == names
    assert [t.position for t in goal.path_tolerance] == list(configured.path)
    # the goal tolerance is where flexarm counts the joints as arrived
    assert [t.position for t in goal.goal_tolerance] == config['motion']['arrival_tolerance']
    assert all(t.velocity == 0 and t.acceleration == 0      # the controller's own
               for t in [*goal.path_tolerance, *goal.goal_tolerance])
    assert (goal.goal_time_tolerance.sec + 1e-9 * goal.goal_time_tolerance.nanosec
            == config['arm']['trajectory_tolerance']['goal_time'])


def test_a_fractional_goal_time_is_split_into_seconds_and_nanoseconds(configured):
    tolerances = TrajectoryTolerances(configured.path, configured.goal, 2.25)
    goal = goal_message(JointTrajectory(joint_names=list(JOINT_NAMES)), tolerances)
    assert (goal.goal_time_tolerance.sec, goal.goal_time_tolerance.nanosec) == (2, 250_000_000)


@pytest.mark.parametrize('change, named', [
    ({'path': [0.1, 0.01, 0.1]}, 'path'),
    ({'path': [0.1, 0.0, 0.1, 0.1]}, 'path'),
    ({'goal_time': 0.0}, 'goal_time'),
])
def test_tolerances_out_of_range_are_refused_by_name(change, named):
    config = load_config('arm.yaml', 'motion.yaml')
    arm = {**config['arm'], 'trajectory_tolerance': {**config['arm']['trajectory_tolerance'],
                                                     **change}}
    with pytest.raises(ValueError, match=f'trajectory_tolerance.{named}'):
        TrajectoryTolerances.from_dicts(arm, config['motion'])


def test_a_succeeded_goal_is_no_failure():
    assert failure(GoalStatus.STATUS_SUCCEEDED, Result.SUCCESSFUL,
                   'Goal successfully reached!') == ''


@pytest.mark.parametrize('code, name, said', [
    (Result.PATH_TOLERANCE_VIOLATED, 'PATH_TOLERANCE_VIOLATED',
     'Aborted due to path tolerance violation'),
    (Result.GOAL_TOLERANCE_VIOLATED, 'GOAL_TOLERANCE_VIOLATED',
     'Aborted due to goal_time_tolerance exceeding by 5.004319 seconds'),
    (Result.INVALID_GOAL, 'INVALID_GOAL', 'joint2 beyond its hardware limit'),
    (Result.INVALID_JOINTS, 'INVALID_JOINTS', 'joint5 is not a joint of the controller'),
])
def test_an_aborted_goal_fails_with_the_code_name_and_the_controllers_words(code, name, said):
    text = failure(GoalStatus.STATUS_ABORTED, code, said)
    assert text == f'joint_trajectory_controller aborted the move: {name} ({said})'


def test_an_abort_without_words_or_a_known_code_still_says_what_came():
    assert failure(GoalStatus.STATUS_ABORTED, -42, '  ') == (
        'joint_trajectory_controller aborted the move: error code -42 (no reason given)')
    # aborted, yet the result says SUCCESSFUL (a server that set no code): the status tells
    assert failure(GoalStatus.STATUS_ABORTED, Result.SUCCESSFUL, '') == (
        f'joint_trajectory_controller aborted the move: status {GoalStatus.STATUS_ABORTED} '
        '(no reason given)')


def test_a_goal_canceled_by_another_client_is_a_failure_and_a_rejection_names_the_log():
    # joint_trajectory_controller cancels with an empty result: error code 0
    assert 'canceled the move' in failure(GoalStatus.STATUS_CANCELED, Result.SUCCESSFUL, '')
    assert rejection().startswith('joint_trajectory_controller rejected the move')
    assert 'its log says why' in rejection()
