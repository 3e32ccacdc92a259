"""After the move: the measured error against the stated bound, and the online bound that
widens when measured goals leave it and starts again with a new model."""
import math

import numpy as np
import pytest

from flexarm_control.execution.bound_check import (
    BoundParts,
    Inflation,
    OnlineBound,
    OnlineSettings,
    beyond_bound,
    needed_factor,
)
from flexarm_core.params import load_config

CAMERA = np.array([0.02e-3, 1e-4])
SETTINGS = OnlineSettings.from_dict(load_config(
    'compensator.yaml', node_name='flexarm_compensator')['online_bound'])
PARTS = BoundParts(np.array([0.06e-3, 1e-3]), np.array([0.03e-3, 2e-4]))


def test_the_warning_needs_the_camera_s_margin_and_gives_both_figures():
    stated = PARTS.stated
    assert stated[0] == pytest.approx(math.hypot(0.06e-3, 0.03e-3))
    assert beyond_bound((stated[0] + 0.002e-3, 0.0), stated, CAMERA) == ''   # camera noise
    warning = beyond_bound((0.27e-3, 0.0), stated, CAMERA)
    assert warning.startswith('warning: measured error 0.270 mm') and '0.067 mm' in warning
    assert beyond_bound((0.0, 2e-3), stated, CAMERA)                          # the angle too


def test_the_score_is_the_factor_that_would_just_have_covered_the_goal():
    error = (0.3e-3, 0.0)
    factor = needed_factor(error, PARTS, CAMERA)
    just = BoundParts(PARTS.model, PARTS.site, Inflation(factor))
    assert np.hypot(just.stated[0], CAMERA[0]) == pytest.approx(error[0])
    assert factor[1] == 0.0                                       # the angle: within
    assert np.all(needed_factor((0.01e-3, 0.0), PARTS, CAMERA) == 0.0)


def test_an_undeclared_load_widens_the_next_plans_and_a_new_model_starts_again():
    online = OnlineBound(SETTINGS)
    online.reset('7')
    for _ in range(10):                                  # a healthy model: goals within
        assert online.account((0.03e-3, 1e-4), PARTS, CAMERA)
    assert np.all(online.inflation.factor == 1.0) and online.summary() == ''
    assert not online.account((2.0e-3, 1e-4), PARTS, CAMERA)     # 30 times its bound
    assert online.broken
    assert online.inflation.floor[0] == 2 * 2.0e-3 and online.inflation.floor[1] == 0.0
    summary = online.summary()
    assert 'model 7' in summary and '1 of 11' in summary and '2.000 mm' in summary
    assert 'the arm changed' in summary and '4.000 mm' in summary
    small = BoundParts(PARTS.model / 2, PARTS.site, online.inflation)   # the model sure there
    assert small.stated[0] == 4.0e-3
    assert online.account((3.0e-3, 1e-4), small, CAMERA)         # the next one is covered
    for _ in range(30):                                 # still changed: no healthy stretch
        online.account((0.03e-3, 1e-4), PARTS, CAMERA)  # forgets it before a new model
    assert online.broken and online.inflation.floor[0] == 2 * 3.0e-3
    online.reset('8')
    assert np.all(online.inflation.factor == 1.0) and online.goals == 0 and not online.broken
    assert np.all(online.inflation.floor == 0.0)


def test_a_miss_within_the_gross_limit_raises_the_factor_only():
    online = OnlineBound(SETTINGS)
    assert not online.account((0.15e-3, 1e-4), PARTS, CAMERA)   # 2.4 times the model's part
    assert not online.broken and 2.0 < online.inflation.factor[0] < 3.0
    assert online.inflation.factor[1] == 1.0


def test_online_settings_are_checked():
    with pytest.raises(ValueError, match='gross > 1'):
        OnlineSettings.from_dict({'gamma': 0.005, 'window': 100, 'gross': 0.5})
