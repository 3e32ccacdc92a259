"""A model's 95 % bound calibrated on held-out samples: it covers what it says on new samples
of the same kind, it is not wider than it needs, and a raw std that lies is corrected."""
import math

import numpy as np
import pytest

from flexarm_deflection.error_bound import (
    BoundCalibration,
    calibrate,
    conformal_exists,
    split,
)


def held_out(n: int, true_std: float, stated_std: float, seed: int = 0):
    """Residuals (n, 3) of a model whose error has per-axis std ``true_std`` (m, and rad for
    the angle) where it states ``stated_std``, varying over the samples by up to 4x."""
    rng = np.random.default_rng(seed)
    level = rng.uniform(1.0, 4.0, n)[:, None]
    return (rng.normal(0.0, true_std, (n, 3)) * level,
            np.full((n, 3), stated_std) * level)


@pytest.mark.parametrize('stated', [1e-5, 1e-4, 1e-3])
def test_the_bound_covers_95_percent_of_new_samples_whatever_the_raw_std_said(stated):
    residuals, std = held_out(200, 1e-4, stated)
    calibration = calibrate(residuals, std)
    new_residuals, new_std = held_out(4000, 1e-4, stated, seed=1)
    bound = calibration.bound(new_std)
    position, angle = split(new_residuals)
    assert 0.94 <= np.mean(position <= bound[:, 0]) <= 0.99
    assert 0.94 <= np.mean(angle <= bound[:, 1]) <= 0.99
    assert 0.9 <= calibration.coverage <= 1.0 and 0.9 <= calibration.angle_coverage <= 1.0


def test_few_samples_state_a_wider_bound_than_many():
    """Below 19 held-out samples no 95 % quantile exists: the Gaussian scale's upper
    confidence limit keeps a few lucky folds from stating a bound the next goal breaks."""
    def evenly(n: int) -> tuple[np.ndarray, np.ndarray]:
        """Errors at the n evenly spaced quantiles of a normal error (std 1e-4 per axis):
        the same spread, told by fewer or more samples."""
        from scipy.stats import norm, rayleigh

        levels = (np.arange(n) + 0.5) / n
        radius, angle = rayleigh.ppf(levels, scale=1e-4), norm.ppf(levels, scale=1e-4)
        residuals = np.column_stack([radius, np.zeros(n), angle])
        return residuals, np.full((n, 3), 1e-4)

    few, many = calibrate(*evenly(10)), calibrate(*evenly(400))
    assert few.position_scale > 1.1 * many.position_scale
    assert few.angle_scale > 1.1 * many.angle_scale
    assert 1.7 < many.position_scale < 2.1 and 1.9 < many.angle_scale < 2.4


def test_a_model_without_a_raw_std_gets_a_constant_bound():
    residuals = np.random.default_rng(2).normal(0.0, 1e-4, (100, 3))
    calibration = calibrate(residuals, np.zeros((100, 3)))
    bound = calibration.bound(np.zeros((5, 3)))
    assert np.all(bound == bound[0]) and 2e-4 < bound[0, 0] < 4e-4


def test_the_prior_adds_at_its_own_95_percent_point_in_quadrature():
    calibration = BoundCalibration(2.0, 2.0, 1e-6, 1e-6, 40, 0.95, 0.95)
    bound = calibration.bound(np.array([3e-5, 4e-5, 1e-5]), np.array([0.0, 1e-3, 0.0]))
    assert bound[0] == pytest.approx(math.hypot(2 * 5e-5, 1.96 * 1e-3), rel=1e-4)
    assert bound[1] == pytest.approx(2e-5)


def test_the_calibration_round_trips_and_refuses_what_it_cannot_use():
    calibration = calibrate(*held_out(30, 1e-4, 1e-4))
    assert BoundCalibration.from_dict(calibration.as_dict()) == calibration
    with pytest.raises(ValueError, match='at least 2 samples'):
        calibrate(np.zeros((1, 3)), np.zeros((1, 3)))


def test_below_19_held_out_samples_the_plain_bound_is_a_floor():
    """There no 95 % conformal quantile exists, and a model's std of a small fit is unsteady:
    the residuals' own 95 % point holds the bound up where the scaled std falls short."""
    assert not conformal_exists(18) and conformal_exists(19)
    residuals, std = held_out(10, 1e-4, 1e-4)
    few = calibrate(residuals, std)
    assert few.position_plain > 1e-4 and few.angle_plain > 1e-4
    tiny_std = np.full((3, 3), 1e-9)
    assert np.all(few.bound(tiny_std)[:, 0] >= few.position_plain)
    many = calibrate(*held_out(40, 1e-4, 1e-4))
    assert many.position_plain == many.angle_plain == 0.0
