"""The tip mode's frequency and damping from the camera's view of its ringing after a move.

The camera samples the tip at a few hertz (5 Hz), far below the 3.6-12.4 Hz mode: the ringing
appears at an alias f_a = |f − k·fs| in [0, fs/2]. Its decay is not aliased: the envelope
e^(−σt), σ = ζ·2πf, is what it is. :func:`identify_ring_down` fits the planar samples with a
damped sinusoid plus a constant per axis (shared f_a and σ; variable projection: the phases,
amplitudes and rest pose are linear), then resolves the alias with the nominal frequency as a
prior: of the candidates k·fs ± f_a, the one within ±``prior_tolerance`` of it, and ζ = σ/2πf.

It refuses (None and the reason) when the ringing is too small or too short against the noise,
or when the prior does not single out one candidate. The latter is a property of the sampling,
not of the fit: at 5 Hz, modes near a multiple of 2.5 Hz alias near 0 or 2.5 Hz, where k·fs + f_a
and k·fs − f_a lie close together (Table 6's 9.93 Hz at 0.2 kg, 0.8 m aliases to 0.07 Hz: 9.93
and 10.07 Hz look alike), and a ringing that decays within a few frames (σ = 3.1/s at 9.93 Hz:
the envelope falls 46 % between frames) leaves little to fit. Pure numpy/scipy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

MIN_SAMPLES = 8       # frames above the noise: 3 unknowns per axis and 2 shared, and to spare
MIN_SNR = 10.0        # first-frame ring amplitude over the fit's rms residual
ALIAS_STEPS = 64      # alias frequencies of the coarse search over [0, fs/2]
DECAY_STEPS = 48      # decay rates of the coarse search


@dataclass(frozen=True)
class ModeEstimate:
    """The tip mode as a ring-down shows it."""

    frequency: float        # [Hz] natural (undamped), the alias resolved with the prior
    damping_ratio: float    # [-]
    alias: float            # [Hz] the ringing's apparent frequency in the samples, 0..fs/2
    decay_rate: float       # [1/s] σ of the envelope e^(−σt)
    amplitude: float        # [m] of the ringing at the first sample
    noise: float            # [m] rms residual of the fit per coordinate


def _basis(t: np.ndarray, decay: float, alias: float) -> np.ndarray:
    envelope = np.exp(-decay * t)
    phase = 2 * math.pi * alias * t
    return np.column_stack([np.ones_like(t), envelope * np.cos(phase), envelope * np.sin(phase)])


def _residual(params: np.ndarray, t: np.ndarray, y: np.ndarray) -> np.ndarray:
    basis = _basis(t, *params)
    coef = np.linalg.lstsq(basis, y, rcond=None)[0]
    return (y - basis @ coef).ravel()


def identify_ring_down(times: np.ndarray, positions: np.ndarray, prior: float,
                       prior_tolerance: float = 0.1) -> tuple[ModeEstimate | None, str]:
    """Fit the ringing in tip samples taken after a move ended: ``times`` (k,) [s],
    ``positions`` (k, 2 or 3) [m, m(, rad)] (only x and y are used: the angle's unit and
    noise differ), ``prior`` the nominal frequency [Hz], trusted within ±``prior_tolerance``
    (relative). (estimate, '') or (None, why not)."""
    t = np.asarray(times, dtype=float)
    y = np.asarray(positions, dtype=float)
    y = y[:, :2] if y.ndim == 2 else y[:, None]
    if t.ndim != 1 or y.shape[0] != t.size:
        return None, 'times and positions must have one row per sample'
    if t.size < MIN_SAMPLES:
        return None, f'{t.size} samples; at least {MIN_SAMPLES} needed'
    steps = np.diff(t)
    if np.any(steps <= 0):
        return None, 'sample times must increase'
    t = t - t[0]
    rate = 1.0 / float(np.median(steps))
    aliases = np.linspace(0.0, rate / 2, ALIAS_STEPS)
    decays = np.geomspace(0.01, 2 * math.pi * prior, DECAY_STEPS)
    cost = [(float(np.sum(_residual(np.array([d, f]), t, y) ** 2)), d, f)
            for d in decays for f in aliases]
    start = np.array(min(cost)[1:])
    fit = least_squares(_residual, start, args=(t, y),
                        bounds=([0.0, 0.0], [2 * math.pi * prior * (1 + prior_tolerance),
                                             rate / 2]), x_scale=start + 0.1)
    decay, alias = (float(v) for v in fit.x)
    basis = _basis(t, decay, alias)
    coef = np.linalg.lstsq(basis, y, rcond=None)[0]
    noise = math.sqrt(2 * fit.cost / max(y.size - 3 * y.shape[1] - 2, 1))
    amplitude = float(np.linalg.norm(coef[1:]))
    if amplitude < MIN_SNR * noise:
        return None, (f'ringing of {amplitude * 1e6:.1f} um against {noise * 1e6:.1f} um of '
                      'noise: too small to identify')
    above = int(np.sum(amplitude * np.exp(-decay * t) > 3 * noise))
    if above < MIN_SAMPLES:
        return None, (f'the ringing stands above the noise for {above} samples; at least '
                      f'{MIN_SAMPLES} needed')
    band = (prior * (1 - prior_tolerance), prior * (1 + prior_tolerance))
    top = int(band[1] / rate) + 1
    candidates = sorted({abs(k * rate + sign * alias) for k in range(top + 1)
                         for sign in (1, -1)})
    inside = [f for f in candidates if band[0] <= f <= band[1]]
    if len(inside) != 1:
        return None, (f'alias {alias:.2f} Hz at {rate:.2f} Hz sampling: '
                      f'{len(inside)} candidate frequencies within ±{prior_tolerance:.0%} of '
                      f'{prior:.2f} Hz ({", ".join(f"{f:.2f}" for f in inside) or "none"})')
    omega = math.hypot(2 * math.pi * inside[0], decay)
    return ModeEstimate(omega / (2 * math.pi), decay / omega, alias, decay, amplitude,
                        noise), ''
