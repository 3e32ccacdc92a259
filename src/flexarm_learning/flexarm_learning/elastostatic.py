"""The arm's physics from its URDF, identified from measurements: where the instrument sees
the target, given the joints and the payload.

    point = R_reg · (target(q; geometry) + Σ_k ω_k × (target − o_k)) + t_reg,
    ω_k = R_k · (c_k ⊙ M_k(q, payload))

- **Registration** (R_reg, t_reg): the instrument's frame to the arm's root, and the target's
  offset from the tip link (a probe, a camera's hole plate): free, as every calibration tool
  has them.
- **Geometry**: each chain joint's URDF origin moved by a small twist (3 translations, 3
  rotations), with a prior toward the nominal (``geometry_prior``: 1 mm, 1 mrad) — the
  redundant directions (the first joint's origin and the registration, a joint's offset and its
  origin's turn about its axis) stay where the prior holds them.
- **Compliance** (deflection = J · C · τ_g): each joint turns by its compliance times the
  gravity moment on what it carries, about its axis (the joint's own) and about the two
  perpendicular axes (the links' bending and the bearings' tilt), pivoting at its URDF origin
  (a prismatic joint's guide): three compliances per joint,
  none negative (a joint gives way to its load), with a prior of ``Priors.compliance`` [rad] of
  turn at the moment's RMS over the arm's workspace (``WORKSPACE`` configurations drawn within
  the joint limits, the payload the samples' mean). The workspace's, not the samples': a
  moment the samples hardly vary (the wrist's, on the UR10 of ../shared/data) let a
  compliance grow to mrad/N·m that a pose with more moment turned into a 12 mm miss.
  First order in the deflection: sub-mrad on an industrial arm.
  A URDF without inertials has no moment to scale: the model is then registration and
  geometry (:attr:`gravity` says which), and what gravity does is left to the residual.

Maximum a posteriori by Gauss-Newton on the analytic Jacobian, the measurement noise
re-estimated from the residuals until it settles (the first guess, the rigid model's residual,
weighed the priors against a noise 3-50 times too large). :attr:`registration_std` is the
Laplace standard deviation of the registration and the target offset: large where the rows
cannot tell them apart (poses that all hold the tool the same way leave the offset along the
tool to the instrument's translation). The Jacobian of the target by the joints
(:meth:`joint_jacobians`, Pinocchio's frame Jacobian, in the instrument's frame) carries a
learned joint error to the instrument (:mod:`.joint_error`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.optimize import lsq_linear

from flexarm_learning.registration import kabsch
from flexarm_learning.urdf_arm import UrdfArm

REGISTRATION = 9        # rotation, translation, target offset: no prior
ITERATIONS = 8          # Gauss-Newton steps at most
NOISE_FLOOR = 1e-6      # [m] the noise estimate's floor (an exact fit: simulated data)
PASSES = 8              # noise re-estimates at most: the fit is weighed by its own residual
NOISE_SETTLED = 0.05    # a noise estimate within 5 % of the last ends them
CONVERGED = 1e-8        # [m or rad] a step this small ends the iterations
WORKSPACE = 200         # configurations whose moments scale the compliance prior


@dataclass(frozen=True)
class Priors:
    """Standard deviations of the prior toward the nominal description."""

    translation: float = 1e-3    # [m] a joint origin's shift
    rotation: float = 1e-3       # [rad] a joint origin's turn
    compliance: float = 1e-3     # [rad] a compliant turn at the RMS moment


class ElastostaticModel:
    """Registration, geometry and compliances of one arm, identified from measured points."""

    def __init__(self, arm: UrdfArm, priors: Priors | None = None, compliance: bool = True,
                 geometry: bool = True) -> None:
        self.arm, self.priors = arm, priors or Priors()
        self.geometry = geometry
        self.compliance = compliance and arm.has_masses
        self.gravity = ('URDF inertials' if self.compliance else
                        'none (the URDF has no inertials)' if compliance and not arm.has_masses
                        else 'not modelled')

    # -- parameters: [registration 9 | geometry 6n | compliance 3n] --------------------------
    @property
    def size(self) -> int:
        n = self.arm.dof
        return REGISTRATION + 6 * n * self.geometry + 3 * n * self.compliance

    def fit(self, joints: np.ndarray, points: np.ndarray, payload: np.ndarray | None = None,
            start: ElastostaticModel | None = None) -> ElastostaticModel:
        """Identify the parameters from rows of joints (N, n) and measured points (N, 3) [m];
        from ``start``'s parameters and noise (a model of the same kind fitted on similar rows:
        cross-validation's folds) instead of Kabsch's registration and the nominal."""
        joints, points = np.asarray(joints, float), np.asarray(points, float)
        payload = np.zeros(len(joints)) if payload is None else np.asarray(payload, float)
        n = self.arm.dof
        if start is None:
            self.offset = np.zeros(3)
            self.twists = np.zeros((n, 6))
            self.compliances = np.zeros((n, 3))
            rigid = np.array([self.arm.state(q, self.offset).target for q in joints])
            self.rotation, self.translation = kabsch(rigid, points)
        else:
            for name in ('offset', 'twists', 'compliances', 'rotation', 'translation'):
                setattr(self, name, getattr(start, name).copy())
        scale = self._workspace_moments(float(payload.mean())) if self.compliance else None
        prior = np.concatenate([
            np.zeros(REGISTRATION),
            np.tile([1 / self.priors.translation] * 3 + [1 / self.priors.rotation] * 3,
                    n * self.geometry),
            (scale / self.priors.compliance).ravel() if self.compliance else []])
        floor = np.concatenate([np.full(self.size - 3 * n * self.compliance, -np.inf),
                                np.zeros(3 * n * self.compliance)])
        noise = None if start is None else start.noise
        for _ in range(PASSES):
            moments = self._moments(joints, payload)    # the payload at the target found
            for _ in range(ITERATIONS):
                residual, jac = self._linearise(joints, points, moments)
                if noise is None:
                    noise = max(float(np.sqrt(np.mean(residual ** 2))), NOISE_FLOOR)
                step = self._step(residual, jac, noise, prior, floor)
                self._apply(step)
                if np.max(np.abs(step)) < CONVERGED:
                    break
            residual, jac = self._linearise(joints, points, moments)
            settled = max(float(np.sqrt(np.mean(residual ** 2))), NOISE_FLOOR)
            done = abs(settled - noise) <= NOISE_SETTLED * noise
            noise = settled
            if done:
                break
        self.noise = noise
        information = jac.T @ jac / noise ** 2 + np.diag(prior ** 2)
        self.registration_std = np.sqrt(np.abs(np.diag(
            np.linalg.pinv(information, hermitian=True))[:REGISTRATION]))
        return self

    def _parameters(self) -> np.ndarray:
        return np.concatenate([np.zeros(6), self.offset,
                               self.twists.ravel() if self.geometry else [],
                               self.compliances.ravel() if self.compliance else []])

    def _step(self, residual: np.ndarray, jac: np.ndarray, noise: float,
              prior: np.ndarray, floor: np.ndarray) -> np.ndarray:
        """The Gauss-Newton step of the MAP problem: data weighted by the noise, each
        parameter drawn to 0 by its prior (registration: none), none below its ``floor``."""
        x = self._parameters()
        a = np.concatenate([jac / noise, np.diag(prior)])
        b = np.concatenate([-residual / noise, -prior * x])
        active = np.any(a != 0, axis=0)
        step = np.zeros(self.size)
        lower = np.minimum(floor[active] - x[active], 0.0)
        step[active] = lsq_linear(a[:, active], b, bounds=(lower, np.inf)).x
        return step

    def _workspace_moments(self, payload: float) -> np.ndarray:
        """(n, 3) [N·m]: each joint's moment RMS over ``WORKSPACE`` seeded configurations
        within the joint limits (a continuous joint over one turn)."""
        rng = np.random.default_rng(0)
        low = np.where(np.isfinite(self.arm.lower), self.arm.lower, -np.pi)
        high = np.where(np.isfinite(self.arm.upper), self.arm.upper, np.pi)
        moments = np.array([self.arm.gravity_moments(rng.uniform(low, high), payload)
                            for _ in range(WORKSPACE)])
        return np.sqrt(np.mean(moments ** 2, axis=0))

    def _apply(self, step: np.ndarray) -> None:
        n = self.arm.dof
        self.rotation = pin.exp3(step[:3]) @ self.rotation
        self.translation = self.translation + step[3:6]
        self.offset = self.offset + step[6:9]
        k = REGISTRATION
        if self.geometry:
            self.twists = self.twists + step[k:k + 6 * n].reshape(n, 6)
            k += 6 * n
        if self.compliance:
            self.compliances = self.compliances + step[k:k + 3 * n].reshape(n, 3)

    def _model(self) -> pin.Model:
        """The URDF's model with each chain joint's origin moved by its twist."""
        if not self.geometry or not np.any(self.twists):
            return self.arm.model
        model = self.arm.model.copy()
        for k, j in enumerate(self.arm.chain):
            model.jointPlacements[j] = model.jointPlacements[j] * pin.exp6(
                pin.Motion(self.twists[k, :3], self.twists[k, 3:]))
        return model

    def _moments(self, joints: np.ndarray, payload: np.ndarray) -> np.ndarray:
        if not self.compliance:
            return np.zeros((len(joints), self.arm.dof, 3))
        return np.array([self.arm.gravity_moments(q, m, self.offset)
                         for q, m in zip(joints, payload)])

    def _rows(self, joints: np.ndarray, moments: np.ndarray, jacobian: bool):
        """Per row: the point in the instrument's frame, and with ``jacobian`` its
        derivatives by the parameters (3, size)."""
        model = self._model()
        n = self.arm.dof
        for q, m in zip(joints, moments):
            s = self.arm.state(q, self.offset, model)
            target = s.target
            body = target.copy()
            if self.compliance:
                for f, o, c, mk in zip(s.joints, s.placed, self.compliances, m):
                    body += pin.skew(f.rotation @ (c * mk)) @ (target - o.translation)
            point = self.rotation @ body + self.translation
            if not jacobian:
                yield point, None
                continue
            d = np.zeros((3, self.size))
            d[:, :3] = -pin.skew(self.rotation @ body)
            d[:, 3:6] = np.eye(3)
            d[:, 6:9] = self.rotation @ s.tip_rotation
            k = REGISTRATION
            if self.geometry:
                for i, f in enumerate(s.placed):
                    d[:, k + 6 * i:k + 6 * i + 3] = self.rotation @ f.rotation
                    d[:, k + 6 * i + 3:k + 6 * i + 6] = (
                        -self.rotation @ pin.skew(target - f.translation) @ f.rotation)
                k += 6 * n
            if self.compliance:
                for i, (f, o) in enumerate(zip(s.joints, s.placed)):
                    d[:, k + 3 * i:k + 3 * i + 3] = (
                        -self.rotation @ pin.skew(target - o.translation) @ f.rotation * m[i])
            yield point, d

    def _linearise(self, joints, points, moments) -> tuple[np.ndarray, np.ndarray]:
        rows = list(self._rows(joints, moments, True))
        residual = np.concatenate([p for p, _ in rows]) - points.ravel()
        return residual, np.concatenate([d for _, d in rows])

    def predict(self, joints: np.ndarray, payload: np.ndarray | None = None) -> np.ndarray:
        """(N, 3) [m]: where the instrument would see the target."""
        joints = np.atleast_2d(np.asarray(joints, float))
        payload = np.zeros(len(joints)) if payload is None else np.asarray(payload, float)
        moments = self._moments(joints, payload)
        return np.array([p for p, _ in self._rows(joints, moments, False)])

    def joint_jacobians(self, joints: np.ndarray) -> np.ndarray:
        """(N, 3, n): the point's derivative by each joint, in the instrument's frame."""
        joints = np.atleast_2d(np.asarray(joints, float))
        model = self._model()
        return np.array([self.rotation @ self.arm.state(q, self.offset, model).jacobian
                         for q in joints])
