"""Rigid kinematics of the 4-joint planar arm (paper section 2-2, Table 1).

Joints: ``joint1`` revolute θ1 [rad], ``joint2`` prismatic θ2 = No.2 arm length [m],
``joint3`` and ``joint4`` revolute [rad]. Base frame: x horizontal, y up; tip pose
(x, y, φ) [m, m, rad]::

    x = l4 cos(θ1+θ3+θ4) + l3 cos(θ1+θ3) + θ2 cos θ1 − d sin θ1
    y = l4 sin(θ1+θ3+θ4) + l3 sin(θ1+θ3) + θ2 sin θ1 + d cos θ1
    φ = θ1 + θ3 + θ4

with d = m1 − m2 the lateral offset of the No.2 arm. This is the model both the controller
side (simulator) and the control side (compensator, learner) use; the actual arm differs from
it by its deflection and fabrication errors (``flexarm_sim.plant``).

Inverse kinematics is analytic for a given θ2. The redundant θ2 follows one documented rule
(:func:`inverse`): the extension nearest to the preferred one (0.6 m, as the paper's
simulation) that keeps the wrist at least ``reach_margin`` inside the elbow's reach, else the
one that keeps it farthest inside. The margin keeps the elbow bent well away from its
stretched, singular pose, where a millimetre of tip motion takes degrees of joint motion and
the compensated target (tens of millimetres from the target) might fall out of reach.
Everything is vectorised over leading axes where it matters (forward kinematics of batches).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

JOINT_NAMES = ('joint1', 'joint2', 'joint3', 'joint4')
JOINT_UNITS = ('rad', 'm', 'rad', 'rad')        # SI unit of each joint's position


class UnreachableError(ValueError):
    """The target pose has no inverse-kinematics solution inside the joint limits."""


@dataclass(frozen=True)
class ArmGeometry:
    """Rigid geometry, joint limits and speeds (config/arm.yaml ``arm.*``)."""

    link3: float                 # [m] joint3 -> joint4
    link4: float                 # [m] joint4 -> tip
    offset: float                # [m] lateral offset m1 - m2 of the No.2 arm axis
    lower: np.ndarray            # (4,) joint lower limits [rad, m, rad, rad]
    upper: np.ndarray            # (4,) joint upper limits
    velocity: np.ndarray         # (4,) joint speed limits [rad/s, m/s, rad/s, rad/s]
    preferred_extension: float   # [m] θ2 used when the target is reachable with it
    min_elbow_bend: float        # [rad] keep the elbow at least this far from stretched
    extension_step: float        # [m] grid of the θ2 search when the preferred one fails
    reach_margin: float          # [m] θ2 keeps the wrist this far inside the elbow's reach

    @cached_property
    def extensions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The θ2 values the redundancy rule may take (the ``extension_step`` grid within
        the limits and the preferred one) and, for each, the wrist distances the elbow reaches
        from folded to stretched as far as allowed (:func:`reach_margins`): fixed by the
        geometry, and a compensation step asks for them twice (they took 20 of its IK's
        30 µs)."""
        lower, upper, step = self.lower[1], self.upper[1], self.extension_step
        grid = lower + step * np.arange(math.floor((upper - lower) / step + 1e-9) + 1)
        grid = np.unique(np.append(np.round(grid, 9), self.preferred_extension))
        return grid, *_reach(self, grid)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ArmGeometry:
        geometry = cls(
            link3=float(d['link3']), link4=float(d['link4']), offset=float(d['offset']),
            lower=np.asarray(d['lower'], dtype=float), upper=np.asarray(d['upper'], dtype=float),
            velocity=np.asarray(d['velocity'], dtype=float),
            preferred_extension=float(d['preferred_extension']),
            min_elbow_bend=float(d['min_elbow_bend']),
            extension_step=float(d['extension_step']),
            reach_margin=float(d['reach_margin']))
        names = tuple(d.get('joint_names', JOINT_NAMES))
        if names != JOINT_NAMES:
            raise ValueError(f'joint_names must be {JOINT_NAMES}, got {names}')
        for name in ('lower', 'upper', 'velocity'):
            if getattr(geometry, name).shape != (4,):
                raise ValueError(f'arm.{name} needs 4 values')
        if np.any(geometry.lower >= geometry.upper) or np.any(geometry.velocity <= 0):
            raise ValueError('arm limits need lower < upper and positive velocities')
        if min(geometry.link3, geometry.link4, geometry.extension_step) <= 0:
            raise ValueError('arm link lengths and extension_step must be positive')
        if geometry.reach_margin < 0:
            raise ValueError('arm.reach_margin must be >= 0')
        if not geometry.lower[1] <= geometry.preferred_extension <= geometry.upper[1]:
            raise ValueError('arm.preferred_extension lies outside the joint2 limits')
        return geometry


def wrap_angle(angle: np.ndarray | float) -> np.ndarray | float:
    """Angle(s) wrapped to (-π, π], the range of PlanarPose.phi; a float for a scalar input."""
    wrapped = np.pi - (np.pi - np.asarray(angle, dtype=float)) % (2 * np.pi)
    return wrapped if wrapped.ndim else float(wrapped)


def forward(geometry: ArmGeometry, joints: np.ndarray) -> np.ndarray:
    """Tip pose(s) (..., 3) of joint vector(s) (..., 4); φ wrapped to [-π, π)."""
    q = np.asarray(joints, dtype=float)
    t1, t2, t3, t4 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    a13, a134 = t1 + t3, t1 + t3 + t4
    x = (geometry.link4 * np.cos(a134) + geometry.link3 * np.cos(a13) + t2 * np.cos(t1)
         - geometry.offset * np.sin(t1))
    y = (geometry.link4 * np.sin(a134) + geometry.link3 * np.sin(a13) + t2 * np.sin(t1)
         + geometry.offset * np.cos(t1))
    return np.stack([x, y, wrap_angle(a134)], axis=-1)


def limit_violation(geometry: ArmGeometry, joints: np.ndarray) -> str | None:
    """Which joint limit ``joints`` violates (human-readable), or None."""
    q = np.asarray(joints, dtype=float)
    for i, name in enumerate(JOINT_NAMES):
        if not geometry.lower[i] <= q[i] <= geometry.upper[i]:
            return (f'{name} = {q[i]:.6g} outside its limits '
                    f'[{geometry.lower[i]:.6g}, {geometry.upper[i]:.6g}]')
    return None


def command_error(values: list[float], geometry: ArmGeometry) -> str | None:
    """Why a joint command (one value per joint) must be refused, or None if it is valid."""
    if len(values) != len(JOINT_NAMES):
        return f'expected {len(JOINT_NAMES)} values ({", ".join(JOINT_NAMES)}), got {len(values)}'
    if not all(math.isfinite(v) for v in values):
        return f'non-finite value in {list(values)}'
    return limit_violation(geometry, np.asarray(values, dtype=float))


def pose_error(target: np.ndarray, pose: np.ndarray) -> tuple[float, float]:
    """(position error [m], |angle error| [rad]) of ``pose`` with respect to ``target``."""
    d = np.asarray(pose, dtype=float) - np.asarray(target, dtype=float)
    return float(math.hypot(d[0], d[1])), float(abs(wrap_angle(float(d[2]))))


def solve_fixed(geometry: ArmGeometry, pose: np.ndarray, extension: float
                ) -> np.ndarray | None:
    """Joints for one θ2, or None: elbow-up branch (θ3 = skew − bend: joint3 above the line from
    the base to joint4 when the arm points forward) first, then elbow-down (scalar math: the
    compensator calls it in its inner loop)."""
    x, y, phi = (float(v) for v in pose)
    wx, wy = x - geometry.link4 * math.cos(phi), y - geometry.link4 * math.sin(phi)
    d, b = geometry.offset, geometry.link3
    a2 = extension * extension + d * d
    cos_bend = (wx * wx + wy * wy - a2 - b * b) / (2 * math.sqrt(a2) * b)
    if not -1.0 <= cos_bend <= 1.0:
        return None
    bend = math.acos(cos_bend)
    if bend < geometry.min_elbow_bend:
        return None
    skew = math.atan2(d, extension)
    lower, upper = geometry.lower, geometry.upper
    for t3 in (skew - bend, skew + bend):
        px, py = extension + b * math.cos(t3), d + b * math.sin(t3)
        t1 = (math.atan2(wy, wx) - math.atan2(py, px) + math.pi) % (2 * math.pi) - math.pi
        t4 = (phi - t1 - t3 + math.pi) % (2 * math.pi) - math.pi
        q = (t1, extension, t3, t4)
        if all(lower[i] <= q[i] <= upper[i] for i in range(4)):
            return np.array(q)
    return None


def inverse(geometry: ArmGeometry, pose: np.ndarray, extension: float | None = None
            ) -> np.ndarray:
    """Joint positions (4,) putting the rigid tip at ``pose`` (x, y, φ).

    ``extension`` fixes θ2 (e.g. to keep the one chosen for an earlier, nearby target); by
    default θ2 follows the redundancy rule: ``preferred_extension`` if it gives a solution,
    else the nearest θ2 on the ``extension_step`` grid that does. Of the two elbow branches
    the elbow-up one (negative θ3: joint3 above the line from the base to joint4) is taken
    when both are valid. Raises :class:`UnreachableError` with the reason when there is no
    solution inside the joint limits.
    """
    pose = np.asarray(pose, dtype=float)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise UnreachableError(f'target must be 3 finite numbers (x, y, phi), got {pose}')
    if extension is not None:
        if not geometry.lower[1] <= extension <= geometry.upper[1]:
            raise UnreachableError(f'joint2 = {extension:.4f} m outside its limits')
        q = solve_fixed(geometry, pose, float(extension))
        if q is None:
            raise UnreachableError(f'pose {describe_pose(pose)} is out of reach of the rigid '
                                   f'arm with joint2 = {extension:.4f} m')
        return q
    for candidate in _extension_candidates(geometry, pose):
        q = solve_fixed(geometry, pose, candidate)
        if q is not None:
            return q
    raise UnreachableError(f'pose {describe_pose(pose)} is out of reach of the rigid arm '
                           'inside its joint limits')


def describe_pose(pose: np.ndarray) -> str:
    """``(x=… m, y=… m, phi=… deg)``, six significant digits (any magnitude stays short)."""
    return (f'(x={float(pose[0]):.6g} m, y={float(pose[1]):.6g} m, '
            f'phi={math.degrees(float(pose[2])):.6g} deg)')


def elbow_bend(geometry: ArmGeometry, joints: np.ndarray) -> float:
    """Signed bend of the elbow [rad]: positive on the elbow-up branch (θ3 below the
    stretched angle atan2(d, θ2)), 0 when stretched (singular)."""
    return math.atan2(geometry.offset, float(joints[1])) - float(joints[2])


def reach_margins(geometry: ArmGeometry, pose: np.ndarray, extensions: np.ndarray
                  ) -> np.ndarray:
    """How far [m] the wrist of ``pose`` lies inside the elbow's reach with each θ2 of
    ``extensions`` (negative: out of reach)."""
    return _margins(_wrist_distance(geometry, pose), *_reach(geometry, extensions))


def _reach(geometry: ArmGeometry, extensions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The wrist distances the elbow reaches with each θ2: from |a − b| (folded) to
    √(a² + b² + 2ab cos(min_elbow_bend)) (stretched as far as allowed), a² = θ2² + d²,
    b = l3."""
    a, b = np.hypot(extensions, geometry.offset), geometry.link3
    return np.abs(a - b), np.sqrt(a * a + b * b + 2 * a * b * math.cos(geometry.min_elbow_bend))


def _wrist_distance(geometry: ArmGeometry, pose: np.ndarray) -> float:
    x, y, phi = (float(v) for v in pose)
    return math.hypot(x - geometry.link4 * math.cos(phi), y - geometry.link4 * math.sin(phi))


def _margins(distance: float, folded: np.ndarray, stretched: np.ndarray) -> np.ndarray:
    return np.minimum(stretched - distance, distance - folded)


def _extension_candidates(geometry: ArmGeometry, pose: np.ndarray) -> list[float]:
    """θ2 values to try, in the rule's order: those of the ``extension_step`` grid (and the
    preferred one) that keep the wrist ``reach_margin`` inside the reach, nearest to the
    preferred first; then those that reach it with less margin, the largest margin first."""
    grid, folded, stretched = geometry.extensions
    margin = _margins(_wrist_distance(geometry, pose), folded, stretched)
    full = margin >= geometry.reach_margin
    some = ~full & (margin >= 0)
    first = grid[full][np.argsort(np.abs(grid[full] - geometry.preferred_extension),
                                  kind='stable')]
    then = grid[some][np.argsort(-margin[some], kind='stable')]
    return [*first.tolist(), *then.tolist()]
