"""Registration: the instrument's frame and the target's offset, recovered from measured points
(ElastostaticModel without compliance and geometry), and Kabsch's start of it."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation
from synthetic_arms import TIP, random_joints, seven_joint_arm

from flexarm_learning.elastostatic import ElastostaticModel
from flexarm_learning.registration import kabsch
from flexarm_learning.urdf_arm import UrdfArm

AXIS = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
ROTATION = Rotation.from_rotvec(np.radians(30.0) * AXIS).as_matrix()   # instrument ← base
TRANSLATION = np.array([1.6, -1.1, 0.5])       # [m] about 2 m from the arm's base
OFFSET = np.array([0.01, -0.02, 0.09])         # [m] the target from the tool link


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    """[rad] the angle of the rotation between a and b."""
    return float(Rotation.from_matrix(a @ b.T).magnitude())


def test_the_fit_recovers_a_known_instrument_transform_and_target_offset() -> None:
    """Noise-free points of the nominal chain seen from a turned and shifted instrument, the
    target off the tool link: the registration comes back to 1e-6 rad and 1e-6 m."""
    arm = UrdfArm.from_xml(seven_joint_arm(), TIP)
    joints = random_joints(arm.lower, arm.upper, 30, np.random.default_rng(11))
    targets = arm.chain_at(joints, OFFSET).target
    points = targets @ ROTATION.T + TRANSLATION
    model = ElastostaticModel(arm, compliance=False, geometry=False).fit(joints, points)
    assert _angle(model.rotation, ROTATION) < 1e-6
    np.testing.assert_allclose(model.translation, TRANSLATION, rtol=0, atol=1e-6)
    np.testing.assert_allclose(model.offset, OFFSET, rtol=0, atol=1e-6)
    np.testing.assert_allclose(model.predict(joints), points, rtol=0, atol=1e-6)


def test_kabsch_recovers_a_rigid_transform_of_a_point_cloud() -> None:
    """measured = model · Rᵀ + t without noise: Kabsch returns R and t."""
    cloud = np.random.default_rng(12).normal(size=(20, 3))
    rotation, translation = kabsch(cloud, cloud @ ROTATION.T + TRANSLATION)
    np.testing.assert_allclose(rotation, ROTATION, rtol=0, atol=1e-12)
    np.testing.assert_allclose(translation, TRANSLATION, rtol=0, atol=1e-12)


def test_kabsch_returns_a_rotation_for_mirrored_points() -> None:
    """Points mirrored (no rotation maps them) still give a proper rotation, det +1."""
    cloud = np.random.default_rng(13).normal(size=(20, 3))
    rotation, _ = kabsch(cloud, cloud * [1.0, 1.0, -1.0])
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), rtol=0, atol=1e-12)
    assert np.linalg.det(rotation) > 0

