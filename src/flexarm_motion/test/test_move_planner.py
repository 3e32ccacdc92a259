"""How the control nodes plan a move for joint_trajectory_controller: shaped at the nominal
tip mode, within the limits, and a stop that comes back to where it was asked."""
import dataclasses

import numpy as np
import pytest

from flexarm_core.params import load_config
from flexarm_motion.shaped_move import MovePlanner

CONFIG = load_config('arm.yaml', 'motion.yaml')
START = np.array([0.0, 0.6, -0.5, -0.5])


@pytest.fixture
def planner() -> MovePlanner:
    return MovePlanner.from_dicts(CONFIG['motion'], CONFIG['arm'])


def test_a_move_is_shaped_at_the_tip_mode_of_its_payload_and_target_within_the_limits(planner):
    target = START + np.array([0.3, 0.1, -0.2, 0.1])
    light, heavy = planner.plan(START, target, 0.0), planner.plan(START, target, 5.0)
    assert light.shaper.frequency == pytest.approx(planner.mode(0.0, 0.7))
    assert heavy.shaper.frequency == pytest.approx(planner.mode(5.0, 0.7))
    assert heavy.shaper.frequency < 4.0 < light.shaper.frequency
    assert heavy.duration > light.duration          # a slower mode: a longer shaper
    for move in (light, heavy):
        assert move.positions[0] == pytest.approx(START) and np.all(move.positions[-1] == target)
        assert np.all(np.abs(move.velocities) <= planner.velocity * (1 + 1e-9))
        assert np.all(np.abs(move.accelerations) <= planner.acceleration * (1 + 1e-9))
        assert np.allclose(np.diff(move.times)[:-1], planner.period)


def test_a_move_to_where_the_arm_is_holds_it_and_a_stop_returns_within_the_limits(planner):
    still = planner.plan(START, START, 0.0)
    assert still.times.tolist() == [0.0, planner.period]
    assert np.all(still.positions == START) and not np.any(still.velocities)
    stop = planner.stop(START)
    assert np.all(stop.positions[-1] == START)
    # the cubic from full speed back to its start brakes at 4 v / T: within the limits
    assert np.all(4 * planner.velocity / stop.duration <= planner.acceleration * (1 + 1e-9))


def test_an_unknown_shaper_or_period_is_refused():
    with pytest.raises(ValueError, match='shaper kind'):
        MovePlanner.from_dicts(dict(CONFIG['motion'], shaping='fast'), CONFIG['arm'])
    with pytest.raises(ValueError, match='trajectory_period'):
        MovePlanner.from_dicts(dict(CONFIG['motion'], trajectory_period=0.0), CONFIG['arm'])
    assert dataclasses.replace(MovePlanner.from_dicts(CONFIG['motion'], CONFIG['arm']),
                               shaping='off').plan(START, START + 0.01, 0.0).shaper.kind == 'off'
