"""The URDF of the arm (pure), written from config/arm.yaml so it never disagrees with the
kinematics every node runs.

Links are simple shapes for a viewer: the No.1 arm a box along joint2's axis, the No.2 arm a
box that slides along it and ends at joint3, the No.3 and No.4 arms (joint3 -> joint4 -> tool)
boxes of their Table 1 lengths, the tip camera a small box. Joint limits and speeds are
Table 1's (arm.yaml); efforts are not modelled (the paper gives none), so every joint says
effort 0. Each arm link's ``<inertial>`` holds the nominal parts it carries (config/arm.yaml
``arm.inertia``, the masses the control side's gravity model uses too): the joint2 drive on the
No.1 arm, the No.2 beam and the joint3 axis on the No.2 arm, the No.3 arm and the joint4 axis on
link3, the No.4 arm and the end effector on link4; beams as boxes of their length, axes and the
end effector as ``LUMP`` cubes, for the inertia tensor a simulator or planner needs (the paper
gives no inertias).
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from typing import Any

from flexarm_core.kinematics import ArmGeometry
from flexarm_description.chain import (
    BASE_FRAME,
    CAMERA_FRAME,
    CAMERA_OPTICAL_FRAME,
    TIP_FRAME,
    Joint,
    arm_joints,
)

ROBOT_NAME = 'flexarm'
LINK_SECTION = 0.06     # [m] box height and depth of the arms
LUMP = 0.1              # [m] side of the cube an axis drive or the end effector is taken as
COLOURS = {'grey': '0.6 0.6 0.65 1', 'orange': '0.95 0.55 0.1 1', 'blue': '0.2 0.4 0.8 1'}


def _fmt(values: Sequence[float]) -> str:
    return ' '.join(f'{v:.9g}' for v in values)


def _box(link: ET.Element, length: float, colour: str, section: float = LINK_SECTION) -> None:
    """A box of ``|length|`` along the link's x from its origin (backwards if negative)."""
    visual = ET.SubElement(link, 'visual')
    ET.SubElement(visual, 'origin', xyz=_fmt((length / 2.0, 0.0, 0.0)), rpy='0 0 0')
    geometry = ET.SubElement(visual, 'geometry')
    ET.SubElement(geometry, 'box', size=_fmt((abs(length), section, section)))
    ET.SubElement(visual, 'material', name=colour)


def link_parts(geometry: ArmGeometry, inertia: Mapping[str, Any]
               ) -> dict[str, list[tuple[float, float, float]]]:
    """Per arm link, its parts as (mass [kg], centre along the link's x [m], length [m]; 0 for
    a lump), from config/arm.yaml ``arm.inertia``."""
    m = inertia['masses']
    return {
        'link1': [(m['second_axis'], inertia['second_axis_position'], 0.0)],
        'link2': [(m['second_arm'], -inertia['beam_length'] / 2, inertia['beam_length']),
                  (m['third_axis'], 0.0, 0.0)],
        'link3': [(m['third_arm'], geometry.link3 / 2, geometry.link3),
                  (m['fourth_axis'], geometry.link3, 0.0)],
        'link4': [(m['fourth_arm'], geometry.link4 / 2, geometry.link4),
                  (m['end_effector'], geometry.link4 + inertia['end_effector_com'], 0.0)],
    }


def _inertial(link: ET.Element, parts: Sequence[tuple[float, float, float]]) -> None:
    """The parts' mass, centre and inertia about it (boxes along x, parallel axes)."""
    mass = sum(p[0] for p in parts)
    centre = sum(p[0] * p[1] for p in parts) / mass
    side = [(length, LINK_SECTION) if length else (LUMP, LUMP) for _, _, length in parts]
    across = sum(p[0] * 2 * s * s / 12 for p, (_, s) in zip(parts, side))
    along = sum(p[0] * ((length * length + s * s) / 12 + (p[1] - centre) ** 2)
                for p, (length, s) in zip(parts, side))
    inertial = ET.SubElement(link, 'inertial')
    ET.SubElement(inertial, 'origin', xyz=_fmt((centre, 0.0, 0.0)), rpy='0 0 0')
    ET.SubElement(inertial, 'mass', value=_fmt((mass,)))
    ET.SubElement(inertial, 'inertia', ixx=_fmt((across,)), ixy='0', ixz='0',
                  iyy=_fmt((along,)), iyz='0', izz=_fmt((along,)))


def _joint(robot: ET.Element, joint: Joint) -> None:
    element = ET.SubElement(robot, 'joint', name=joint.name, type=joint.kind)
    ET.SubElement(element, 'parent', link=joint.parent)
    ET.SubElement(element, 'child', link=joint.child)
    ET.SubElement(element, 'origin', xyz=_fmt(joint.xyz), rpy=_fmt(joint.rpy))
    if joint.kind != 'fixed':
        ET.SubElement(element, 'axis', xyz=_fmt(joint.axis))
        ET.SubElement(element, 'limit', lower=_fmt((joint.lower,)), upper=_fmt((joint.upper,)),
                      effort='0', velocity=_fmt((joint.velocity,)))


def robot_description(geometry: ArmGeometry, inertia: Mapping[str, Any],
                      camera_offset: Sequence[float] = (0.0, 0.0)) -> str:
    """The URDF (XML text) of the arm with its tool and tip camera; ``inertia``: config/arm.yaml
    ``arm.inertia``."""
    robot = ET.Element('robot', name=ROBOT_NAME)
    for name, rgba in COLOURS.items():
        ET.SubElement(ET.SubElement(robot, 'material', name=name), 'color', rgba=rgba)
    shapes = {
        BASE_FRAME: None,
        'link1': (geometry.upper[1], 'grey'),                   # the No.1 arm: joint2's rail
        'link2': (-geometry.upper[1], 'orange'),     # the No.2 arm, ending at joint3
        'link3': (geometry.link3, 'orange'),
        'link4': (geometry.link4, 'blue'),
        TIP_FRAME: None,
        CAMERA_FRAME: (0.03, 'grey'),
        CAMERA_OPTICAL_FRAME: None,
    }
    parts = link_parts(geometry, inertia)
    for name, shape in shapes.items():
        link = ET.SubElement(robot, 'link', name=name)
        if shape is not None:
            _box(link, float(shape[0]), shape[1],
                 section=0.03 if name == CAMERA_FRAME else LINK_SECTION)
        if name in parts:
            _inertial(link, parts[name])
    for joint in arm_joints(geometry, camera_offset):
        _joint(robot, joint)
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding='unicode') + '\n'
