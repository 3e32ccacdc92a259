"""Synthetic serial arms for the tests: URDF strings built in code, and random joint rows.

- :func:`seven_joint_arm`: seven revolute joints with alternating axes (z, y, z, y, z, y, z;
  the last one continuous), links of 0.2-0.4 m with lateral offsets of 0.1-0.2 m, each link
  with an inertial of 2-8 kg, and the tip link ``tool``; ``masses=False`` leaves every
  ``<inertial>`` out, ``branches=True`` adds joints off the chain (a finger on the last link,
  a camera mast on the base).
- :func:`prismatic_arm`: three joints, the middle one prismatic, tip ``tool``.
- :func:`random_joints`: rows of joint positions within an arm's limits.
"""
from __future__ import annotations

import numpy as np

TIP = 'tool'
# per joint: name, axis, origin from the parent joint's frame [m], limit [rad] (None:
# continuous). The lateral offsets keep a joint's axis off the line of the next one: without
# them a joint's bending and the next joint's axial compliance turn about one line under one
# moment, and no measurement tells them apart.
SEVEN = (
    ('shoulder_pan', 'z', (0.00, 0.00, 0.15), 2.9),
    ('shoulder_lift', 'y', (0.00, 0.20, 0.30), 2.0),
    ('upper_arm_roll', 'z', (0.15, 0.00, 0.20), 2.9),
    ('elbow', 'y', (0.00, -0.20, 0.40), 2.0),
    ('forearm_roll', 'z', (-0.15, 0.00, 0.20), 2.9),
    ('wrist_pitch', 'y', (0.00, 0.20, 0.35), 2.0),
    ('wrist_roll', 'z', (0.10, 0.00, 0.20), None),
)
TOOL_OFFSET = (0.0, 0.0, 0.25)      # [m] the tool link from the last joint
# [m] link k: from joint k to the next joint (the last: to the tool), along its z
LINK_LENGTHS = tuple(xyz[2] for _, _, xyz, _ in SEVEN[1:]) + (TOOL_OFFSET[2],)
LINK_MASSES = (8.0, 7.0, 6.0, 5.0, 4.0, 4.0, 4.0)            # [kg]
TOOL_MASS = 4.0                     # [kg]
LINK_RADIUS = 0.05                  # [m] of the cylinders the inertias are of
AXIAL = tuple('xyz'.index(axis) for _, axis, _, _ in SEVEN)   # each joint's axis, in its frame
AXES = {'x': '1 0 0', 'y': '0 1 0', 'z': '0 0 1'}


def _xyz(v: tuple[float, ...] | np.ndarray) -> str:
    return ' '.join(f'{x:.6g}' for x in v)


def _inertial(mass: float, com: tuple[float, float, float], length: float) -> str:
    """A solid cylinder's inertial along z (radius :data:`LINK_RADIUS`)."""
    side = mass * (3 * LINK_RADIUS ** 2 + length ** 2) / 12
    axial = mass * LINK_RADIUS ** 2 / 2
    return (f'<inertial><origin xyz="{_xyz(com)}" rpy="0 0 0"/><mass value="{mass}"/>'
            f'<inertia ixx="{side:.6g}" ixy="0" ixz="0" iyy="{side:.6g}" iyz="0" '
            f'izz="{axial:.6g}"/></inertial>')


def _link(name: str, inertial: str = '') -> str:
    return f'<link name="{name}">{inertial}</link>'


def _joint(name: str, kind: str, parent: str, child: str, xyz: tuple[float, ...],
           axis: str = 'z', limit: tuple[float, float] | None = None) -> str:
    limit_xml = ('' if limit is None else
                 f'<limit lower="{limit[0]}" upper="{limit[1]}" effort="100" velocity="2"/>')
    axis_xml = '' if kind == 'fixed' else f'<axis xyz="{AXES[axis]}"/>'
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{_xyz(xyz)}" rpy="0 0 0"/>'
            f'{axis_xml}{limit_xml}</joint>')


def seven_joint_arm(masses: bool = True, branches: bool = False) -> str:
    """The URDF of the 7-joint arm (see the module's docstring); its joints in chain order
    are :func:`seven_joint_names`."""
    parts = [_link('base_link', _inertial(10.0, (0, 0, 0.05), 0.1) if masses else '')]
    parent = 'base_link'
    for k, (name, axis, xyz, limit) in enumerate(SEVEN):
        child = f'link{k + 1}'
        length = LINK_LENGTHS[k]
        inertial = _inertial(LINK_MASSES[k], (0.05, 0.0, 0.45 * length), length)
        parts.append(_link(child, inertial if masses else ''))
        parts.append(_joint(name, 'revolute' if limit else 'continuous', parent, child, xyz,
                            axis, (-limit, limit) if limit else None))
        parent = child
    parts.append(_link(TIP, _inertial(TOOL_MASS, (0, 0, 0.03), 0.06) if masses else ''))
    parts.append(_joint('tool_mount', 'fixed', parent, TIP, TOOL_OFFSET))
    if branches:   # joints that are not on the way from the root to the tool
        parts.append(_link('finger', _inertial(0.2, (0, 0, 0.02), 0.04) if masses else ''))
        parts.append(_joint('finger_joint', 'prismatic', parent, 'finger', (0.0, 0.0, 0.2),
                            'x', (0.0, 0.04)))
        parts.append(_link('camera', _inertial(0.5, (0, 0, 0.02), 0.04) if masses else ''))
        parts.append(_joint('camera_tilt', 'revolute', 'base_link', 'camera', (0.3, 0.0, 0.5),
                            'y', (-1.0, 1.0)))
    return '<robot name="seven">' + ''.join(parts) + '</robot>'


def seven_joint_names() -> tuple[str, ...]:
    """The 7-joint arm's joint names from the root to the tool."""
    return tuple(name for name, _, _, _ in SEVEN)


def prismatic_arm() -> str:
    """A 3-joint arm: a turn about z, a slide along x (0-0.3 m), a pitch about y; tip ``tool``."""
    parts = [
        _link('base_link'),
        _link('column', _inertial(5.0, (0, 0, 0.15), 0.3)),
        _joint('turn', 'revolute', 'base_link', 'column', (0, 0, 0.1), 'z', (-3.0, 3.0)),
        _link('slide', _inertial(3.0, (0.1, 0, 0), 0.2)),
        _joint('reach', 'prismatic', 'column', 'slide', (0.05, 0, 0.3), 'x', (0.0, 0.3)),
        _link('wrist', _inertial(2.0, (0, 0, 0.1), 0.2)),
        _joint('pitch', 'revolute', 'slide', 'wrist', (0.2, 0, 0), 'y', (-1.5, 1.5)),
        _link(TIP),
        _joint('tool_mount', 'fixed', 'wrist', TIP, (0, 0, 0.25)),
    ]
    return '<robot name="slider">' + ''.join(parts) + '</robot>'


def random_joints(lower: np.ndarray, upper: np.ndarray, count: int, rng: np.random.Generator,
                  span: float = 0.9) -> np.ndarray:
    """(count, n) joint rows drawn uniformly in ``span`` of each joint's range about its
    middle; an infinite limit (a continuous joint) counts as ±π."""
    lower = np.where(np.isfinite(lower), lower, -np.pi)
    upper = np.where(np.isfinite(upper), upper, np.pi)
    middle, half = (lower + upper) / 2, span * (upper - lower) / 2
    return rng.uniform(middle - half, middle + half, (count, len(lower)))
