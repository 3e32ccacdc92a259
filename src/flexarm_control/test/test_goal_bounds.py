"""Goal bounds and the server's own end of a goal: its time limit, its sender gone."""
import math

import pytest

from flexarm_control.execution.goal_bounds import (
    MAX_CORRECTIONS,
    TIME_MARGIN,
    GoalBounds,
    GoalWatch,
    goal_error,
    move_budget,
    time_limit,
)
from flexarm_control.execution.modes import Mode
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_motion.arm_motion import MotionSettings

BOUNDS = GoalBounds.nominal()
A1 = (1.45, -0.15, math.radians(-45))
CLOSED = int(Mode.CLOSED_LOOP)


def error(target=A1, mode=CLOSED, position=0.0, angle=0.0, corrections=0):
    return goal_error(target, mode, position, angle, corrections, BOUNDS)


def test_the_floors_are_the_vision_s_settledness_and_the_defaults_pass():
    settle = load_config('vision.yaml', node_name='flexarm_vision')['settle']
    assert BOUNDS.min_position_tolerance == settle['stability'] == 2e-5
    assert BOUNDS.min_angle_tolerance == settle['angle_stability'] == 5e-5
    defaults = load_config('compensator.yaml', node_name='flexarm_compensator')
    assert BOUNDS.tolerance_error(defaults['position_tolerance'],
                                  defaults['angle_tolerance']) is None
    assert 1 <= defaults['max_corrections'] <= MAX_CORRECTIONS


def test_the_testers_goal_is_refused_for_each_of_its_values():
    assert error() is None and error(position=5e-5, angle=8.7e-5, corrections=5) is None
    assert 'max_corrections 1000000000 is beyond 10' in error(corrections=10**9)
    assert 'position_tolerance 1e-12 m is below 2e-05 m' in error(position=1e-12)
    assert 'outside [-pi, pi]' in error(target=(1.45, -0.15, 1e9))


@pytest.mark.parametrize('kwargs, reason', [
    ({'target': (math.nan, 0.0, 0.0)}, 'non-finite target.x'),
    ({'angle': math.inf}, 'non-finite angle_tolerance'),
    ({'mode': 4}, 'unknown mode 4'),
    ({'position': -1e-3}, 'position_tolerance must be >= 0'),
    ({'angle': 1e-6}, 'angle_tolerance 1e-06 rad is below 5e-05 rad'),
    ({'position': 0.5}, 'position_tolerance 0.5 m is beyond 0.1 m'),
    ({'angle': math.radians(30)}, 'angle_tolerance 0.523599 rad is beyond 0.174533 rad'),
    ({'target': (1.45, -0.15, math.pi + 1e-9)}, 'target.phi 3.14159 rad is outside'),
    ({'corrections': MAX_CORRECTIONS + 1, 'mode': int(Mode.RIGID)}, 'beyond 10'),
])
def test_out_of_bounds_values_say_why(kwargs, reason):
    assert reason in error(**kwargs)


def test_the_edges_are_inside():
    assert error(target=(1.0, 0.0, -math.pi)) is None and error(target=(1, 0, math.pi)) is None
    assert error(position=BOUNDS.min_position_tolerance,
                 angle=BOUNDS.max_angle_tolerance, corrections=MAX_CORRECTIONS) is None
    assert error(position=BOUNDS.max_position_tolerance,
                 angle=BOUNDS.min_angle_tolerance) is None


def test_the_time_limit_is_twice_the_moves_own_timeouts():
    config = load_config('arm.yaml', 'motion.yaml')
    geometry = ArmGeometry.from_dict(config['arm'])
    motion = MotionSettings.from_dict(config['motion'])
    # joint1's whole range at 10 deg/s, the approach leg, two legs' margins, a measurement
    assert move_budget(geometry, motion) == pytest.approx(36.0 + 0.02 + 2 * 10.0 + 30.0)
    assert time_limit(1, geometry, motion) == pytest.approx(2 * 86.02)
    assert time_limit(6, geometry, motion) == pytest.approx(6 * TIME_MARGIN * 86.02)


class Clocks:
    def __init__(self) -> None:
        self.arm, self.wall, self.looks, self.left = 0.0, 0.0, 0, False

    def sender_left(self) -> bool:
        self.looks += 1
        return self.left


def test_a_goal_watch_ends_a_goal_at_its_time_limit():
    clocks = Clocks()
    watch = GoalWatch(100.0, lambda: clocks.arm, clocks.sender_left, 0.5, lambda: clocks.wall)
    clocks.arm = 100.0
    assert not watch() and watch.reason == ''
    clocks.arm = 100.1
    assert watch() and watch.reason == "it outlasted its time limit, 100 s of the arm's time"
    clocks.arm = 0.0
    assert watch()                        # once ended, it stays ended


def test_a_goal_watch_looks_for_the_sender_every_period():
    clocks = Clocks()
    watch = GoalWatch(100.0, lambda: clocks.arm, clocks.sender_left, 0.5, lambda: clocks.wall)
    assert not watch() and clocks.looks == 1        # at once
    clocks.wall = 0.4
    assert not watch() and clocks.looks == 1        # not before the period is over
    clocks.left = True
    assert not watch()
    clocks.wall = 0.5
    assert watch() and clocks.looks == 2
    assert watch.reason == 'every client that may have sent it has left the graph'
