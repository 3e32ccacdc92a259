"""ElastostaticModel: registration, geometry, elasticity and play identified from points (and
rotations) that a model with known parameters produced (its own ``predict_pose``), with
measurement noise."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from synthetic_arms import AXIAL, TIP, prismatic_arm, random_joints, seven_joint_arm

from flexarm_learning.elastostatic import TERMS, ElastostaticModel
from flexarm_learning.urdf_arm import UrdfArm

FIT, HELD_OUT = 150, 50          # rows
NOISE = 1e-5                     # [m] the instrument's noise per component (0.01 mm)
# [rad/(N·m)] axial compliances of the joints that carry a gravity moment about their axis
# (shoulder lift to wrist pitch; the base pan and the wrist roll carry none): softer toward the
# wrist, as on real arms, each a turn of 0.2-0.5 mrad at its RMS moment.
LOADED = {1: 3e-6, 2: 5e-6, 3: 4e-6, 4: 1.2e-5, 5: 1.6e-5}
# [m, rad] each joint origin's true twist: an arm as built (half the geometry prior), and a
# smaller one
GEOMETRY_ERROR, SMALL_GEOMETRY_ERROR = 5e-4, 2e-4


@pytest.fixture(scope='module')
def arm() -> UrdfArm:
    return UrdfArm.from_xml(seven_joint_arm(), TIP)


def true_model(arm: UrdfArm, twists: np.ndarray | None = None,
               compliances: dict[int, float] | None = None) -> ElastostaticModel:
    """A model with hand-set parameters: an instrument 30° turned and ~2 m away, a target 9 cm
    off the tool, the joint origins moved by ``twists`` and the axial ``compliances``."""
    model = ElastostaticModel(arm, compliance=compliances is not None)
    model.rotation = pin.exp3(np.radians(30.0) * np.array([0.6, -0.7, 0.39]))
    model.translation = np.array([1.6, -1.1, 0.5])
    model.offset = np.array([0.01, -0.02, 0.09])
    model.twists = np.zeros((arm.dof, 6)) if twists is None else twists
    model.compliances = np.zeros((arm.dof, 3))
    for joint, value in (compliances or {}).items():
        model.compliances[joint, AXIAL[joint]] = value
    return model


def dataset(arm: UrdfArm, seed: int) -> tuple[np.ndarray, np.ndarray, np.random.Generator]:
    """Joint rows (fit, then held out), the measurement noise for them, and the generator."""
    rng = np.random.default_rng(seed)
    joints = random_joints(arm.lower, arm.upper, FIT + HELD_OUT, rng)
    return joints, rng.normal(0.0, NOISE, (FIT + HELD_OUT, 3)), rng


def axial(model: ElastostaticModel) -> np.ndarray:
    """The identified axial compliances of the loaded joints, in LOADED's order."""
    return np.array([model.compliances[j, AXIAL[j]] for j in LOADED])


def test_identifies_the_axial_compliances_of_the_loaded_joints(arm: UrdfArm) -> None:
    """150 noisy rows (0.01 mm) of an arm that sags under its own weight, the joints'
    compliances alone fitted (the default terms): each loaded joint's axial compliance comes
    back within 10 %, and held-out points are predicted to 0.05 mm, where a rigid model
    misses them by far more (the sag is in the data). With the links' bending as well the
    compliances are not asked back: a link bending at its far end and the next joint turning
    at its pivot are nearly one motion, which points tell apart only weakly."""
    joints, noise, _ = dataset(arm, 1)
    truth = true_model(arm, compliances=LOADED)
    exact = truth.predict(joints)
    measured = exact + noise
    model = ElastostaticModel(arm).fit(joints[:FIT], measured[:FIT])
    assert model.gravity == 'URDF inertials'
    np.testing.assert_allclose(axial(model), list(LOADED.values()), rtol=0.10)
    error = np.linalg.norm(model.predict(joints[FIT:]) - exact[FIT:], axis=1)
    assert error.max() < 5e-5
    rigid = ElastostaticModel(arm, compliance=False).fit(joints[:FIT], measured[:FIT])
    assert np.linalg.norm(rigid.predict(joints[FIT:]) - exact[FIT:], axis=1).max() > 2e-4


def test_links_that_bend_and_joints_with_play_are_learnt_from_points_and_rotations() -> None:
    """An arm with a slide (the JAERI arm's kind) whose slide and wrist bend (end turns and
    sideways shifts) and whose joints have play, on top of their compliances, 15-20 mrad of sag
    in all, measured by an instrument already registered (points and rotations, 0.01 mm and
    0.01 mrad of noise): held-out points to 0.02 mm and rotations to 0.02 mrad, the
    registration held stays where it was and the noise of the rotations is found."""
    arm = UrdfArm.from_xml(prismatic_arm(), TIP)
    rng = np.random.default_rng(7)
    truth = ElastostaticModel(arm, terms=TERMS)
    truth.offset = np.array([0.0, 0.01, 0.05])
    truth.compliances[:, 1] = [0.0, 4e-4, 6e-4]      # [rad/(N·m)] about y: the sag
    truth.bending[:, 1] = [0.0, 2e-4, 4e-4]
    truth.shift[:, 2] = [0.0, 1e-4, 2e-4]            # [m/(N·m)]
    truth.play[:, 1] = [0.0, 2e-3, 1e-3]             # [rad]
    joints = random_joints(arm.lower, arm.upper, FIT + HELD_OUT, rng)
    points, rotations = truth.predict_pose(joints)
    turn = np.array([pin.log3(r @ np.linalg.inv(c))
                     for r, c in zip(rotations, arm.chain_at(joints, truth.offset).tip_rotation)])
    assert np.linalg.norm(turn, axis=1).max() > 0.015
    noisy = np.array([pin.exp3(rng.normal(0.0, NOISE, 3)) @ r for r in rotations[:FIT]])
    model = ElastostaticModel(arm, registration=False, terms=TERMS).fit(
        joints[:FIT], points[:FIT] + rng.normal(0.0, NOISE, (FIT, 3)), rotations=noisy)
    np.testing.assert_array_equal(model.rotation, np.eye(3))
    np.testing.assert_array_equal(model.translation, np.zeros(3))
    got_points, got_rotations = model.predict_pose(joints[FIT:])
    assert np.linalg.norm(got_points - points[FIT:], axis=1).max() < 2e-5
    left = [np.linalg.norm(pin.log3(g @ t.T)) for g, t in zip(got_rotations, rotations[FIT:])]
    assert max(left) < 2e-5
    assert model.rotation_noise == pytest.approx(NOISE, rel=0.3)


def test_terms_are_the_known_ones_with_the_compliances() -> None:
    """Elastic terms outside TERMS, or without the joints' compliances, are refused."""
    arm = UrdfArm.from_xml(prismatic_arm(), TIP)
    for terms in (('compliances', 'twist'), ('bending',)):
        with pytest.raises(ValueError, match='compliances'):
            ElastostaticModel(arm, terms=terms)


def test_the_stated_spread_is_the_spread_of_refits() -> None:
    """pose_std, the parameters' covariance carried to a prediction, is the scatter of the
    predictions of models fitted on other noise draws (within 30 %, 40 draws)."""
    arm = UrdfArm.from_xml(prismatic_arm(), TIP)
    rng = np.random.default_rng(8)
    truth = ElastostaticModel(arm)
    truth.compliances[:, 1] = [0.0, 2e-4, 3e-4]
    joints = random_joints(arm.lower, arm.upper, 30, rng)
    query = random_joints(arm.lower, arm.upper, 3, rng)
    exact = truth.predict(joints)
    fits = [ElastostaticModel(arm, registration=False).fit(
        joints, exact + rng.normal(0.0, 1e-4, exact.shape)) for _ in range(40)]
    scatter = np.std([f.predict(query) for f in fits], axis=0)
    stated = np.mean([f.pose_std(query)[:, :3] for f in fits], axis=0)
    np.testing.assert_allclose(stated, scatter, rtol=0.3, atol=2e-6)


def test_geometry_errors_do_not_bias_the_compliances_or_the_noise(arm: UrdfArm) -> None:
    """The same data from an arm whose joint origins are 0.5 mm / 0.5 mrad off the URDF (what
    the geometry part is for): the compliances still come back within 10 %, held-out points
    to 0.05 mm, and the noise estimate is the instrument's (within 20 %): one above it would
    say the priors were weighed against a noise larger than the one the fit ends with."""
    joints, noise, rng = dataset(arm, 1)
    truth = true_model(arm, rng.normal(0.0, GEOMETRY_ERROR, (arm.dof, 6)), LOADED)
    exact = truth.predict(joints)
    model = ElastostaticModel(arm).fit(joints[:FIT], exact[:FIT] + noise[:FIT])
    np.testing.assert_allclose(axial(model), list(LOADED.values()), rtol=0.10)
    assert np.linalg.norm(model.predict(joints[FIT:]) - exact[FIT:], axis=1).max() < 5e-5
    assert model.noise == pytest.approx(NOISE, rel=0.2)


def test_a_massless_urdf_fits_registration_and_geometry(arm: UrdfArm) -> None:
    """A URDF without inertials has no moments to scale: ``gravity`` says so, the model has no
    compliances, and registration and geometry are still fitted (held-out rows to 0.05 mm)."""
    massless = UrdfArm.from_xml(seven_joint_arm(masses=False), TIP)
    joints, noise, rng = dataset(massless, 2)
    truth = true_model(massless, rng.normal(0.0, SMALL_GEOMETRY_ERROR, (massless.dof, 6)))
    exact = truth.predict(joints)
    model = ElastostaticModel(massless)
    assert 'no inertials' in model.gravity and not model.compliance
    model.fit(joints[:FIT], exact[:FIT] + noise[:FIT])
    np.testing.assert_array_equal(model.compliances, 0.0)
    assert np.linalg.norm(model.predict(joints[FIT:]) - exact[FIT:], axis=1).max() < 5e-5
    assert ElastostaticModel(arm, compliance=False).gravity == 'not modelled'


def test_the_joint_jacobians_are_the_derivative_of_the_prediction(arm: UrdfArm) -> None:
    """joint_jacobians is d point / d q in the instrument's frame, with the geometry's twists
    (a rigid model: the compliant turn's own change with q is not in it)."""
    joints, _, rng = dataset(arm, 3)
    model = true_model(arm, rng.normal(0.0, 1e-2, (arm.dof, 6)))
    jacobians = model.joint_jacobians(joints[:4])
    step = 1e-6
    for q, jacobian in zip(joints[:4], jacobians):
        rows = q + step * np.concatenate([np.eye(arm.dof), -np.eye(arm.dof)])
        points = model.predict(rows)
        numeric = (points[:arm.dof] - points[arm.dof:]).T / (2 * step)
        np.testing.assert_allclose(jacobian, numeric, rtol=0, atol=1e-6)


def test_a_rows_prediction_depends_on_that_row_alone(arm: UrdfArm) -> None:
    """With payloads, predicting rows as a batch or one at a time (in any order) gives the same
    points: nothing of one row leaks into the next."""
    joints, _, rng = dataset(arm, 4)
    payload = rng.uniform(0.0, 5.0, len(joints))
    model = true_model(arm, compliances=LOADED)
    batch = model.predict(joints[:6], payload[:6])
    single = np.array([model.predict(joints[i], payload[i:i + 1])[0] for i in (5, 3, 1, 0, 2, 4)])
    np.testing.assert_allclose(single, batch[[5, 3, 1, 0, 2, 4]], rtol=0, atol=1e-12)


def test_a_prediction_bends_the_chain_as_the_fit_does() -> None:
    """Predictions (one rigid motion per joint, no derivatives) and the fit's bent chain
    (step by step, with derivatives) give the same points and rotations, every term on."""
    arm = UrdfArm.from_xml(prismatic_arm(), TIP)
    rng = np.random.default_rng(9)
    model = ElastostaticModel(arm, terms=TERMS)
    for name in TERMS:
        setattr(model, name, np.abs(rng.normal(0.0, 3e-4, (arm.dof, 3))))
    model.twists = rng.normal(0.0, 1e-3, (arm.dof, 6))
    joints = random_joints(arm.lower, arm.upper, 6, rng)
    payload = np.full(6, 2.0)
    predicted = model._evaluate(joints, payload, False)
    fitted = model._evaluate(joints, payload, True)
    np.testing.assert_allclose(predicted[0], fitted[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(predicted[1], fitted[1], rtol=0, atol=1e-12)


def test_the_target_rotation_is_registered_on_measured_orientations(arm: UrdfArm) -> None:
    """A model fitted to points alone meets measured orientations once the target's rotation
    on the tip link is registered on them: a probe mounted 20° off comes back to 0.02 mrad
    from rotations with 0.01 mrad of noise, and held-out orientations are met to 0.3 mrad
    (what the points tell of the arm's turns: measured 0.13 mrad at most)."""
    joints, noise, rng = dataset(arm, 5)
    truth = true_model(arm, compliances=LOADED)
    truth.tool = pin.exp3(np.radians(20.0) * np.array([0.3, 0.9, -0.3]))
    points, rotations = truth.predict_pose(joints)
    measured = np.array([pin.exp3(rng.normal(0.0, NOISE, 3)) @ r for r in rotations])
    model = ElastostaticModel(arm).fit(joints[:FIT], points[:FIT] + noise[:FIT])
    model.register_target_rotation(joints[:FIT], measured[:FIT])
    assert np.linalg.norm(pin.log3(model.tool @ truth.tool.T)) < 2e-5
    _, predicted = model.predict_pose(joints[FIT:])
    left = [np.linalg.norm(pin.log3(p @ t.T)) for p, t in zip(predicted, rotations[FIT:])]
    assert max(left) < 3e-4
