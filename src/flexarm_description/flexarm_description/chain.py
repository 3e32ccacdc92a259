"""The arm as a chain of frames in 3-D (pure): one description for the URDF and for ``/tf``.

Frames (REP 103): ``base_link`` is z up and the arm moves in its x–z plane
(:mod:`flexarm_core.plane`). Every revolute joint of the arm turns about −y, so a positive
joint angle raises the arm as in the paper's planar model.

Chain (Table 1; ``d`` the lateral offset of the No.2 arm, joint2 the No.2 arm length)::

    base_link -joint1(rev)-> link1 -joint2(prism, at z=d)-> link2 -joint3(rev)-> link3
      -joint4(rev, x=l3)-> link4 -tip_joint(fixed, x=l4)-> tip_link
      -tip_camera_joint(fixed, camera offset)-> tip_camera_link
      -tip_camera_optical_joint(fixed)-> tip_camera_optical_frame

``arm_plane`` (:mod:`flexarm_core.frames`), the frame of the planar messages, is fixed to
``base_link``: :func:`plane_transform`.

``tip_link`` is the tool (camera reference point) of the rigid model: ``base_link -> tip_link``
equals :func:`flexarm_core.kinematics.forward` at the joint positions. The camera looks at
the hole plate, which lies behind the arm's plane (+y): ``tip_camera_link`` is tool-aligned,
its optical frame has z along +y (the optical axis), x along the tool axis (image u) and y
along −z of the tool (image v), as :mod:`flexarm_vision.camera_model` maps the plate to pixels.

The transforms are plain quaternion arithmetic: scipy's ``Rotation`` costs a process some
30 MB, and the state publisher, which makes ``/tf`` from them, needs nothing else of scipy.
Only :func:`compose` and :func:`planar_pose`, which check the chain with it, import it.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from flexarm_core import frames, plane
from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation

Quaternion = tuple[float, float, float, float]    # (x, y, z, w)

BASE_FRAME = frames.BASE_FRAME
TIP_FRAME = frames.TIP_FRAME
CAMERA_FRAME = 'tip_camera_link'
CAMERA_OPTICAL_FRAME = 'tip_camera_optical_frame'


@dataclass(frozen=True)
class Joint:
    """One URDF joint: parent -> child at ``xyz``/``rpy``, then moved along/about ``axis``."""

    name: str
    kind: str                         # revolute | prismatic | fixed
    parent: str
    child: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = plane.PLANE_NORMAL
    lower: float = 0.0
    upper: float = 0.0
    velocity: float = 0.0


@dataclass(frozen=True)
class Transform:
    """parent -> child: translation [m] and rotation quaternion (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


def arm_joints(geometry: ArmGeometry, camera_offset: Sequence[float] = (0.0, 0.0)
               ) -> list[Joint]:
    """The chain of frames: the four moving joints (Table 1 limits and speeds), the tool and
    the tip camera (``camera_offset``: its axis on the plate in the tool frame, planar [m])."""
    lo, hi, speed = geometry.lower, geometry.upper, geometry.velocity
    moving = [
        Joint('joint1', 'revolute', BASE_FRAME, 'link1', (0.0, 0.0, 0.0)),
        Joint('joint2', 'prismatic', 'link1', 'link2', (0.0, 0.0, geometry.offset),
              axis=(1.0, 0.0, 0.0)),
        Joint('joint3', 'revolute', 'link2', 'link3', (0.0, 0.0, 0.0)),
        Joint('joint4', 'revolute', 'link3', 'link4', (geometry.link3, 0.0, 0.0)),
    ]
    moving = [Joint(j.name, j.kind, j.parent, j.child, j.xyz, j.rpy, j.axis, float(lo[i]),
                    float(hi[i]), float(speed[i])) for i, j in enumerate(moving)]
    ox, oy = (float(v) for v in camera_offset)
    return moving + [
        Joint('tip_joint', 'fixed', 'link4', TIP_FRAME, (geometry.link4, 0.0, 0.0)),
        Joint('tip_camera_joint', 'fixed', TIP_FRAME, CAMERA_FRAME, (ox, 0.0, oy)),
        Joint('tip_camera_optical_joint', 'fixed', CAMERA_FRAME, CAMERA_OPTICAL_FRAME,
              (0.0, 0.0, 0.0), rpy=(-math.pi / 2.0, 0.0, 0.0)),
    ]


def joint_transform(joint: Joint, position: float = 0.0) -> Transform:
    """parent -> child of ``joint`` at ``position`` [rad or m] (ignored for a fixed joint)."""
    roll, pitch, yaw = joint.rpy
    origin = _product(_product(_about((0.0, 0.0, 1.0), yaw), _about((0.0, 1.0, 0.0), pitch)),
                      _about((1.0, 0.0, 0.0), roll))          # URDF rpy: fixed axes x, y, z
    translation = np.asarray(joint.xyz, dtype=float)
    rotation = origin
    if joint.kind == 'revolute':
        rotation = _product(origin, _about(joint.axis, position))
    elif joint.kind == 'prismatic':
        translation = translation + _rotate(origin, np.asarray(joint.axis) * position)
    return Transform(joint.parent, joint.child, _tuple(translation), rotation)


def moving_transforms(joints: Sequence[Joint], positions: dict[str, float]) -> list[Transform]:
    """Transforms of the moving joints at ``positions`` (by joint name; all four needed)."""
    missing = [name for name in JOINT_NAMES if name not in positions]
    if missing:
        raise ValueError(f'joint positions lack {", ".join(missing)}')
    return [joint_transform(j, positions[j.name]) for j in joints if j.kind != 'fixed']


def fixed_transforms(joints: Sequence[Joint]) -> list[Transform]:
    """Transforms of the fixed joints (``/tf_static``)."""
    return [joint_transform(j) for j in joints if j.kind == 'fixed']


def plane_transform() -> Transform:
    """``base_link`` -> ``arm_plane``, the frame of the planar messages (``/tf_static``)."""
    return Transform(BASE_FRAME, frames.PLANE_FRAME, (0.0, 0.0, 0.0), plane.PLANE_IN_BASE)


def planar_transform(parent: str, child: str, pose: Sequence[float]) -> Transform:
    """The frame of a planar pose (x, y_up, phi) of the arm's plane, in ``parent``."""
    return Transform(parent, child, plane.position(pose), plane.orientation(float(pose[2])))


def compose(transforms: Sequence[Transform]) -> tuple[np.ndarray, Rotation]:
    """The product of a parent-to-child sequence: (translation (3,), rotation)."""
    from scipy.spatial.transform import Rotation

    translation, rotation = np.zeros(3), Rotation.identity()
    for t in transforms:
        translation = translation + rotation.apply(t.translation)
        rotation = rotation * Rotation.from_quat(t.rotation)
    return translation, rotation


def planar_pose(translation: np.ndarray, rotation: Rotation) -> np.ndarray:
    """Back to (x, y_up, phi) from a frame in the arm's plane."""
    tool = rotation.apply([1.0, 0.0, 0.0])
    return np.array([translation[0], translation[2], math.atan2(tool[2], tool[0])])


def _tuple(values: np.ndarray) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in values)
    return x, y, z


def _about(axis: Sequence[float], angle: float) -> Quaternion:
    """The rotation by ``angle`` [rad] about the unit vector ``axis``."""
    s = math.sin(angle / 2.0)
    return axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2.0)


def _product(a: Quaternion, b: Quaternion) -> Quaternion:
    """The rotation ``b``, then ``a`` (Hamilton product a b)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def _rotate(q: Quaternion, v: np.ndarray) -> np.ndarray:
    """``v`` (3,) turned by ``q``."""
    u, w = np.array(q[:3]), q[3]
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)
