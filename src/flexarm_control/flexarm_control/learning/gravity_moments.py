"""Gravity moments of the arm's parts about its compliant elements (pure; no rclpy).

The structure of the grey-box deflection model (:mod:`.predictors.greybox`): the nominal part
masses of the robot description (config/arm.yaml ``arm.inertia``: what a site knows, not the
simulator's truth) and the payload at the tip, placed along the rigid arm (``arm.*``) — No.2
arm beam centred ``beam_length``/2 behind joint3, the joint2 drive ``second_axis_position``
along the arm from joint1, each link's mass at its middle, the joint3 and joint4 axes at their
joints, the end effector ``end_effector_com`` beyond the tip. The moment about an element is
M_z = −g Σ m (x − x_element) over the parts beyond it (small-deflection approximation: on the
rigid pose), in N·m; it is linear in the payload.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

GRAVITY = 9.80665       # [m/s²]
ELEMENTS = ('joint1', 'arm2', 'joint3', 'joint4')   # arm2: the No.2 arm's root (its guide)
PARTS = ('second_axis', 'second_arm', 'third_axis', 'third_arm', 'fourth_axis', 'fourth_arm',
         'end_effector')


@dataclass(frozen=True)
class ArmMasses:
    """Nominal geometry [m] and part masses [kg] of the arm, as the moments need them."""

    link3: float                  # joint3 -> joint4
    link4: float                  # joint4 -> tip
    offset: float                 # lateral offset of the No.2 arm axis
    masses: Mapping[str, float]   # the names of PARTS
    beam_length: float            # the sliding No.2 arm
    second_axis_position: float   # joint2 drive along the arm from joint1
    end_effector_com: float       # end-effector CoM beyond the tip

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ArmMasses:
        """From :meth:`as_dict` (a saved model) — ValueError if a part is missing."""
        masses = {name: float(d['masses'][name]) for name in PARTS}
        if min(masses.values()) < 0:
            raise ValueError(f'part masses must be >= 0 kg, got {masses}')
        return cls(float(d['link3']), float(d['link4']), float(d['offset']), masses,
                   float(d['beam_length']), float(d['second_axis_position']),
                   float(d['end_effector_com']))

    @classmethod
    def from_description(cls, arm: Mapping[str, Any]) -> ArmMasses:
        """From the robot description: config/arm.yaml ``arm`` (geometry and ``inertia``)."""
        return cls.from_dict({**{k: arm[k] for k in ('link3', 'link4', 'offset')},
                              **arm['inertia']})

    def as_dict(self) -> dict[str, Any]:
        return {**asdict(self), 'masses': dict(self.masses)}

    def moments(self, joints: np.ndarray, payload: np.ndarray | float) -> np.ndarray:
        """M_z [N·m] (..., 4) about ``ELEMENTS`` at joints (..., 4) with payload [kg] at the
        tip; negative for the downward load of an arm pointing along +x."""
        m = self.masses
        q = np.asarray(joints, dtype=float)
        t1, t2 = q[..., 0], q[..., 1]
        c1, s1 = np.cos(t1), np.sin(t1)
        c13, c134 = np.cos(t1 + q[..., 2]), np.cos(t1 + q[..., 2] + q[..., 3])
        x3 = t2 * c1 - self.offset * s1                    # joint3
        x4 = x3 + self.link3 * c13                         # joint4
        xt = x4 + self.link4 * c134                        # tip
        beyond4 = (m['fourth_arm'] * (x4 + 0.5 * self.link4 * c134)
                   + m['end_effector'] * (xt + self.end_effector_com * c134) + payload * xt)
        mass4 = m['fourth_arm'] + m['end_effector'] + payload
        beyond3 = (m['third_arm'] * (x3 + 0.5 * self.link3 * c13) + m['fourth_axis'] * x4
                   + beyond4)
        mass3 = m['third_arm'] + m['fourth_axis'] + mass4
        arm2 = (m['second_arm'] * ((t2 - 0.5 * self.beam_length) * c1 - self.offset * s1)
                + m['third_axis'] * x3 + beyond3)
        return -GRAVITY * np.stack([arm2 + m['second_axis'] * self.second_axis_position * c1,
                                    arm2, beyond3 - mass3 * x3, beyond4 - mass4 * x4], axis=-1)


@dataclass(frozen=True)
class InertiaUncertainty:
    """One standard deviation of the nominal inertia (config/arm.yaml
    ``arm.inertia_uncertainty``)."""

    common: float              # relative, every part's mass together
    part: float                # relative, each part's mass on its own
    end_effector_com: float    # [m]

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> InertiaUncertainty:
        u = cls(float(d['common']), float(d['part']), float(d['end_effector_com']))
        if min(u.common, u.part, u.end_effector_com) < 0:
            raise ValueError(f'inertia uncertainties must be >= 0, got {u}')
        return u


def moment_spread(arm: ArmMasses, uncertainty: InertiaUncertainty, joints: np.ndarray
                  ) -> np.ndarray:
    """Std [N·m] (..., 4) of the parts' moments about ``ELEMENTS`` at joints (..., 4) that
    the inertia's uncertainty leaves (the payload's moment is exact: it is declared). The
    moments are linear in the masses: each part's own moment is the derivative; the CoM's by
    a central difference."""
    zero = {name: 0.0 for name in PARTS}
    own = np.stack([replace(arm, masses={**zero, name: arm.masses[name]}).moments(joints, 0.0)
                    for name in PARTS])                  # (parts, ..., 4)
    step = 1e-3
    com = (replace(arm, end_effector_com=arm.end_effector_com + step).moments(joints, 0.0)
           - replace(arm, end_effector_com=arm.end_effector_com - step).moments(joints, 0.0)
           ) / (2 * step)
    return np.sqrt((uncertainty.part ** 2) * (own ** 2).sum(axis=0)
                   + (uncertainty.common * own.sum(axis=0)) ** 2
                   + (uncertainty.end_effector_com * com) ** 2)
