"""The arm's error sources at their configured magnitudes (config/sim.yaml error_sources)."""
import copy
import math

import numpy as np
import pytest

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_sim.dynamics import ArmDynamics, NaturalFrequency
from flexarm_sim.errors import ArmErrors, Thermal
from flexarm_sim.plant import Plant

pytestmark = pytest.mark.duration(25)

CONFIG = load_config('arm.yaml', 'sim.yaml')
SOURCES = CONFIG['error_sources']
GEOMETRY = ArmGeometry.from_dict(CONFIG['arm'])
PLANT = Plant.from_dict(CONFIG['plant'], GEOMETRY)
START = np.array([0.0, 0.6, -0.5, -0.5])
TARGET = np.array([0.2, 0.7, -0.4, 0.3])
NAMES = ('repeatability', 'hysteresis', 'thermal', 'payload', 'camera')


def only(*names: str, **changes: dict) -> dict:
    """The shipped error_sources with the master switch on and only ``names`` on."""
    d = copy.deepcopy(SOURCES)
    d['enabled'] = True
    for name in NAMES:
        d[name]['enabled'] = name in names
        d[name].update(changes.get(name, {}))
    return d


def make(sources: dict | None, damping: float | None = None, initial=START,
         plant: Plant = PLANT) -> ArmDynamics:
    """The arm with these error sources; ``damping`` instead of the configured ratio makes the
    tip settle within a few tenths of a second."""
    params = CONFIG['dynamics'] if damping is None else {**CONFIG['dynamics'],
                                                         'damping_ratio': damping}
    errors = None if sources is None else ArmErrors.from_dict(sources, plant.backlash)
    return ArmDynamics(plant, GEOMETRY, params, np.array(initial, dtype=float), errors)


def settle(arm: ArmDynamics, after: float = 0.3, dt: float = 0.01) -> np.ndarray:
    """Step to the end of the move and ``after`` seconds more; the tip pose."""
    while arm.state.is_moving:
        arm.step(dt)
    for _ in range(round(after / dt)):
        arm.step(dt)
    return arm.state.tip_pose


def jacobian(q: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """d(plant pose)/d(joints) (3, 4), central differences."""
    return np.stack([(PLANT.pose(q + d) - PLANT.pose(q - d)) / (2 * step)
                     for d in np.eye(4) * step], axis=-1)


def test_the_sources_are_shipped_on_at_their_realistic_magnitudes():
    assert SOURCES['enabled'] is True                   # the realistic world is the default
    assert all(SOURCES[name]['enabled'] for name in NAMES)
    assert SOURCES['repeatability']['sigma'] == [2e-5, 5e-6, 2e-5, 2e-5]
    assert SOURCES['hysteresis']['fraction'] == 0.3
    assert (SOURCES['thermal']['expansion'], SOURCES['thermal']['rise']) == (12e-6, 2.0)
    errors = ArmErrors.from_dict({**SOURCES, 'enabled': False}, PLANT.backlash)
    assert not np.any(errors.sigma) and not np.any(errors.band) and errors.thermal is None


@pytest.mark.parametrize('sources', [{**SOURCES, 'enabled': False},
                                     {**only(*NAMES), 'enabled': False}, only()])
def test_with_every_source_off_the_arm_moves_exactly_as_the_ideal_one(sources):
    ideal, arm = make(None), make(sources)
    rng = np.random.default_rng(4)
    for k in range(1200):
        if k % 300 == 0:
            target = rng.uniform(GEOMETRY.lower, GEOMETRY.upper)
            ideal.command(target)
            arm.command(target)
        if k == 750:
            ideal.hold()
            arm.hold()
        ideal.step(0.01)
        arm.step(0.01)
        a, b = ideal.state, arm.state
        for field in ('joint_positions', 'joint_velocities', 'tip_pose', 'tip_velocity'):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
    arm.command(TARGET)
    np.testing.assert_allclose(settle(arm, after=20.0), PLANT.pose(TARGET), atol=1e-7)
    np.testing.assert_array_equal(arm.state.joint_positions, TARGET)


def test_repeated_moves_to_one_command_spread_by_the_repeatability():
    sigma = np.array(SOURCES['repeatability']['sigma'])
    arm = make(only('repeatability'), damping=0.9, initial=TARGET)
    away = TARGET + [2e-3, 2e-3, -2e-3, 2e-3]
    poses = []
    for _ in range(300):
        arm.command(away)
        settle(arm, after=0.0)
        arm.command(TARGET)
        poses.append(settle(arm, after=0.3))
        np.testing.assert_array_equal(arm.state.joint_positions, TARGET)   # the encoders
    poses = np.array(poses)
    j = jacobian(TARGET)
    expected = np.sqrt(np.diag(j @ np.diag(sigma ** 2) @ j.T))
    assert expected[0] > 1e-6 and expected[1] > 1e-5 and expected[2] > 2e-5
    # 300 moves: the sample spread is within 4 % (1 standard error) of the true one.
    np.testing.assert_allclose(poses.std(axis=0, ddof=1), expected, rtol=0.12)
    np.testing.assert_allclose(poses.mean(axis=0), PLANT.pose(TARGET),
                               atol=float(np.max(4 * expected / math.sqrt(len(poses)))))


def test_a_joint_that_is_not_commanded_to_move_keeps_its_error():
    arm = make(only('repeatability'), damping=0.9)
    arm.command(TARGET)
    before = settle(arm)
    arm.command(TARGET)                                 # the same command again: no move
    np.testing.assert_allclose(settle(arm), before, atol=1e-12)


@pytest.mark.parametrize('joint', range(4))
def test_approaches_from_opposite_sides_differ_by_the_hysteresis_band(joint):
    fraction = SOURCES['hysteresis']['fraction']
    step = np.eye(4)[joint] * 0.01
    poses = {}
    for side in (-1, 1):
        arm = make(only('hysteresis'), damping=0.9, initial=TARGET + side * step)
        arm.command(TARGET)
        poses[side] = settle(arm)
        arm.command(TARGET + side * step)               # away and back from the same side:
        settle(arm)                                     # the same pose again
        arm.command(TARGET)
        np.testing.assert_allclose(settle(arm), poses[side], atol=1e-10)
    # Each element's rotation adds to the tool angle; from below it lags behind (-).
    assert poses[1][2] - poses[-1][2] == pytest.approx(
        2 * fraction * PLANT.backlash[joint], rel=1e-6)
    assert np.hypot(*(poses[1] - poses[-1])[:2]) > 0.5 * fraction * PLANT.backlash[joint]


def test_a_reversal_inside_the_band_does_not_move_the_tip():
    band = SOURCES['hysteresis']['fraction'] * PLANT.backlash[3]
    arm = make(only('hysteresis'), damping=0.9, initial=TARGET - [0.0, 0.0, 0.0, 0.01])
    arm.command(TARGET)
    before = settle(arm)
    arm.command(TARGET - [0.0, 0.0, 0.0, band])         # back by half the band's width:
    np.testing.assert_allclose(settle(arm), before, atol=0.02 * band)   # only the moments move
    arm.command(TARGET - [0.0, 0.0, 0.0, 3 * band])     # beyond it: the tip follows
    assert settle(arm)[2] == pytest.approx(before[2] - band, abs=0.05 * band)


def test_the_temperature_follows_its_profile():
    t = SOURCES['thermal']
    ramp = Thermal(t['expansion'], t['rise'], t['duration'], 'ramp')
    assert [ramp.temperature(s) for s in (0.0, 1800.0, 3600.0, 7200.0)] == [0.0, 1.0, 2.0, 2.0]
    lag = Thermal(t['expansion'], t['rise'], t['duration'], 'first_order')
    assert lag.temperature(3600.0) == pytest.approx(2.0 * (1 - math.exp(-1)))
    assert ramp.strain(3600.0) == pytest.approx(24e-6)


def test_a_temperature_rise_lengthens_the_reach():
    expansion, rise = SOURCES['thermal']['expansion'], SOURCES['thermal']['rise']
    q = np.array([0.3, 0.8, 0.1, -0.2])
    cold, hot = PLANT.pose(q), PLANT.pose(q, strain=expansion * rise)
    reach = np.hypot(*cold[:2])
    assert np.hypot(*hot[:2]) - reach == pytest.approx(expansion * rise * reach, rel=1e-9)
    assert hot[2] == cold[2]
    # The simulated arm warms up along the profile, here sped up to 5 s.
    arm = make(only('thermal', thermal={'duration': 5.0}), damping=0.9, initial=q)
    assert np.hypot(*settle(arm, after=6.0)[:2]) - reach == pytest.approx(
        expansion * rise * reach, rel=1e-3)


def test_a_payload_change_at_run_time_moves_the_tip_as_the_heavier_plant_would():
    arm = make(None, initial=TARGET)
    settle(arm)
    arm.set_payload(5.0)
    heavy = PLANT.with_payload(5.0)
    frequency = NaturalFrequency.from_dict(CONFIG['dynamics']['natural_frequency'])
    assert arm.natural_frequency() == frequency(5.0, TARGET[1])
    dt, ringing = 0.002, []
    for _ in range(1000):                               # 2 s of ringing about the new pose
        arm.step(dt)
        ringing.append(arm.state.tip_pose[1] - heavy.pose(TARGET)[1])
    crossings = np.flatnonzero(np.diff(np.sign(ringing)) != 0)
    measured = (len(crossings) - 1) / 2 / ((crossings[-1] - crossings[0]) * dt)
    zeta = CONFIG['dynamics']['damping_ratio']
    assert measured == pytest.approx(arm.natural_frequency() * math.sqrt(1 - zeta ** 2),
                                     rel=0.03)
    np.testing.assert_allclose(settle(arm, after=30.0), heavy.pose(TARGET), atol=1e-7)
    with pytest.raises(ValueError, match='payload'):
        arm.set_payload(-1.0)
    assert arm.plant.payload == 5.0


def test_a_step_at_rest_is_what_evaluating_the_plant_anew_gives_bit_for_bit():
    """The arm keeps the plant's pose and the tip frequency while it rests (every source on:
    thermal strain, a payload change, moves with their joint errors and friction)."""
    kept, anew = make(only(*NAMES)), make(only(*NAMES))
    events = {50: lambda arm: arm.command(TARGET), 900: lambda arm: arm.set_payload(3.0),
              1200: lambda arm: arm.command(START), 1900: lambda arm: arm.hold()}
    for step in range(2500):
        for arm in (kept, anew):
            events.get(step, lambda arm: None)(arm)
        if anew._kept is not None:          # evaluated anew at every step
            anew._kept = (anew._kept[0], b'stale', *anew._kept[2:])
        kept.step(0.01)
        anew.step(0.01)
        for field in ('joint_positions', 'joint_velocities', 'tip_pose', 'tip_velocity'):
            assert np.array_equal(getattr(kept.state, field), getattr(anew.state, field))


def test_a_repeated_command_is_the_same_move_with_the_same_error():
    errors = ArmErrors.from_dict(only('repeatability'), PLANT.backlash)
    start = np.array([0.0, 0.6, -0.5, -0.5])
    target = start + [0.1, 0.05, 0.1, 0.1]
    move = errors.plan(errors.start(start), start, target)
    halfway = (start + target) / 2
    assert errors.plan(move, halfway, target.copy()) is move
    assert errors.plan(move, halfway, target + 1e-3) is not move
