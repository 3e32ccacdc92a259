"""JointErrorGp: a joint's own error, as a function of its angle, learned from the residual it
leaves at the target through the joint Jacobian."""
from __future__ import annotations

import numpy as np
import pytest
from synthetic_arms import TIP, random_joints, seven_joint_arm

from flexarm_learning.joint_error import JointErrorGp
from flexarm_learning.urdf_arm import UrdfArm

FIT, HELD_OUT = 150, 100         # rows
JOINT = 0                        # the joint with the error: the base pan, the longest lever
AMPLITUDE = 2e-4                 # [rad] of its error δq = a · sin(q / SCALE)
SCALE = 0.05                     # [rad] a gear's transmission error: short in the joint angle
NOISE = 5e-6                     # [m] per component
OFFSET = np.array([0.0, 0.0, 0.05])   # [m] the target from the tool link
Learned = tuple[JointErrorGp, np.ndarray, np.ndarray, np.ndarray]


@pytest.fixture(scope='module')
def learned() -> Learned:
    """The GP fitted on FIT rows; its posterior mean and covariances at HELD_OUT new rows, and
    the noise-free residual there."""
    arm = UrdfArm.from_xml(seven_joint_arm(), TIP)
    rng = np.random.default_rng(21)
    joints = random_joints(arm.lower, arm.upper, FIT + HELD_OUT, rng)
    jacobians = arm.chain_at(joints, OFFSET).jacobian
    error = AMPLITUDE * np.sin(joints[:, JOINT] / SCALE)
    residual = jacobians[:, :, JOINT] * error[:, None]
    measured = residual + rng.normal(0.0, NOISE, residual.shape)
    gp = JointErrorGp().fit(joints[:FIT], jacobians[:FIT], measured[:FIT])
    mean, cov = gp.predict(joints[FIT:], jacobians[FIT:])
    return gp, mean, cov, residual[FIT:]


def test_predicts_held_out_residuals_of_a_joint_error(learned: Learned) -> None:
    """The residual of a joint's short-scale error, carried by its Jacobian column, is
    predicted at new rows to well under its own size (RMS error < 30 % of its RMS), and the
    noise it learns is the measurement's (within a factor 1.5)."""
    gp, mean, cov, residual = learned
    assert mean.shape == residual.shape and cov.shape == (HELD_OUT, 3, 3)
    rms = np.sqrt(np.mean(residual ** 2))
    assert np.sqrt(np.mean((mean - residual) ** 2)) < 0.3 * rms
    assert NOISE / 1.5 < gp.noise < NOISE * 1.5


def test_the_posterior_covariances_are_symmetric_positive_definite(learned: Learned) -> None:
    """Each 3 × 3 covariance of a predicted residual is symmetric and positive definite (it
    holds the noise σ² at least)."""
    gp, _, cov, _ = learned
    scale = np.abs(cov).max()
    np.testing.assert_allclose(cov, np.swapaxes(cov, 1, 2), rtol=0, atol=1e-9 * scale)
    smallest = np.linalg.eigvalsh((cov + np.swapaxes(cov, 1, 2)) / 2).min(axis=1)
    assert np.all(smallest > 0.5 * gp.noise ** 2)
