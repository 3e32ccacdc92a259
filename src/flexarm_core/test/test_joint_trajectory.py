"""A joint trajectory sampled as joint_trajectory_controller's spline."""
import numpy as np
import pytest

from flexarm_core.joint_trajectory import SampledTrajectory


def test_the_reference_passes_its_points_and_is_the_cubic_between_them():
    times = np.array([0.5, 1.0, 1.5, 2.0])
    cubic = np.stack([times ** 3, -2 * times ** 2 + 0.3], axis=1)
    slope = np.stack([3 * times ** 2, -4 * times], axis=1)
    trajectory = SampledTrajectory.from_points(np.array([0.0, 0.3]), times, cubic, slope)
    for t in (0.7, 1.0, 1.25, 1.9):
        q, qd = trajectory.at(t)
        assert q == pytest.approx([t ** 3, -2 * t ** 2 + 0.3], abs=1e-12)
        assert qd == pytest.approx([3 * t ** 2, -4 * t], abs=1e-12)
    q, qd = trajectory.at(0.0)
    assert q == pytest.approx([0.0, 0.3]) and not np.any(qd)       # starts at rest
    q, qd = trajectory.at(5.0)
    assert q == pytest.approx(cubic[-1]) and not np.any(qd)        # holds its end
    assert trajectory.duration == 2.0


@pytest.mark.parametrize('times, positions, reason', [
    ([0.0, 1.0], [[0.0], [1.0]], 'rise from above 0'),
    ([1.0, 1.0], [[0.0], [1.0]], 'rise from above 0'),
    ([1.0], [[np.nan]], 'finite'),
    ([1.0], [[0.0, 1.0]], 'points of 1 positions'),
    ([], np.zeros((0, 1)), 'points of 1 positions'),
])
def test_a_malformed_trajectory_is_refused(times, positions, reason):
    with pytest.raises(ValueError, match=reason):
        SampledTrajectory.from_points(np.zeros(1), np.asarray(times, dtype=float),
                                      np.asarray(positions, dtype=float))


def test_a_trajectory_taken_over_mid_motion_starts_at_the_reference_s_speed():
    trajectory = SampledTrajectory.from_points(np.zeros(1), np.array([1.0]), np.zeros((1, 1)))
    moving = trajectory.starting(np.array([0.0]), np.array([0.3]))
    q, qd = moving.at(0.0)
    assert q == pytest.approx([0.0]) and qd == pytest.approx([0.3])
    q, qd = moving.at(1.0)                          # back where it was, at rest
    assert q == pytest.approx([0.0]) and qd == pytest.approx([0.0])
    assert moving.at(1 / 3)[0][0] == pytest.approx(0.3 * 4 / 27)    # the overshoot's peak


def test_a_trajectory_message_is_read_in_joint_order_or_refused_with_a_reason():
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    from flexarm_core.ros.trajectory_message import trajectory_from

    names = ['joint4', 'joint3', 'joint2', 'joint1']
    msg = JointTrajectory(joint_names=names, points=[JointTrajectoryPoint(
        positions=[4.0, 3.0, 2.0, 1.0], time_from_start=Duration(sec=1, nanosec=500_000_000))])
    trajectory = trajectory_from(msg)
    assert trajectory.end.tolist() == [1.0, 2.0, 3.0, 4.0] and trajectory.duration == 1.5
    assert not np.any(trajectory.velocities)
    with pytest.raises(ValueError, match='trajectory joints'):
        trajectory_from(JointTrajectory(joint_names=names[:3], points=msg.points))
    msg.points[0].velocities = [0.1]
    with pytest.raises(ValueError, match='a position .or velocity. per joint'):
        trajectory_from(msg)
