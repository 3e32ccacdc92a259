"""The kinds of model of where an arm's target really is, each with its 95 % error radius.

| kind | what it identifies |
|---|---|
| ``rigid`` | the registration only: the URDF as it is |
| ``geometric`` | + every joint origin's offset (a geometric calibration) |
| ``elastostatic`` | + the joints' and links' compliances under gravity |
| ``greybox`` | + each joint's learned error (:mod:`.joint_error`): the default |
| ``mlp`` | elastostatic + a network ensemble on all joints (:mod:`.residual_mlp`) |

The radius (:mod:`.error_radius`) is calibrated on a grouped ``folds``-fold cross-validation
of the training rows: each fold refits the physics (from the fit on all rows); the joint-error
GP keeps the hyperparameters of the fit on all rows (their optimisation is most of a fit's
time, and they vary little between folds; refitted in each fold from those, the UR10's
series B covered 0.943 of held-out rows at 200 training rows instead of 0.947, and the 40-row
bounds of series C widened to 2.9 times the median error). Numpy's BLAS runs on one thread:
these matrices are small, and a pool of threads competing for two busy cores made a fit ten
times slower.
The physics-only kinds state one spread for every row (their residual RMS); the grey-box its
GP's posterior. Where the measurements give the target's orientation, the physics fitted to the
points predicts it, the target's rotation registered on the measured ones: fitted with the
points, the turns weighed against them (1 mrad as 1 mm) and the UR10's series C held-out
coverage at 200 rows fell from 0.95 to 0.86. The residual models and the radius are of the
point.
"""
from __future__ import annotations

import numpy as np
from threadpoolctl import threadpool_limits

from flexarm_learning.choices import DEFAULT_KIND, KINDS
from flexarm_learning.elastostatic import ElastostaticModel
from flexarm_learning.error_radius import conformal_factor
from flexarm_learning.joint_error import JointErrorGp
from flexarm_learning.measurements import Measurements
from flexarm_learning.residual_mlp import ResidualMlp
from flexarm_learning.urdf_arm import UrdfArm

FOLDS = 5


class ArmErrorModel:
    """One kind, fitted on measurements: predicted points and their 95 % radius."""

    def __init__(self, arm: UrdfArm, kind: str = DEFAULT_KIND) -> None:
        if kind not in KINDS:
            raise ValueError(f'unknown kind {kind!r}; the kinds: {", ".join(KINDS)}')
        self.arm, self.kind = arm, kind
        self.factor = float('nan')

    def _physics(self) -> ElastostaticModel:
        return ElastostaticModel(self.arm, geometry=self.kind != 'rigid',
                                 compliance=self.kind not in ('rigid', 'geometric'))

    def fit(self, data: Measurements, folds: int = FOLDS, seed: int = 0) -> ArmErrorModel:
        with threadpool_limits(1):
            return self._fit_all(data, folds, seed)

    def _fit_all(self, data: Measurements, folds: int, seed: int) -> ArmErrorModel:
        self.physics, self.residual = self._fit(data)
        scores = []
        for held in _folds(data.group, folds, seed):
            physics, residual = self._fit(data.subset(~held), self.residual, self.physics)
            points, spread = _predict(physics, residual, data.subset(held))
            scores.append(np.linalg.norm(points - data.points[held], axis=1) / spread)
        self.scores = np.concatenate(scores)
        self.factor = conformal_factor(self.scores)
        return self

    def _fit(self, data: Measurements, like: JointErrorGp | ResidualMlp | None = None,
             start: ElastostaticModel | None = None):
        physics = self._physics().fit(data.joints, data.points, data.payload, start)
        if data.rotations is not None:
            physics.register_target_rotation(data.joints, data.rotations, data.payload)
        if self.kind not in ('greybox', 'mlp'):
            return physics, None
        left = data.points - physics.predict(data.joints, data.payload)
        if self.kind == 'mlp':
            return physics, ResidualMlp().fit(data.joints, left)
        residual = JointErrorGp().fit(data.joints, physics.joint_jacobians(data.joints), left,
                                      None if like is None else like.hyper)
        return physics, residual

    def rotations(self, joints: np.ndarray, payload: np.ndarray | None = None) -> np.ndarray:
        """(M, 3, 3): the target's orientation in the instrument's frame, the physics' (the
        learned residuals are of the point)."""
        with threadpool_limits(1):
            return self.physics.predict_pose(np.atleast_2d(joints), payload)[1]

    def predict(self, joints: np.ndarray, payload: np.ndarray | None = None,
                ) -> tuple[np.ndarray, np.ndarray]:
        """Points (M, 3) [m] in the instrument's frame and their 95 % radius (M,) [m]."""
        points, spread = self.predict_spread(joints, payload)
        return points, self.factor * spread

    def predict_spread(self, joints: np.ndarray, payload: np.ndarray | None = None,
                       ) -> tuple[np.ndarray, np.ndarray]:
        """Points (M, 3) [m] and their raw radial spread ρ (M,) [m], which :attr:`factor`
        (or an :class:`~flexarm_learning.online_radius.OnlineRadius` started from
        :attr:`scores`) turns into the 95 % radius."""
        joints = np.atleast_2d(joints)
        payload = np.zeros(len(joints)) if payload is None else payload
        data = Measurements(joints, np.zeros((len(joints), 3)), payload,
                            np.zeros(len(joints)))
        with threadpool_limits(1):
            return _predict(self.physics, self.residual, data)


def _predict(physics: ElastostaticModel, residual: JointErrorGp | ResidualMlp | None,
             data: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """Points and raw radial spread ρ [m] of a fitted physics and residual."""
    points = physics.predict(data.joints, data.payload)
    if residual is None:
        return points, np.full(len(points), physics.noise * np.sqrt(3.0))
    if isinstance(residual, ResidualMlp):
        mean, cov = residual.predict(data.joints)
    else:
        mean, cov = residual.predict(data.joints, physics.joint_jacobians(data.joints))
    return points + mean, np.sqrt(np.trace(cov, axis1=1, axis2=2))


def _folds(group: np.ndarray, folds: int, seed: int) -> list[np.ndarray]:
    """Boolean held-out masks of a grouped k-fold: each group in one fold."""
    labels = np.unique(group)
    order = np.random.default_rng(seed).permutation(len(labels))
    fold_of = dict(zip(labels[order], np.arange(len(labels)) % folds))
    index = np.array([fold_of[g] for g in group])
    return [index == k for k in range(min(folds, len(labels)))]
