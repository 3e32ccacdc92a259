"""The tip mode identified from a 5 Hz camera's view of its ring-down: the 5 kg modes (alias
1.1-1.4 Hz) are, the light payload's near 10 Hz (alias near 0) are refused, as are rings too
small or too short to fit."""
import math

import numpy as np
import pytest

from flexarm_control.execution.ring_down import identify_ring_down

RATE = 5.0    # [Hz] camera frames in simulated time


def ring_down(frequency: float, zeta: float, amplitude: float, count: int,
              noise: float = 1e-6, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Frames of a planar tip ringing about its rest pose, with camera noise [m]."""
    rng = np.random.default_rng(seed)
    omega = 2 * math.pi * frequency
    t = 0.13 + np.arange(count) / RATE
    phase = rng.uniform(0, 2 * math.pi, 2)
    envelope = amplitude * np.exp(-zeta * omega * t)[:, None]
    swing = envelope * [1.0, 0.4] * np.cos(omega * math.sqrt(1 - zeta ** 2) * t[:, None] + phase)
    pose = np.tile([0.8, 0.3, 0.1], (count, 1))
    pose[:, :2] += swing
    return t, pose + rng.normal(0.0, noise, pose.shape)


@pytest.mark.parametrize('frequency, prior', [(3.6, 3.77), (3.86, 3.77), (3.77, 3.5)])
def test_a_heavy_payload_mode_is_identified_through_its_alias(frequency, prior):
    estimate, reason = identify_ring_down(*ring_down(frequency, 0.05, 1e-3, 25), prior=prior)
    assert reason == '' and estimate is not None
    assert estimate.frequency == pytest.approx(frequency, rel=2e-3)
    assert estimate.damping_ratio == pytest.approx(0.05, rel=0.03)
    assert estimate.alias == pytest.approx(5.0 - frequency, abs=0.01)
    assert estimate.amplitude == pytest.approx(1e-3 * math.exp(-0.05 * 2 * math.pi * frequency
                                                               * 0.13), rel=0.5)
    assert estimate.noise == pytest.approx(1e-6, rel=0.5)


def test_a_light_payload_mode_near_10_hz_is_ambiguous():
    estimate, reason = identify_ring_down(*ring_down(9.93, 0.05, 1e-3, 25), prior=9.93)
    assert estimate is None and 'candidate frequencies' in reason


@pytest.mark.parametrize('amplitude, count, reason', [
    (5e-6, 25, 'too small'),
    (1e-4, 25, 'above the noise for'),     # 12 Hz: gone within 5 frames
    (1e-3, 6, 'at least 8 needed'),
])
def test_too_little_ringing_is_refused(amplitude, count, reason):
    frequency = 12.0 if amplitude == 1e-4 else 3.7
    estimate, why = identify_ring_down(*ring_down(frequency, 0.05, amplitude, count),
                                       prior=frequency)
    assert estimate is None and reason in why


def test_a_mode_away_from_the_prior_is_refused():
    """3.7 Hz aliases to 1.3 Hz: 3.7 or 6.3 Hz, neither within 10 % of 5 Hz. (A prior of
    6 Hz would take 6.3 Hz: the prior must be right to within the candidates' spacing.)"""
    estimate, reason = identify_ring_down(*ring_down(3.7, 0.05, 1e-3, 25), prior=5.0)
    assert estimate is None and '0 candidate frequencies' in reason
