"""The paper's benchmark numbers (Tables 8, 9 and 10), for side-by-side reports.

Units as printed in the paper: mm and degrees.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PaperTarget:
    name: str
    region: str                                  # learner region preset used for it
    target: tuple[float, float, float]           # x mm, y mm, phi deg
    rigid: tuple[float, float, float] | None     # pose reached by the rigid model (Table 10)
    compensated: tuple[float, float, float] | None   # reached with the neural network

    @property
    def pose(self) -> np.ndarray:
        """The target in SI units (m, m, rad)."""
        x, y, phi = self.target
        return np.array([x / 1e3, y / 1e3, math.radians(phi)])

    @staticmethod
    def errors(target: tuple[float, float, float], reached: tuple[float, float, float] | None
               ) -> tuple[float, float] | None:
        if reached is None:
            return None
        return (math.hypot(reached[0] - target[0], reached[1] - target[1]),
                abs(reached[2] - target[2]))

    @property
    def rigid_errors(self) -> tuple[float, float] | None:
        """(position mm, |angle| deg) of the paper's rigid-model control."""
        return self.errors(self.target, self.rigid)

    @property
    def compensated_errors(self) -> tuple[float, float] | None:
        return self.errors(self.target, self.compensated)


# Table 10 (benchmark experiments). Target 3's rigid x is printed 1448.5, 101 mm off while
# its y and angle errors are 16 mm and 3.8 deg: read as 1548.5.
TABLE_10 = (
    PaperTarget('A1', 'A', (1450, -150, -45), (1444.1, -161.6, -46.2), (1450.4, -150.8, -44.9)),
    PaperTarget('A2', 'A', (1550, 0, -22), (1545.8, -15.5, -24.0), (1550.4, -1.1, -22.0)),
    PaperTarget('A3', 'A', (1550, 150, -6), (1548.5, 133.9, -9.8), (1551.3, 148.3, -6.3)),
    PaperTarget('B4', 'B', (1000, -500, -100), (1002.1, -505.1, -99.0), (1000.0, -500.5, -99.9)),
    PaperTarget('B5', 'B', (1150, -350, -70), (1147.3, -355.0, -70.3), (1149.5, -350.5, -70.0)),
    PaperTarget('B6', 'B', (1300, -200, -61), (1295.8, -207.1, -61.7), (1299.8, -200.5, -61.1)),
)

# Table 9 (simulation, No.2 arm 600 mm, target angle 0): the paper gives the targets only in
# its Fig. 5(b); ours are five poses of that workspace reachable with joint2 = 600 mm. Paper
# errors (position mm, angle deg): rigid model, and 40 learning samples.
TABLE_9 = (
    ('S1', (1300, 0, 0), (9.93, 2.00), (0.373, 5.48e-4)),
    ('S2', (1250, -150, 0), (18.2, None), (0.940, 2.45e-3)),
    ('S3', (1200, 100, 0), (15.5, 2.40), (0.756, 9.92e-4)),
    ('S4', (1100, -250, 0), (15.3, 2.41), (0.547, 3.61e-4)),
    ('S5', (1350, -100, 0), (20.0, None), (0.690, 1.66e-2)),
)

# Table 8: max prediction error at 10 hidden units vs learning samples: x mm, y mm, phi deg.
TABLE_8 = {30: (3.46, 2.30, 0.046), 40: (1.72, 1.51, 0.030), 50: (1.66, 0.97, 0.032)}
# Table 7: normalised fitting error vs hidden units at 50 samples.
TABLE_7 = {5: 0.07, 10: 0.04, 15: 0.05}
