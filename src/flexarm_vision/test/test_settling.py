"""Settledness from joint stillness and image stability."""
import numpy as np
import pytest

from flexarm_vision.settling import SettleDetector, SettleSettings

SETTINGS = SettleSettings(still_time=2.0, velocity_tolerance=1e-4, window=3,
                          stability=0.02e-3, angle_stability=1e-5)
STILL = np.zeros(4)
POSE = np.array([1.4, -0.15, -0.78])


def run(detector: SettleDetector, t0: float, t1: float, pose_at) -> str | None:
    reason = None
    for t in np.arange(t0, t1, 0.1):
        detector.update_joints(t, STILL)
        reason = detector.update_estimate(t, pose_at(t))
    return reason


def test_still_and_stable_is_settled() -> None:
    d = SettleDetector(SETTINGS)
    assert run(d, 0.0, 1.0, lambda t: POSE) is not None      # not still long enough
    assert run(d, 1.0, 3.0, lambda t: POSE) is None


def test_vibrating_tip_is_not_settled_although_joints_are_still() -> None:
    d = SettleDetector(SETTINGS)
    reason = run(d, 0.0, 5.0, lambda t: POSE + [1e-4 * np.sin(2 * np.pi * 3.6 * t), 0, 0])
    assert reason is not None and 'vibrating' in reason


def test_joint_motion_resets_and_invalid_frames_are_never_settled() -> None:
    d = SettleDetector(SETTINGS)
    run(d, 0.0, 3.0, lambda t: POSE)
    d.update_joints(3.0, np.array([0.0, 0.01, 0.0, 0.0]))
    assert 'moving' in d.update_estimate(3.0, POSE)
    assert run(d, 3.1, 4.0, lambda t: POSE) is not None
    assert d.update_estimate(10.0, None) == 'invalid measurement'


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError):
        SettleSettings.from_dict({'still_time': 1, 'velocity_tolerance': 1e-4, 'window': 1,
                                  'stability': 1e-5, 'angle_stability': 1e-5})
