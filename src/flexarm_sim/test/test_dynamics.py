"""Joint motion at the Table 1 speeds and the Table 6 tip vibration."""
import math
import sys

import numpy as np
import pytest

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_sim import dynamics
from flexarm_sim.dynamics import ArmDynamics
from flexarm_sim.plant import Plant


@pytest.fixture(scope='module')
def config():
    return load_config('arm.yaml', 'sim.yaml')


START = (0.0, 0.6, -0.5, -0.5)


def make(config, payload=0.0, initial=START) -> ArmDynamics:
    geometry = ArmGeometry.from_dict(config['arm'])
    plant = Plant.from_dict({**config['plant'], 'payload': payload}, geometry)
    return ArmDynamics(plant, geometry, config['dynamics'], np.array(initial))


@pytest.mark.parametrize('initial, reason', [
    ((0.0, 0.6, -0.5), 'expected 4 values'),
    ((0.0, math.nan, -0.5, -0.5), 'non-finite'),
    ((0.0, 0.95, -0.5, -0.5), 'joint2'),
    (((0.0, 0.6), (-0.5, -0.5)), 'flat'),
])
def test_bad_initial_positions_are_refused(config, initial, reason):
    with pytest.raises(ValueError, match=f'initial joint positions: .*{reason}'):
        make(config, initial=initial)


def test_a_command_landing_mid_step_never_teleports_a_joint(config):
    """The fake controller commands from its socket thread while ``step`` runs: inject the
    command between any two lines of ``step`` (as a thread switch could)."""
    dt = 0.01
    geometry = ArmGeometry.from_dict(config['arm'])
    reach = geometry.velocity * float(config['dynamics']['speed_scale']) * dt + 1e-12
    far = np.array(START) + [1.0, 0.1, 0.5, 0.5]
    previous = sys.gettrace()
    k, injected = 1, True
    while injected:
        arm, lines, injected = make(config), 0, False

        def tracer(frame, event, arg, k=k, arm=arm):
            nonlocal lines, injected
            if frame.f_code.co_filename != dynamics.__file__:
                return None
            if event == 'line':
                lines += 1
                if lines == k:
                    arm.command(far)
                    injected = True
            return tracer

        sys.settrace(tracer)
        try:
            arm.step(dt)
        finally:
            sys.settrace(previous)
        assert np.all(np.abs(arm.state.joint_positions - START) <= reach), f'line {k}'
        k += 1
    assert k > 10


def test_joints_travel_at_the_table_1_speeds(config):
    arm = make(config)
    arm.command(np.array([0.5, 0.6, -0.5, -0.5]))      # joint1 by 0.5 rad at 10 deg/s
    speeds, t = [], 0.0
    while arm.state.is_moving and t < 20:
        arm.step(0.01)
        t += 0.01
        speeds.append(arm.state.joint_velocities[0])
    assert not arm.state.is_moving
    assert max(speeds) == pytest.approx(math.radians(10), rel=1e-6)
    assert 0.5 / math.radians(10) < t < 0.5 / math.radians(10) + 1.5
    np.testing.assert_array_equal(arm.state.joint_positions, [0.5, 0.6, -0.5, -0.5])


def test_tip_rings_after_a_move_then_settles_on_the_static_pose(config):
    arm = make(config, payload=5.0)
    target = np.array([0.3, 0.7, -0.6, -0.2])
    arm.command(target)
    while arm.state.is_moving:
        arm.step(0.005)
    static = arm.plant.pose(target)
    early = []
    for _ in range(200):                                # 1 s after arrival
        arm.step(0.005)
        early.append(arm.state.tip_pose - static)
    early = np.array(early)
    assert np.ptp(early[:, 1]) > 1e-5                   # visible ringing
    for _ in range(4000):                               # 20 s more
        arm.step(0.005)
    np.testing.assert_allclose(arm.state.tip_pose, static, atol=1e-7)


def test_a_step_rings_as_its_semi_implicit_euler_sub_steps_would(config):
    """The sub-steps composed into one map give what running them one by one gives."""
    arm = make(config, payload=5.0)
    arm.command(np.array([0.3, 0.7, -0.6, -0.2]))
    dt = 0.01
    n = math.ceil(dt / config['dynamics']['max_step'])
    zeta, h = config['dynamics']['damping_ratio'], dt / n
    for _ in range(150):                   # through the move and into the ringing after it
        z, zd, vel = arm._z.copy(), arm._zd.copy(), arm._static_vel.copy()
        arm.step(dt)
        accel = (arm._static_vel - vel) / dt
        omega = 2 * math.pi * arm.natural_frequency()
        for _ in range(n):
            zd += h * (-accel - 2 * zeta * omega * zd - omega ** 2 * z)
            z += h * zd
        np.testing.assert_allclose(arm._z, z, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(arm._zd, zd, rtol=1e-12, atol=1e-15)
    assert np.abs(arm._z).max() > 1e-5    # it did ring


def test_tip_angle_stays_wrapped_while_ringing(config):
    target = np.array([1.0, 0.6, 1.0, 1.0])
    plant = make(config, payload=5.0).plant
    for _ in range(3):                                  # static tool angle just below π
        target[3] += math.remainder(math.pi - 1e-4 - plant.pose(target)[2], 2 * math.pi)
    arm = make(config, payload=5.0, initial=target - [0.1, 0.0, 0.0, 0.0])
    arm.command(target)                                 # overshoots past π while ringing
    phis = []
    for _ in range(400):
        arm.step(0.005)
        phis.append(arm.state.tip_pose[2])
    assert min(phis) < -3.14 and all(-math.pi <= phi < math.pi for phi in phis)


def test_hold_stops_short_of_the_target(config):
    arm = make(config)
    arm.command(np.array([1.0, 0.6, -0.5, -0.5]))
    for _ in range(100):
        arm.step(0.01)
    arm.hold()
    while arm.state.is_moving:
        arm.step(0.01)
    assert 0.0 < arm.state.joint_positions[0] < 0.5


def test_a_rest_whose_ringing_has_ended_stays_exactly_still_until_something_changes(config):
    arm = make(config)          # no thermal growth: still means still
    arm.command(np.array([0.1, 0.65, -0.4, -0.6]))
    for _ in range(3000):                     # the move, then 26 s of sim time to ring down
        arm.step(0.01)
    still = arm.state
    assert not still.is_moving and not np.any(still.tip_velocity)
    for _ in range(100):
        arm.step(0.01)
    np.testing.assert_array_equal(arm.state.tip_pose, still.tip_pose)
    arm.set_payload(5.0)                      # a load picked up at rest: the tip sags, rings
    arm.step(0.01)
    assert np.any(arm.state.tip_velocity) and arm.state.tip_pose[1] != still.tip_pose[1]


def test_a_followed_trajectory_is_tracked_exactly_then_held_at_its_end(config):
    from flexarm_core.joint_trajectory import SampledTrajectory

    arm = make(config)
    start = np.array(START)
    end = start + np.array([0.1, 0.0, -0.05, 0.0])
    times = np.arange(1, 31) * 0.1                      # 3 s, a smooth cosine ramp
    s = (1 - np.cos(np.pi * times / 3.0)) / 2
    sd = np.pi / 6.0 * np.sin(np.pi * times / 3.0)
    trajectory = SampledTrajectory.from_points(
        start, times, start + np.outer(s, end - start), np.outer(sd, end - start))
    arm.step(0.01)
    arm.follow(trajectory)
    for _ in range(150):
        arm.step(0.01)
    expected = start + (1 - math.cos(math.pi * 1.5 / 3.0)) / 2 * (end - start)
    assert arm.state.joint_positions == pytest.approx(expected, abs=1e-4)
    assert arm.state.is_moving
    for _ in range(160):
        arm.step(0.01)
    assert arm.state.joint_positions == pytest.approx(end, abs=1e-15)
    assert not arm.state.is_moving and not np.any(arm.state.joint_velocities)
    arm.follow(trajectory)                    # a new one starts where the joints are
    arm.hold()                                # and a hold ends it
    arm.step(0.01)
    assert arm.state.joint_positions == pytest.approx(end, abs=1e-12)
