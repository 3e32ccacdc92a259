"""The URDF of the arm (pure), written from config/arm.yaml so it never disagrees with the
kinematics every node runs; complete enough for MoveIt, Gazebo and ros2_control.

Links are simple shapes: the No.1 arm a box along joint2's axis, the No.2 arm a box that slides
along it and ends at joint3, the No.3 and No.4 arms (joint3 -> joint4 -> tool) boxes of their
Table 1 lengths, the tip camera a small box. Each arm link's ``<inertial>`` holds the nominal
parts it carries (config/arm.yaml ``arm.inertia``, the masses the control side's gravity model
uses too): the joint2 drive on the No.1 arm, the No.2 beam and the joint3 axis on the No.2 arm,
the No.3 arm and the joint4 axis on link3, the No.4 arm and the end effector on link4; beams as
boxes of their length, axes and the end effector as ``LUMP`` cubes, for the inertia tensor a
simulator or planner needs (the paper gives no inertias).

``<collision>`` uses the same primitives: each link's box, and a ``LUMP`` cube for each axis
drive and for the end effector it carries, so that a planner keeps the drives and the tool
clear too. The sizes are assumed (the paper draws no cross-sections): ``LINK_SECTION`` square
arms, ``LUMP`` cubes.

Joint limits and speeds are Table 1's (arm.yaml). The paper rates no drives, so each joint's
effort limit is ``EFFORT_MARGIN`` times the static gravity load of the nominal masses and
Table 1's payload (``PAYLOAD``) with the arm stretched at full extension, the worst static
case: horizontal for the revolute joints [N·m], vertical for the prismatic joint2 [N]. The
margin leaves room for acceleration and friction; a site with rated drives replaces them.

The ``<ros2_control>`` system (:func:`ros2_control`) is part of the description unless asked
not to be, because controller_manager reads it from ``robot_description``.
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
SYSTEM_NAME = 'FlexarmSystem'                   # the <ros2_control> system
MOCK_HARDWARE = 'mock_components/GenericSystem'  # echoes commands as states: no robot needed
LINK_SECTION = 0.06     # [m] side of the arms' square cross-section (assumed)
CAMERA_SIDE = 0.03      # [m] side of the tip camera's cube
LUMP = 0.1              # [m] side of the cube an axis drive or the end effector is taken as
PAYLOAD = 5.0           # [kg] Table 1's payload (5 kgf) at the tip, sizing the efforts
EFFORT_MARGIN = 2.0     # effort limit over the static gravity load at full extension
GRAVITY = 9.80665       # [m/s²]
COLOURS = {'grey': '0.6 0.6 0.65 1', 'orange': '0.95 0.55 0.1 1', 'blue': '0.2 0.4 0.8 1'}


def _fmt(values: Sequence[float]) -> str:
    """Shortest text that reads back the same double: a command at arm.yaml's limit is within
    the URDF's."""
    return ' '.join(repr(float(v)) for v in values)


def _box(parent: ET.Element, centre: float, size: Sequence[float]) -> None:
    """A box of ``size`` centred ``centre`` along the link's x, in a visual or collision."""
    ET.SubElement(parent, 'origin', xyz=_fmt((centre, 0.0, 0.0)), rpy='0 0 0')
    ET.SubElement(ET.SubElement(parent, 'geometry'), 'box', size=_fmt(size))


def _shape(link: ET.Element, length: float, colour: str, section: float) -> None:
    """A box of ``|length|`` along the link's x from its origin (backwards if negative), seen
    and collided with."""
    size = (abs(length), section, section)
    visual = ET.SubElement(link, 'visual')
    _box(visual, length / 2.0, size)
    ET.SubElement(visual, 'material', name=colour)
    _box(ET.SubElement(link, 'collision'), length / 2.0, size)


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


def joint_efforts(geometry: ArmGeometry, inertia: Mapping[str, Any]) -> dict[str, float]:
    """Effort limit per moving joint [N·m, N for joint2]: ``EFFORT_MARGIN`` times the static
    gravity load of the parts it moves and ``PAYLOAD``, the arm stretched at full extension."""
    extension = float(geometry.upper[1])
    origins = {'link1': 0.0, 'link2': extension, 'link3': extension,     # [m] from joint1
               'link4': extension + geometry.link3}
    tip = extension + geometry.link3 + geometry.link4
    parts, links = link_parts(geometry, inertia), list(origins)
    efforts = {}
    for joint in arm_joints(geometry):
        if joint.kind == 'fixed':
            continue
        moved = links[links.index(joint.child):]
        loads = [(m, origins[link] + x) for link in moved for m, x, _ in parts[link]]
        loads.append((PAYLOAD, tip))
        if joint.kind == 'prismatic':                   # lifting them, the arm vertical
            load = sum(m for m, _ in loads)
        else:                                           # holding them, the arm horizontal
            load = sum(m * (x - origins[joint.child]) for m, x in loads)
        efforts[joint.name] = EFFORT_MARGIN * GRAVITY * load
    return efforts


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


def _lumps(link: ET.Element, parts: Sequence[tuple[float, float, float]]) -> None:
    """A collision cube for each lumped part (an axis drive, the end effector)."""
    for _, centre, length in parts:
        if not length:
            _box(ET.SubElement(link, 'collision'), centre, (LUMP, LUMP, LUMP))


def _joint(robot: ET.Element, joint: Joint, efforts: Mapping[str, float]) -> None:
    element = ET.SubElement(robot, 'joint', name=joint.name, type=joint.kind)
    ET.SubElement(element, 'parent', link=joint.parent)
    ET.SubElement(element, 'child', link=joint.child)
    ET.SubElement(element, 'origin', xyz=_fmt(joint.xyz), rpy=_fmt(joint.rpy))
    if joint.kind != 'fixed':
        ET.SubElement(element, 'axis', xyz=_fmt(joint.axis))
        ET.SubElement(element, 'limit', lower=_fmt((joint.lower,)), upper=_fmt((joint.upper,)),
                      effort=_fmt((efforts[joint.name],)), velocity=_fmt((joint.velocity,)))


def _param(parent: ET.Element, name: str, value: float) -> None:
    ET.SubElement(parent, 'param', name=name).text = _fmt((value,))


def hardware_parameters(pairs: Sequence[str]) -> dict[str, str]:
    """``NAME=VALUE`` strings (a ROS parameter cannot be a map) as the ``<param>`` elements
    of a hardware plugin (a real driver's address, port, ...); '' entries are none (a ROS
    list parameter is never empty); ValueError naming a bad one."""
    out = {}
    for pair in filter(str.strip, pairs):
        name, sep, value = pair.partition('=')
        if not sep or not name.strip():
            raise ValueError(f'hardware parameter {pair!r}: NAME=VALUE expected')
        out[name.strip()] = value.strip()
    return out


def ros2_control(geometry: ArmGeometry, plugin: str = MOCK_HARDWARE,
                 parameters: Mapping[str, str] | None = None) -> ET.Element:
    """The ``<ros2_control>`` system on hardware ``plugin`` with its ``parameters``: each
    joint commanded in position within its limits, position and velocity read back; a joint
    starts (on mock hardware) at the position nearest zero within its limits, so joint2
    retracted."""
    system = ET.Element('ros2_control', name=SYSTEM_NAME, type='system')
    hardware = ET.SubElement(system, 'hardware')
    ET.SubElement(hardware, 'plugin').text = plugin
    for name, value in (parameters or {}).items():
        ET.SubElement(hardware, 'param', name=name).text = value
    for joint in arm_joints(geometry):
        if joint.kind == 'fixed':
            continue
        element = ET.SubElement(system, 'joint', name=joint.name)
        command = ET.SubElement(element, 'command_interface', name='position')
        _param(command, 'min', joint.lower)
        _param(command, 'max', joint.upper)
        state = ET.SubElement(element, 'state_interface', name='position')
        _param(state, 'initial_value', min(max(0.0, joint.lower), joint.upper))
        ET.SubElement(element, 'state_interface', name='velocity')
    return system


def robot_description(geometry: ArmGeometry, inertia: Mapping[str, Any],
                      camera_offset: Sequence[float] = (0.0, 0.0),
                      hardware: str = MOCK_HARDWARE,
                      hardware_params: Mapping[str, str] | None = None) -> str:
    """The URDF (XML text) of the arm with its tool and tip camera; ``inertia``: config/arm.yaml
    ``arm.inertia``; ``hardware``: the ros2_control hardware plugin, '' for no
    ``<ros2_control>`` block, with ``hardware_params``."""
    robot = ET.Element('robot', name=ROBOT_NAME)
    for name, rgba in COLOURS.items():
        ET.SubElement(ET.SubElement(robot, 'material', name=name), 'color', rgba=rgba)
    shapes = {
        BASE_FRAME: None,
        'link1': (geometry.upper[1], 'grey', LINK_SECTION),    # the No.1 arm: joint2's rail
        'link2': (-geometry.upper[1], 'orange', LINK_SECTION),  # the No.2 arm, ending at joint3
        'link3': (geometry.link3, 'orange', LINK_SECTION),
        'link4': (geometry.link4, 'blue', LINK_SECTION),
        TIP_FRAME: None,
        CAMERA_FRAME: (CAMERA_SIDE, 'grey', CAMERA_SIDE),
        CAMERA_OPTICAL_FRAME: None,
    }
    parts = link_parts(geometry, inertia)
    for name, shape in shapes.items():
        link = ET.SubElement(robot, 'link', name=name)
        if shape is not None:
            _shape(link, float(shape[0]), shape[1], shape[2])
        if name in parts:
            _lumps(link, parts[name])
            _inertial(link, parts[name])
    efforts = joint_efforts(geometry, inertia)
    for joint in arm_joints(geometry, camera_offset):
        _joint(robot, joint, efforts)
    if hardware:
        robot.append(ros2_control(geometry, hardware, hardware_params))
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding='unicode') + '\n'


def published_description(parameters: Mapping[str, Any]) -> str:
    """The URDF the state publisher publishes on ``/robot_description``, from its parameters
    (nested: ``arm``, ``camera``, ``hardware_plugin``, ``hardware_parameters``): one function
    for the node and for ``flexarm urdf``, which makes it without a running graph."""
    arm = parameters['arm']
    return robot_description(ArmGeometry.from_dict(arm), arm['inertia'],
                             parameters['camera']['offset'],
                             parameters.get('hardware_plugin', MOCK_HARDWARE),
                             hardware_parameters(parameters.get('hardware_parameters', ())))
