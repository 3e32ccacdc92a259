"""Static model of the actual, flexible arm: where the tip really is for given joint positions.

Built from the paper's measured characteristics (Tables 3-5; every number and every reading of
an ambiguous one is in config/sim.yaml ``plant.*``):

* Gravity moments (kgf·m, the unit of Table 5) at each compliant element from the part masses
  of Table 3 and the payload, with the parts placed along the rigid arm.
* Joint compliance of the harmonic drives (joints 1, 3, 4) and of the No.2 arm's linear-motion
  guide: rotation = c · M, where c is the "positive area" constant for a moment that loads the
  element like a downward load on the arm pointing along +x (M_z < 0) and the "negative area"
  constant otherwise.
* Bending of arms 2, 3 and 4: lateral deflection and end rotation of each arm per kgf·m of
  moment at its root, positive/negative as above.
* Table 5 read literally makes the arm twice as soft at the tip as Table 4 measured directly
  (P12/P13); ``compliance_scale`` reconciles them (see config/sim.yaml).
* Backlash: each joint sits at ± half its play on the side the moment pushes it, smoothed over
  ``backlash_smoothing`` kgf·m (static friction keeps a real joint from snapping across).
* Fabrication errors: link-length, offset and joint-zero errors of the real arm.
* Optional per call (the error sources of :mod:`flexarm_sim.errors`): friction offsets of the
  four elements on top of their backlash (hysteresis) and a thermal strain that grows every
  length of the arm uniformly about joint 1.

Small-deflection approximation: the moments are computed on the rigid pose. Deterministic,
vectorised over any leading axes of the joint array; no rclpy.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_core.kinematics import ArmGeometry, forward, wrap_angle
from flexarm_core.params import load_config

MM = 1e-3


@dataclass(frozen=True)
class Compliance:
    """A sign-dependent compliance: ``positive`` for M_z < 0 (downward load), else ``negative``."""

    positive: float
    negative: float

    def __call__(self, moment: np.ndarray) -> np.ndarray:
        return np.where(moment < 0, self.positive, self.negative) * moment

    @classmethod
    def from_pair(cls, pair: Any, scale: float = 1.0) -> Compliance:
        positive, negative = (float(v) * scale for v in pair)
        if positive < 0 or negative < 0:
            raise ValueError(f'compliances must be non-negative, got {pair}')
        return cls(positive, negative)


@dataclass(frozen=True)
class Plant:
    """The actual arm: rigid geometry + fabrication errors + gravity deflection."""

    geometry: ArmGeometry
    payload: float                    # [kg] at the tip
    gravity: float                    # [standard gravities]; 0 switches deflection off
    masses: Mapping[str, float]       # [kg] Table 3 parts
    beam_length: float                # [m] physical length of the sliding No.2 arm (L1)
    second_axis_position: float       # [m] of the joint2 drive along the arm from joint1
    end_effector_com: float           # [m] of the end-effector CoM beyond the tip point
    joint_compliance: tuple[Compliance, Compliance, Compliance, Compliance]  # J1, LM, J3, J4
    arm_deflection: tuple[Compliance, Compliance, Compliance]   # arms 2, 3, 4 [m/(kgf·m)]
    arm_angle: tuple[Compliance, Compliance, Compliance]        # arms 2, 3, 4 [rad/(kgf·m)]
    backlash: np.ndarray              # (4,) full play of J1, LM, J3, J4 [rad]
    backlash_smoothing: float         # [kgf·m]
    joint_zero_error: np.ndarray      # (4,) added to joints 1..4 [rad, m, rad, rad]
    link3_error: float                # [m]
    link4_error: float                # [m]
    offset_error: float               # [m]

    def __post_init__(self) -> None:
        if not (math.isfinite(self.payload) and self.payload >= 0):
            raise ValueError(f'plant payload must be finite and >= 0 kg, got {self.payload}')

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], geometry: ArmGeometry) -> Plant:
        """From config/sim.yaml ``plant.*``. Any finite payload >= 0 is modelled statically;
        the dynamics hold the tip frequency at Table 6's largest payload above it."""
        c, f = d['compliance'], d['fabrication']
        scale = float(d['compliance_scale'])
        if scale < 0:
            raise ValueError('plant.compliance_scale must be non-negative')
        plant = cls(
            geometry=geometry, payload=float(d['payload']), gravity=float(d['gravity']),
            masses={k: float(v) for k, v in d['masses'].items()},
            beam_length=float(d['beam_length']),
            second_axis_position=float(d['second_axis_position']),
            end_effector_com=float(d['end_effector_com']),
            joint_compliance=tuple(Compliance.from_pair(c[k], scale) for k in (
                'joint1', 'guide2', 'joint3', 'joint4')),
            arm_deflection=tuple(Compliance.from_pair(c[k], MM * scale) for k in (
                'arm2_deflection', 'arm3_deflection', 'arm4_deflection')),
            arm_angle=tuple(Compliance.from_pair(c[k], scale) for k in (
                'arm2_angle', 'arm3_angle', 'arm4_angle')),
            backlash=np.asarray(d['backlash'], dtype=float),
            backlash_smoothing=float(d['backlash_smoothing']),
            joint_zero_error=np.asarray(f['joint_zero'], dtype=float),
            link3_error=float(f['link3']), link4_error=float(f['link4']),
            offset_error=float(f['offset']))
        missing = {'second_axis', 'second_arm', 'third_axis', 'third_arm', 'fourth_axis',
                   'fourth_arm', 'end_effector'} - set(plant.masses)
        if missing:
            raise ValueError(f'plant.masses lacks {sorted(missing)}')
        if plant.backlash.shape != (4,) or np.any(plant.backlash < 0):
            raise ValueError('plant needs 4 non-negative backlash values')
        if plant.joint_zero_error.shape != (4,) or plant.backlash_smoothing <= 0:
            raise ValueError('plant needs 4 joint_zero errors and backlash_smoothing > 0')
        return plant

    def with_payload(self, payload: float) -> Plant:
        """The same arm carrying another payload."""
        return Plant(**{**self.__dict__, 'payload': float(payload)})

    def moments(self, joints: np.ndarray) -> dict[str, np.ndarray]:
        """Gravity moments M_z [kgf·m] at joint1, the guide/arm-2 root, joint3 and joint4."""
        g, m = self.geometry, self.masses
        q = np.asarray(joints, dtype=float)
        t1, t2, t3, t4 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
        c1, s1 = np.cos(t1), np.sin(t1)
        c13, c134 = np.cos(t1 + t3), np.cos(t1 + t3 + t4)
        x3 = t2 * c1 - g.offset * s1                    # joint3
        x4 = x3 + g.link3 * c13                         # joint4
        xt = x4 + g.link4 * c134                        # tip
        x_ee = xt + self.end_effector_com * c134
        beyond4 = m['fourth_arm'] * (x4 + 0.5 * g.link4 * c134) + (
            m['end_effector'] * x_ee + self.payload * xt)
        mass4 = m['fourth_arm'] + m['end_effector'] + self.payload
        beyond3 = m['third_arm'] * (x3 + 0.5 * g.link3 * c13) + m['fourth_axis'] * x4 + beyond4
        mass3 = m['third_arm'] + m['fourth_axis'] + mass4
        beam = m['second_arm'] * ((t2 - 0.5 * self.beam_length) * c1 - g.offset * s1)
        arm2 = beam + m['third_axis'] * x3 + beyond3
        # M_z of weights w at x about a point at x_p: -(w (x - x_p)), in kgf·m.
        k = -self.gravity
        return {
            'joint1': k * (arm2 + m['second_axis'] * self.second_axis_position * c1),
            'arm2': k * arm2,
            'joint3': k * (beyond3 - mass3 * x3),
            'joint4': k * (beyond4 - mass4 * x4),
        }

    def pose(self, joints: np.ndarray, lag: np.ndarray | None = None,
             strain: float = 0.0) -> np.ndarray:
        """Actual tip pose(s) (..., 3) [m, m, rad] for joint positions (..., 4).

        ``lag`` (..., 4): friction offsets [rad] of J1, the guide, J3 and J4 added to their
        backlash (hysteresis); ``strain``: thermal growth of every length (expansion x ΔT).
        """
        g = self.geometry
        q = np.asarray(joints, dtype=float) + self.joint_zero_error
        mom = self.moments(joints)
        m1, m2, m3, m4 = mom['joint1'], mom['arm2'], mom['joint3'], mom['joint4']
        j1, guide, j3, j4 = self.joint_compliance
        play = self.backlash / 2.0
        smooth = self.backlash_smoothing

        def slack(i: int, moment: np.ndarray) -> np.ndarray:
            taken = play[i] * np.tanh(moment / smooth)
            return taken if lag is None else taken + np.asarray(lag)[..., i]

        a1 = q[..., 0] + j1(m1) + slack(0, m1) + guide(m2) + slack(1, m2)
        u1, n1 = _unit(a1)
        p = ((q[..., 1])[..., None] * u1 + (g.offset + self.offset_error
                                             + self.arm_deflection[0](m2))[..., None] * n1)
        a3 = a1 + self.arm_angle[0](m2) + q[..., 2] + j3(m3) + slack(2, m3)
        u3, n3 = _unit(a3)
        p = p + (g.link3 + self.link3_error) * u3 + self.arm_deflection[1](m3)[..., None] * n3
        a4 = a3 + self.arm_angle[1](m3) + q[..., 3] + j4(m4) + slack(3, m4)
        u4, n4 = _unit(a4)
        p = p + (g.link4 + self.link4_error) * u4 + self.arm_deflection[2](m4)[..., None] * n4
        phi = wrap_angle(a4 + self.arm_angle[2](m4))
        return np.concatenate([p * (1.0 + strain), np.asarray(phi)[..., None]], axis=-1)

    def deflection(self, joints: np.ndarray) -> np.ndarray:
        """Actual minus rigid-model tip pose (..., 3), φ difference wrapped."""
        d = self.pose(joints) - forward(self.geometry, joints)
        d[..., 2] = wrap_angle(d[..., 2])
        return d


def _unit(angle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vector along ``angle`` and its left normal, each (..., 2)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c, s], axis=-1), np.stack([-s, c], axis=-1)


def configured_plant(geometry: ArmGeometry) -> Plant:
    """The simulated real arm of config/sim.yaml ``plant``: the simulator's truth, which only
    the simulator's side reads (the control side has the nominal robot description)."""
    return Plant.from_dict(load_config('sim.yaml', node_name='flexarm_sim')['plant'], geometry)
