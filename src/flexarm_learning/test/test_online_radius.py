"""The online radius keeps covering 95 % of measured goals when their errors jump, where a
radius calibrated once does not; with nothing changing it stays the calibrated one."""
from __future__ import annotations

import numpy as np

from flexarm_learning.error_radius import conformal_factor
from flexarm_learning.online_radius import BEYOND, OnlineRadius


def errors(rng: np.random.Generator, count: int, scale: float) -> np.ndarray:
    """Radial errors of 3-D Gaussian misses of ``scale`` [m] per axis."""
    return np.linalg.norm(rng.normal(0.0, scale, (count, 3)), axis=1)


def test_a_steady_stream_is_covered_at_95_percent_as_calibrated() -> None:
    rng = np.random.default_rng(0)
    online = OnlineRadius(errors(rng, 200, 1.0))
    start = online.factor
    covered = [online.update(e, 1.0) for e in errors(rng, 4000, 1.0)]
    assert abs(np.mean(covered) - 0.95) < 0.01
    assert abs(online.factor - start) < 0.25 * start


def test_after_the_errors_triple_it_covers_again_and_the_fixed_radius_does_not() -> None:
    rng = np.random.default_rng(1)
    calibration = errors(rng, 200, 1.0)
    fixed = conformal_factor(calibration)
    online = OnlineRadius(calibration)
    for e in errors(rng, 500, 1.0):
        online.update(e, 1.0)
    drifted = errors(rng, 3000, 3.0)
    covered = np.array([online.update(e, 1.0) for e in drifted])
    assert np.mean(drifted <= fixed) < 0.3
    assert np.mean(covered) > 0.93
    assert np.mean(covered[-1000:]) > 0.93          # held, not just made up for early


def test_a_level_run_below_zero_states_a_finite_radius_beyond_every_score() -> None:
    online = OnlineRadius(np.array([1.0, 2.0, 3.0]), gamma=0.5)
    online.update(100.0, 1.0)                       # a miss: α = 0.05 − 0.475 < 0
    assert online.alpha < 0
    assert online.factor == BEYOND * 100.0          # the miss's score joined the window


def test_a_floored_radius_starts_at_its_floor_and_lucky_goals_do_not_sharpen_it() -> None:
    online = OnlineRadius(floor=1.0)
    assert online.factor == 1.0                     # nothing measured: the calibration's
    for e in (0.3, 0.5, 0.4):
        assert online.update(e, 1.0)
    assert online.factor == 1.0
    assert not online.update(4.0, 1.0)
    assert online.factor == 4.0                     # few scores: the largest stands in
