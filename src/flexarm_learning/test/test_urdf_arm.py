"""UrdfArm: the chain of a tip link read from a URDF, its kinematics and its gravity moments."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from synthetic_arms import (
    AXIAL,
    LINK_MASSES,
    SEVEN,
    TIP,
    TOOL_MASS,
    prismatic_arm,
    random_joints,
    seven_joint_arm,
    seven_joint_names,
)

from flexarm_learning.urdf_arm import GRAVITY, DescriptionError, UrdfArm

OFFSET = np.array([0.03, -0.02, 0.08])   # [m] a target off the tool link


def test_joint_names_are_the_chain_from_the_root_to_the_tip_only() -> None:
    """Joints off the chain (a camera mast on the base, a finger beside the tool) are not the
    arm's; the chain's joints come root first, with their limits (a continuous joint: ±inf)."""
    arm = UrdfArm.from_xml(seven_joint_arm(branches=True), TIP)
    assert arm.joint_names == seven_joint_names()
    assert arm.dof == 7
    limits = np.array([np.inf if limit is None else limit for _, _, _, limit in SEVEN])
    np.testing.assert_array_equal(arm.upper, limits)
    np.testing.assert_array_equal(arm.lower, -limits)
    finger = UrdfArm.from_xml(seven_joint_arm(branches=True), 'finger')
    assert finger.joint_names == (*seven_joint_names(), 'finger_joint')


def test_a_missing_tip_link_is_a_description_error_naming_it() -> None:
    """Asking for a link the URDF does not have says which link was asked for."""
    with pytest.raises(DescriptionError, match='gripper_tcp'):
        UrdfArm.from_xml(seven_joint_arm(), 'gripper_tcp')


def test_a_document_that_is_no_urdf_is_a_description_error() -> None:
    """XML that Pinocchio cannot read as a URDF is reported as such, not as Pinocchio's error."""
    with pytest.raises(DescriptionError):
        UrdfArm.from_xml('<robot name="broken"><link name="a"/>', TIP)


@pytest.mark.parametrize('make', [
    lambda folder: folder / 'absent.urdf',                   # no such file
    lambda folder: folder,                                   # a directory
    lambda folder: _write(folder / 'latin1.urdf',            # not UTF-8 (a Latin-1 comment)
                          seven_joint_arm().replace('<robot name="seven">',
                                                    '<robot name="seven"><!-- Größe -->'),
                          'latin-1'),
], ids=['missing', 'directory', 'not-utf8'])
def test_an_unreadable_file_is_a_description_error(tmp_path: Path,
                                                  make: Callable[[Path], Path]) -> None:
    """A URDF file that cannot be read is a DescriptionError naming the file."""
    path = make(tmp_path)
    with pytest.raises(DescriptionError, match=path.name):
        UrdfArm.from_file(path, TIP)


def test_a_readable_file_gives_the_same_arm_as_its_text(tmp_path: Path) -> None:
    """from_file reads what from_xml would be given."""
    path = _write(tmp_path / 'arm.urdf', seven_joint_arm(), 'utf-8')
    assert UrdfArm.from_file(path, TIP).joint_names == seven_joint_names()


@pytest.mark.parametrize('xml', [seven_joint_arm(), prismatic_arm()], ids=['seven', 'prismatic'])
def test_the_jacobian_is_the_derivative_of_the_target(xml: str) -> None:
    """state().jacobian is d target / d q (m/rad, m/m for a prismatic joint), the target
    off the tool link: a central finite difference of state().target agrees to 1e-6."""
    arm = UrdfArm.from_xml(xml, TIP)
    step = 1e-6
    for q in random_joints(arm.lower, arm.upper, 5, np.random.default_rng(3)):
        numeric = np.empty((3, arm.dof))
        for k in range(arm.dof):
            dq = np.zeros(arm.dof)
            dq[k] = step
            numeric[:, k] = (arm.chain_at(q + dq, OFFSET).target[0]
                             - arm.chain_at(q - dq, OFFSET).target[0]) / (2 * step)
        np.testing.assert_allclose(arm.chain_at(q, OFFSET).jacobian[0], numeric, rtol=0, atol=1e-6)


def test_has_masses_tells_an_arm_with_inertials_from_one_without() -> None:
    """The chain's mass is its links' and the tool's (not the base's); a URDF without
    inertials has none, and no gravity moments."""
    arm = UrdfArm.from_xml(seven_joint_arm(), TIP)
    massless = UrdfArm.from_xml(seven_joint_arm(masses=False), TIP)
    assert arm.has_masses and not massless.has_masses
    assert arm.mass == pytest.approx(sum(LINK_MASSES) + TOOL_MASS)
    q = random_joints(massless.lower, massless.upper, 1, np.random.default_rng(4))[0]
    np.testing.assert_array_equal(massless.gravity_moments(massless.chain_at(q, OFFSET)),
                                  np.zeros((1, 7, 3)))


def test_gravity_moments_about_the_joint_axes_are_pinocchios_generalized_gravity() -> None:
    """About each joint's own axis, the moment gravity puts on what the joint carries is
    minus Pinocchio's generalized gravity (the torque that holds the arm still); branches
    the joint carries (the finger) count, branches it does not (the camera) do not."""
    arm = UrdfArm.from_xml(seven_joint_arm(branches=True), TIP)
    model = arm.model
    data = model.createData()
    velocity = [model.joints[model.getJointId(name)].idx_v for name in arm.joint_names]
    for q in random_joints(arm.lower, arm.upper, 6, np.random.default_rng(5)):
        holding = pin.computeGeneralizedGravity(model, data, arm.configuration(q))[velocity]
        moments = arm.gravity_moments(arm.chain_at(q, OFFSET))[0]
        axial = moments[np.arange(arm.dof), AXIAL]
        np.testing.assert_allclose(axial, -holding, rtol=1e-9, atol=1e-9)


def test_a_payload_adds_its_weight_times_its_lever() -> None:
    """A payload m at the target adds, at each joint, the moment (target − joint) × m·g in the
    joint's frame; about the joint's axis that is the virtual work J_k · m·g. Rows one after
    the other, as a batch of measurements is evaluated."""
    arm = UrdfArm.from_xml(seven_joint_arm(), TIP)
    mass = 3.0
    rows = random_joints(arm.lower, arm.upper, 6, np.random.default_rng(6))
    chain = arm.chain_at(rows, OFFSET)
    loaded = arm.gravity_moments(chain, np.full(len(rows), mass))
    empty = arm.gravity_moments(chain, 0.0)
    weight = mass * GRAVITY
    for r, (with_payload, without) in enumerate(zip(loaded, empty)):
        expected = np.array([frame.T @ np.cross(chain.target[r] - pivot, weight)
                             for frame, pivot in zip(chain.frames[r], chain.pivots[r])])
        np.testing.assert_allclose(with_payload - without, expected, rtol=0, atol=1e-9)
        np.testing.assert_allclose((with_payload - without)[np.arange(arm.dof), AXIAL],
                                   chain.jacobian[r].T @ weight, rtol=0, atol=1e-9)


def _write(path: Path, text: str, encoding: str) -> Path:
    path.write_text(text, encoding=encoding)
    return path
