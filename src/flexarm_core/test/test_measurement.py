"""Averaging tip-pose frames."""
import math

import numpy as np
import pytest

from flexarm_core.measurement import average_frames


def test_average_and_spread() -> None:
    poses = np.array([[1.0, 2.0, 0.1], [1.2, 2.0, 0.3]])
    m = average_frames(poses, holes_used=7, residual=1e-5)
    np.testing.assert_allclose(m.pose, [1.1, 2.0, 0.2], atol=1e-12)
    np.testing.assert_allclose(m.spread, [0.1, 0.0, 0.1], atol=1e-12)
    assert (m.frames, m.holes_used, m.residual) == (2, 7, 1e-5)


def test_angles_near_pi_do_not_cancel() -> None:
    poses = np.array([[0, 0, math.pi - 0.01], [0, 0, -math.pi + 0.01]])
    m = average_frames(poses, 5, 0.0)
    assert abs(abs(m.pose[2]) - math.pi) < 1e-9
    assert m.spread[2] == pytest.approx(0.01)


def test_no_frames_is_an_error() -> None:
    with pytest.raises(ValueError):
        average_frames(np.empty((0, 3)), 0, 0.0)
