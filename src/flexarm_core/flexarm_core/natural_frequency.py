"""The tip's first natural frequency over payload and No.2 arm length (paper Table 6).

Shared by the simulator (its truth, config/sim.yaml ``dynamics.natural_frequency``) and the
control side (the nominal tip mode of the robot description, config/arm.yaml
``arm.tip_mode.natural_frequency``, from which input shapers are designed): one reading of the
table for both. 1/f² (∝ effective mass) is interpolated linearly in payload (extrapolated down
to 0 kg, held at the largest tabulated payload above it) and f linearly in the arm length,
clamped to the measured range. Pure numpy.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class NaturalFrequency:
    """Table 6: natural frequency [Hz] over payload [kg] × No.2 arm length [m]."""

    payloads: np.ndarray      # (2,) or more, strictly increasing, >= 0
    extensions: np.ndarray    # (k,), strictly increasing
    hz: np.ndarray            # (payloads, extensions); config: flat, payload-major

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> NaturalFrequency:
        payloads = np.asarray(d['payloads'], dtype=float)
        extensions = np.asarray(d['extensions'], dtype=float)
        hz = np.asarray(d['hz'], dtype=float)
        if hz.size != payloads.size * extensions.size or np.any(hz <= 0) or payloads.size < 2:
            raise ValueError('natural_frequency.hz: positive, payloads x extensions values')
        if (extensions.size < 1 or np.any(np.diff(payloads) <= 0)
                or np.any(np.diff(extensions) <= 0) or payloads[0] < 0):
            raise ValueError('natural_frequency: payloads (>= 0) and extensions must be '
                             f'strictly increasing, got {payloads} and {extensions}')
        return cls(payloads, extensions, hz.reshape(payloads.size, extensions.size))

    def __call__(self, payload: float, extension: float) -> float:
        """[Hz]; above the largest tabulated payload the frequency stays at that payload's."""
        ext = float(np.clip(extension, self.extensions[0], self.extensions[-1]))
        per_payload = [np.interp(ext, self.extensions, row) for row in self.hz]
        inv_sq = 1.0 / np.square(per_payload)
        p = self.payloads
        i = int(np.clip(np.searchsorted(p, payload) - 1, 0, p.size - 2))
        slope = (inv_sq[i + 1] - inv_sq[i]) / (p[i + 1] - p[i])
        value = inv_sq[i] + slope * (min(payload, p[-1]) - p[i])
        return float(1.0 / math.sqrt(max(value, 1e-12)))
