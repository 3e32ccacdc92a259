"""The kinds of model of where an arm's target really is, each with its 95 % error radius.

| kind | what it identifies |
|---|---|
| ``rigid`` | the registration only: the URDF as it is |
| ``geometric`` | + every joint origin's offset (a geometric calibration) |
| ``elastostatic`` | + the joints' and links' compliances under gravity |
| ``greybox`` | + each joint's learned error (:mod:`.joint_error`): the default |
| ``gp`` | elastostatic + a GP on all joints (:mod:`.residual_gp`) |
| ``mlp`` | elastostatic + a network ensemble on all joints (:mod:`.residual_mlp`) |
| ``auto`` | whichever of ``AUTO_CANDIDATES`` cross-validates best (lowest mean error) |

``auto`` costs the sum of its candidates' fits; the default stays ``greybox``, which
``auto`` chose on every split of the UR10's series C (docs/accuracy.md).

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

from flexarm_learning.choices import AUTO_CANDIDATES, DEFAULT_KIND, KINDS
from flexarm_learning.elastostatic import ElastostaticModel
from flexarm_learning.error_radius import conformal_factor
from flexarm_learning.joint_error import JointErrorGp
from flexarm_learning.measurements import Measurements
from flexarm_learning.residual_gp import ResidualGp
from flexarm_learning.residual_mlp import ResidualMlp
from flexarm_learning.urdf_arm import UrdfArm

FOLDS = 5
Residual = JointErrorGp | ResidualGp | ResidualMlp


class ArmErrorModel:
    """One kind, fitted on measurements: predicted points and their 95 % radius."""

    def __init__(self, arm: UrdfArm, kind: str = DEFAULT_KIND) -> None:
        if kind not in KINDS:
            raise ValueError(f'unknown kind {kind!r}; the kinds: {", ".join(KINDS)}')
        self.arm, self.kind, self.chosen = arm, kind, kind
        self.factor = float('nan')
        self.cv_mean_m: dict[str, float] = {}

    def _physics(self) -> ElastostaticModel:
        return ElastostaticModel(self.arm, geometry=self.chosen != 'rigid',
                                 compliance=self.chosen not in ('rigid', 'geometric'))

    def fit(self, data: Measurements, folds: int = FOLDS, seed: int = 0) -> ArmErrorModel:
        """The model on all rows, its radius calibrated on a grouped cross-validation;
        ``auto`` fits every candidate and keeps the one whose held-out mean error is least
        (:attr:`cv_mean_m` holds each one's)."""
        with threadpool_limits(1):
            if self.kind != 'auto':
                return self._fit_all(data, folds, seed)
            fitted = [ArmErrorModel(self.arm, kind)._fit_all(data, folds, seed)
                      for kind in AUTO_CANDIDATES]
        best = min(fitted, key=lambda model: model.cv_mean_m[model.kind])
        self.chosen, self.physics, self.residual = best.kind, best.physics, best.residual
        self.scores, self.factor = best.scores, best.factor
        self.cv_mean_m = {model.kind: model.cv_mean_m[model.kind] for model in fitted}
        return self

    def _fit_all(self, data: Measurements, folds: int, seed: int) -> ArmErrorModel:
        self.physics, self.residual = self._fit(data, seed=seed)
        scores, errors = [], []
        for held in _folds(data.group, folds, seed):
            physics, residual = self._fit(data.subset(~held), self.residual, self.physics, seed)
            points, spread = _predict(physics, residual, data.subset(held))
            errors.append(np.linalg.norm(points - data.points[held], axis=1))
            scores.append(errors[-1] / spread)
        self.scores = np.concatenate(scores)
        self.factor = conformal_factor(self.scores)
        self.cv_mean_m = {self.kind: float(np.concatenate(errors).mean())}
        return self

    def _fit(self, data: Measurements, like: Residual | None = None,
             start: ElastostaticModel | None = None, seed: int = 0,
             ) -> tuple[ElastostaticModel, Residual | None]:
        physics = self._physics().fit(data.joints, data.points, data.payload, start)
        if data.rotations is not None:
            physics.register_target_rotation(data.joints, data.rotations, data.payload)
        if self.chosen not in ('greybox', 'gp', 'mlp'):
            return physics, None
        left = data.points - physics.predict(data.joints, data.payload)
        if self.chosen == 'mlp':
            return physics, ResidualMlp().fit(data.joints, left)
        if self.chosen == 'gp':
            return physics, ResidualGp().fit(data.joints, left,
                                             None if like is None else like.theta, seed)
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


def _predict(physics: ElastostaticModel, residual: Residual | None,
             data: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """Points and raw radial spread ρ [m] of a fitted physics and residual."""
    points = physics.predict(data.joints, data.payload)
    if residual is None:
        return points, np.full(len(points), physics.noise * np.sqrt(3.0))
    if isinstance(residual, JointErrorGp):
        mean, cov = residual.predict(data.joints, physics.joint_jacobians(data.joints))
    else:
        mean, cov = residual.predict(data.joints)
    return points + mean, np.sqrt(np.trace(cov, axis1=1, axis2=2))


def _folds(group: np.ndarray, folds: int, seed: int) -> list[np.ndarray]:
    """Boolean held-out masks of a grouped k-fold: each group in one fold."""
    labels = np.unique(group)
    order = np.random.default_rng(seed).permutation(len(labels))
    fold_of = dict(zip(labels[order], np.arange(len(labels)) % folds))
    index = np.array([fold_of[g] for g in group])
    return [index == k for k in range(min(folds, len(labels)))]
