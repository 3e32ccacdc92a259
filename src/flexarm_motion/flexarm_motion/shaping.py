"""Input shapers: impulse sequences that, convolved with a move, leave the tip's lightly damped
first mode (3.6-12.4 Hz, ζ ≈ 0.05, config/arm.yaml ``arm.tip_mode``) at rest when the move
ends, so the arm need not wait for the ringing to decay (Singer & Seering 1990; EI: Singhose,
Seering & Singer 1994).

Designed at the mode's natural frequency f [Hz] and damping ratio ζ with the damped formulas
K = exp(−ζπ/√(1−ζ²)), Td = 1/(f√(1−ζ²)); amplitudes are normalised to sum to 1:

====  ==================================  ============  ========  ============================
kind  amplitudes (before normalising)     times         duration  V ≤ 5 % for f_actual/f in
====  ==================================  ============  ========  ============================
off   1                                   0             0         nowhere (V = 100 %)
zv    1, K                                0, Td/2       Td/2      0.966-1.035 (±3.5 %)
zvd   1, 2K, K²                           0, Td/2, Td   Td        0.846-1.158 (±15 %)
ei    (1+Vt)/4, (1−Vt)/2·K, (1+Vt)/4·K²   0, Td/2, Td   Td        0.794-1.210 (±20 %)
====  ==================================  ============  ========  ============================

(the last column at ζ = 0.05; at ζ = 0 the bands are ±3.2, ±14 and ±20 %). ZV and ZVD leave
no vibration at f itself; EI leaves up to Vt = 5 % there (4.2 % at ζ = 0.05) to stay below it
over the widest band; its damped amplitudes are the usual approximation, exact at ζ = 0.
V is the residual vibration the shaped impulse leaves relative to an unshaped one
(:func:`residual_vibration`). :func:`choose_shaper` takes the shortest shaper that keeps
V ≤ 5 % over the frequency uncertainty at hand: Table 6's frequency varies threefold with the
payload, so a wrong payload is beyond any of them. Pure numpy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

KINDS = ('off', 'zv', 'zvd', 'ei')   # cheapest first; ZVD before the as long EI: it leaves
                                     # nothing at the design frequency
VTOL = 0.05                          # [-] EI's tolerated vibration, and the choice's limit
BAND_POINTS = 201                    # frequency ratios a band's worst vibration is taken over


@dataclass(frozen=True)
class Shaper:
    """An impulse sequence designed for a mode of ``frequency`` [Hz] and ``damping_ratio``."""

    kind: str
    frequency: float              # [Hz] natural (undamped) frequency designed for
    damping_ratio: float          # [-]
    amplitudes: np.ndarray        # (m,) positive, summing to 1
    times: np.ndarray             # (m,) [s] from 0, increasing

    @classmethod
    def design(cls, kind: str, frequency: float, damping_ratio: float) -> Shaper:
        if kind not in KINDS:
            raise ValueError(f'shaper kind {kind!r}: one of {", ".join(KINDS)}')
        if not (math.isfinite(frequency) and frequency > 0 and 0 <= damping_ratio < 1):
            raise ValueError(f'shaper needs frequency > 0 and 0 <= damping_ratio < 1, got '
                             f'{frequency} Hz and {damping_ratio}')
        root = math.sqrt(1.0 - damping_ratio ** 2)
        k = math.exp(-damping_ratio * math.pi / root)
        td = 1.0 / (frequency * root)
        raw, times = {
            'off': ([1.0], [0.0]),
            'zv': ([1.0, k], [0.0, td / 2]),
            'zvd': ([1.0, 2 * k, k * k], [0.0, td / 2, td]),
            'ei': ([(1 + VTOL) / 4, (1 - VTOL) / 2 * k, (1 + VTOL) / 4 * k * k],
                   [0.0, td / 2, td]),
        }[kind]
        amplitudes = np.asarray(raw) / sum(raw)
        return cls(kind, float(frequency), float(damping_ratio), amplitudes, np.asarray(times))

    @property
    def duration(self) -> float:
        """[s] the shaper adds to a move."""
        return float(self.times[-1])


def residual_vibration(shaper: Shaper, ratio: float | np.ndarray) -> np.ndarray:
    """Residual vibration V [-] (0.05 = 5 %) of a mode at ``ratio`` × the design frequency
    (same damping) after the shaper's impulses, relative to a single unit impulse's."""
    r = np.atleast_1d(np.asarray(ratio, dtype=float))[:, None]
    omega = 2 * math.pi * shaper.frequency * r
    sigma = shaper.damping_ratio * omega
    omega_d = omega * math.sqrt(1.0 - shaper.damping_ratio ** 2)
    weight = shaper.amplitudes * np.exp(sigma * shaper.times)
    c = (weight * np.cos(omega_d * shaper.times)).sum(axis=1)
    s = (weight * np.sin(omega_d * shaper.times)).sum(axis=1)
    return np.exp(-sigma[:, 0] * shaper.duration) * np.hypot(c, s)


def worst_vibration(shaper: Shaper, uncertainty: float) -> float:
    """Largest V [-] over actual frequencies within ±``uncertainty`` (relative) of the design."""
    return float(residual_vibration(
        shaper, np.linspace(1 - uncertainty, 1 + uncertainty, BAND_POINTS)).max())


def choose_shaper(frequency: float, damping_ratio: float, uncertainty: float,
                  limit: float = VTOL) -> Shaper:
    """The shortest shaper whose V stays ≤ ``limit`` while the actual frequency lies within
    ±``uncertainty`` (relative, < 1) of ``frequency``; where none does, the one leaving the
    least vibration at the band's worst (the frequency is too uncertain for shaping alone)."""
    if not 0 <= uncertainty < 1:
        raise ValueError(f'frequency uncertainty must lie in [0, 1), got {uncertainty}')
    shapers = [Shaper.design(kind, frequency, damping_ratio) for kind in KINDS]
    worst = [worst_vibration(s, uncertainty) for s in shapers]
    fit = [s for s, v in zip(shapers, worst) if v <= limit]
    return fit[0] if fit else shapers[int(np.argmin(worst))]
