"""Input shapers and the shaped joint reference: textbook impulses, the residual vibration they
leave on a damped mode, the insensitivity that picks one, and the limits the reference keeps."""
import math

import numpy as np
import pytest
from scipy.linalg import expm

from flexarm_core.params import load_config
from flexarm_motion.shaped_move import plan_profile, shape_move
from flexarm_motion.shaping import (
    KINDS,
    Shaper,
    choose_shaper,
    residual_vibration,
    worst_vibration,
)

ARM = load_config('arm.yaml')['arm']
VELOCITY, ACCELERATION = np.array(ARM['velocity']), np.array(ARM['acceleration'])
ZETA = ARM['tip_mode']['damping_ratio']
START = np.array([0.0, 0.6, -0.5, -0.5])
MOVE = START + [0.3, 0.0, 0.2, 0.0]


def ring(times: np.ndarray, accel: np.ndarray, frequency: float, zeta: float) -> float:
    """Amplitude [m] of z'' + 2ζω z' + ω² z = −a(t) at the last sample, a held between
    samples (exact discretisation), from rest."""
    omega = 2 * math.pi * frequency
    system = np.array([[0.0, 1.0, 0.0], [-omega ** 2, -2 * zeta * omega, -1.0],
                       [0.0, 0.0, 0.0]])
    state = np.zeros(3)
    steps = {}
    for k in range(times.size - 1):
        h = round(times[k + 1] - times[k], 12)
        if h not in steps:
            steps[h] = expm(system * h)
        state = steps[h] @ np.array([state[0], state[1], accel[k]])
    sigma, omega_d = zeta * omega, omega * math.sqrt(1 - zeta ** 2)
    return math.hypot(state[0], (state[1] + sigma * state[0]) / omega_d)


@pytest.mark.parametrize('kind, amplitudes, times', [
    ('off', [1.0], [0.0]),
    ('zv', [0.5, 0.5], [0.0, 0.5]),
    ('zvd', [0.25, 0.5, 0.25], [0.0, 0.5, 1.0]),
    ('ei', [0.2625, 0.475, 0.2625], [0.0, 0.5, 1.0]),
])
def test_undamped_shapers_are_the_textbook_ones(kind, amplitudes, times):
    shaper = Shaper.design(kind, 2.0, 0.0)      # period T = 0.5 s
    assert shaper.amplitudes == pytest.approx(amplitudes)
    assert shaper.times == pytest.approx(np.array(times) * 0.5)


@pytest.mark.parametrize('kind', KINDS)
def test_damped_shapers_sum_to_one_and_cancel_their_mode(kind):
    shaper = Shaper.design(kind, 9.9, ZETA)
    assert shaper.amplitudes.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.all(shaper.amplitudes > 0) and np.all(np.diff(shaper.times) > 0)
    expected = {'off': 1.0, 'zv': 0.0, 'zvd': 0.0, 'ei': 0.042}[kind]
    assert residual_vibration(shaper, 1.0)[0] == pytest.approx(expected, abs=1e-3)
    td = 1 / (9.9 * math.sqrt(1 - ZETA ** 2))
    assert shaper.duration == pytest.approx({'off': 0, 'zv': td / 2}.get(kind, td))


@pytest.mark.parametrize('kind, low, high', [('zv', 0.966, 1.035), ('zvd', 0.846, 1.158),
                                             ('ei', 0.794, 1.210)])
def test_documented_insensitivity_bands(kind, low, high):
    shaper = Shaper.design(kind, 5.0, ZETA)
    assert np.all(residual_vibration(shaper, np.linspace(low + 1e-3, high - 1e-3, 101)) < 0.05)
    assert np.all(residual_vibration(shaper, [low - 3e-3, high + 3e-3]) > 0.05)


@pytest.mark.parametrize('uncertainty, kind', [(0.0, 'zv'), (0.03, 'zv'), (0.1, 'zvd'),
                                               (0.15, 'zvd'), (0.2, 'ei'), (0.6, 'ei')])
def test_the_shortest_shaper_good_enough_for_the_uncertainty_is_chosen(uncertainty, kind):
    shaper = choose_shaper(3.7, ZETA, uncertainty)
    assert shaper.kind == kind
    assert (worst_vibration(shaper, uncertainty) <= 0.05) == (uncertainty < 0.6)


def test_bad_designs_are_refused():
    with pytest.raises(ValueError, match='one of off, zv, zvd, ei'):
        Shaper.design('zvdd', 5.0, 0.05)
    with pytest.raises(ValueError, match='frequency > 0'):
        Shaper.design('zv', 0.0, 0.05)
    with pytest.raises(ValueError, match='uncertainty'):
        choose_shaper(5.0, 0.05, 1.0)


@pytest.mark.parametrize('kind', KINDS)
def test_shaped_reference_keeps_the_limits_and_lands_on_the_target(kind):
    profile = plan_profile(START, MOVE, VELOCITY, ACCELERATION)
    move = shape_move(profile, Shaper.design(kind, 3.7, ZETA), 0.01)
    assert move.duration == pytest.approx(profile.duration + move.shaper.duration)
    assert np.all(np.diff(move.times) > 0) and move.times[0] == 0.0
    assert np.all(np.diff(move.times) <= 0.01 + 1e-12)
    assert np.all(np.abs(move.velocities) <= VELOCITY * (1 + 1e-12))
    assert np.all(np.abs(move.accelerations) <= ACCELERATION * (1 + 1e-12))
    assert np.array_equal(move.positions[0], START) and np.array_equal(move.positions[-1], MOVE)
    assert np.all(move.velocities[[0, -1]] == 0) and np.all(move.accelerations[-1] == 0)
    # joints move together along the straight line, joint1 at its limits
    share = (move.positions - START)[:, 2] / 0.2
    assert (move.positions - START)[:, 0] / 0.3 == pytest.approx(share)
    assert np.abs(move.velocities[:, 0]).max() == pytest.approx(VELOCITY[0])
    assert np.abs(move.accelerations[:, 0]).max() == pytest.approx(ACCELERATION[0])


def test_profile_is_time_optimal_for_its_slowest_joint():
    long = plan_profile(START, MOVE, VELOCITY, ACCELERATION)       # trapezoid: 0.3 rad
    assert long.duration == pytest.approx(0.3 / VELOCITY[0] + VELOCITY[0] / ACCELERATION[0])
    short = plan_profile(START, START + [0.0, 0.01, 0.0, 0.0], VELOCITY, ACCELERATION)
    assert short.duration == pytest.approx(2 * math.sqrt(0.01 / ACCELERATION[1]))   # triangle
    still = shape_move(plan_profile(START, START, VELOCITY, ACCELERATION),
                       Shaper.design('zv', 5.0, ZETA), 0.01)
    assert np.all(still.positions == START) and still.duration == pytest.approx(0.1, rel=0.01)


@pytest.mark.parametrize('frequency', [3.7, 9.9])
def test_shaping_leaves_the_residual_its_vibration_ratio_says(frequency):
    profile = plan_profile(START, MOVE, VELOCITY, ACCELERATION)
    residual = {}
    for kind in KINDS:
        for ratio in (0.85, 1.0, 1.15):
            move = shape_move(profile, Shaper.design(kind, frequency, ZETA), 2e-4)
            residual[kind, ratio] = ring(move.times, move.accelerations[:, 0],
                                         frequency * ratio, ZETA)
    for (kind, ratio), value in residual.items():
        shaper = Shaper.design(kind, frequency, ZETA)
        assert value / residual['off', ratio] == pytest.approx(
            residual_vibration(shaper, ratio)[0], abs=0.01)
    assert residual['zv', 1.0] < 0.01 * residual['off', 1.0]
    assert residual['zvd', 1.0] < 0.01 * residual['off', 1.0]
    for ratio in (0.85, 1.15):
        assert residual['zvd', ratio] < 0.06 * residual['off', ratio]
        assert residual['ei', ratio] < 0.06 * residual['off', ratio]
        assert residual['zv', ratio] > 3 * max(residual['zvd', ratio], residual['ei', ratio])


def test_the_shipped_shaper_is_the_one_chosen_for_a_tap_test_s_frequency_uncertainty():
    from flexarm_core.params import load_config
    from flexarm_motion.shaped_move import MovePlanner

    config = load_config('arm.yaml', 'motion.yaml')
    assert config['motion']['shaping'] == 'auto'
    planner = MovePlanner.from_dicts(config['motion'], config['arm'])
    assert planner.shaping == 'zvd'                       # ±15 %: ZV would leave 20 %
    exact = dict(config['motion'], shaping='zv')
    assert MovePlanner.from_dicts(exact, config['arm']).shaping == 'zv'
