"""Physics-informed grey-box predictor: the robot description's elastostatic model, identified
from the samples, plus an optional learned residual.

The structure is the learning core's (:mod:`flexarm_learning.elastostatic`, the one any arm's
measurements go through in ``flexarm accuracy``) on the URDF that flexarm_description writes
from config/arm.yaml — the nominal geometry and masses, what a site knows: Pinocchio's
kinematics and gravity moments (the payload [kg] a point mass at the tip), each joint's
compliance and play (a dead band of ``dead_band`` [N·m]) and the bending of the link it
carries, every joint origin's geometric error. The elastic terms' prior is
``compliance_prior`` [rad] of turn at each moment's RMS over the workspace: the JAERI arm sags
10-20 mm over 1.6 m, ~10 mrad (the core's default, 1 mrad, is an industrial arm's: with it,
20 samples at 0 kg predicted 5 kg four times worse in region A). The camera measures the tip
in the arm's frame, so the registration is held and the tip's offset (the last link's own
length error) is free. The graph stays planar: a sample's deflection (dx, dy, dφ) is turned
into the tip's pose in the URDF's frame (x, 0, y; φ a turn about −y) and back. The simulated
arm has this structure but for one compliance per sign of each moment (Table 5):
benchmarks/core_on_jaeri.py gives the figures; a real arm's departures from it are left to
the residual.

``residual`` 'gp': a Gaussian process (:mod:`.gp`, kernel ``residual_kernel``) learns what
the structure leaves (camera errors, friction, what the moments miss); training chooses
'none' or 'gp' by cross-validation.

The payload enters the moments linearly and the compliances do not depend on it, so the model
carries the payload physically (:attr:`payload_physical`): fitted on the samples' payloads (or
``payload`` when they come without one), it predicts at whatever payload it is asked,
``payload_input`` or not — also from samples at a single payload. A query without a payload is
at the payload trained at (``greybox.trained_payload``: the samples' mean). The residual GP
takes the payload only with ``payload_input``; otherwise it stays as trained at every payload:
what it learns (camera errors, friction, thermal growth) does not grow with the load. From one
payload, turns the samples hardly tell apart (a link's bending at its far end, the next
joint's compliance at the same point) are split by the prior, and the payload's step
multiplies what the split got wrong; samples at two payloads tell them apart.

Uncertainty (:meth:`GreyboxPredictor.deflection_std`, :meth:`GreyboxPredictor.prior_std`): the
identified parameters' Laplace covariance carried to the prediction, with the residual GP's
posterior; and, from samples at a single payload, what they cannot tell — the compliances took
up the nominal masses' error with them, so a payload's change is off, joint by joint, by the
relative error of that joint's moments under each independent error of the inertia prior
(config/arm.yaml ``arm.inertia_uncertainty``: all masses together, each body's, the tool's
centre; :meth:`flexarm_learning.urdf_arm.UrdfArm.moment_errors`) times what that joint's
moments' change does (:meth:`flexarm_learning.elastostatic.ElastostaticModel.load_effects`);
one error moves every joint that carries its body, so their shares add before the errors
are summed in quadrature (taken joint by joint, as if each joint's error were its own, the
bound in region B was half the old planar model's and covered 0.73 of the goals with the
masses off). Samples at two
payloads tell the two apart: no prior term then.

The URDF, the description it was written from (``greybox.arm``: the rigid model the
deflection is taken against, flexarm_core's ``forward``, which the URDF's kinematics meet to
1e-12 m) and the identified parameters are kept in the model file: a saved model is
self-contained. A grey-box file of the planar structure
flexarm had before has no URDF and is refused: train a new one. flexarm_learning (Pinocchio,
0.2 s of CPU to import) is imported at the first fit or load, not with the node.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from flexarm_core.kinematics import ArmGeometry, forward, wrap_angle
from flexarm_deflection.predictors.base import PAYLOAD_TOLERANCE, Predictor, restore
from flexarm_deflection.predictors.gp import GpPredictor
from flexarm_deflection.predictors.kinematic import read_config
from flexarm_description.chain import TIP_FRAME
from flexarm_description.urdf_model import robot_description
from flexarm_learning.ard_gp import KERNELS

if TYPE_CHECKING:
    from flexarm_learning.elastostatic import ElastostaticModel

RESIDUALS = ('none', 'gp')
LEVER = 1.0     # [m] a link's shift prior is the turn prior's over this lever


def description() -> dict[str, Any]:
    """The robot description: config/arm.yaml ``arm`` (nominal geometry and masses, and how
    far its inertia may be off: ``inertia_uncertainty``)."""
    return read_config('arm.yaml')['arm']


def planar(points: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Tip poses (N, 3) [m, m, rad] in the arm's plane of points (N, 3) and rotations
    (N, 3, 3) in the URDF's frame (the plane its x-z, φ a turn about −y)."""
    pose = np.empty((len(points), 3))
    pose[:, 0], pose[:, 1] = points[:, 0], points[:, 2]
    pose[:, 2] = -np.arctan2(rotations[:, 0, 2], rotations[:, 0, 0])
    return pose


class GreyboxPredictor(Predictor):
    """The URDF's elastostatic model through the learning core, plus an optional GP."""

    kind: ClassVar[str] = 'greybox'
    defaults: ClassVar[dict[str, Any]] = {
        'dead_band': 0.5, 'compliance_prior': 0.01, 'payload': 0.0, 'residual': 'gp',
        'residual_kernel': 'matern32', 'residual_restarts': 0, 'seed': 0,
        'payload_input': False}
    cv_choices: ClassVar[dict[str, list[Any]]] = {'residual': list(RESIDUALS)}
    physical: ClassVar[bool] = True

    def _check_settings(self) -> None:
        s = self.settings
        if s['dead_band'] <= 0 or s['compliance_prior'] <= 0 or s['payload'] < 0:
            raise ValueError("greybox needs 'dead_band' > 0, 'compliance_prior' > 0 and "
                             "'payload' >= 0")
        if s['residual'] not in RESIDUALS:
            raise ValueError(f"greybox 'residual' must be one of {list(RESIDUALS)}, "
                             f"got {s['residual']!r}")
        if s['residual_kernel'] not in KERNELS or s['residual_restarts'] < 0:
            raise ValueError(f"greybox 'residual_kernel' must be one of {sorted(KERNELS)} "
                             "and 'residual_restarts' >= 0")

    @property
    def payload_physical(self) -> bool:
        return True

    def _core(self, urdf: str) -> ElastostaticModel:
        """The learning core's model of the URDF: all its elastic terms, the registration
        held."""
        from flexarm_learning.elastostatic import TERMS, ElastostaticModel, Priors
        from flexarm_learning.urdf_arm import UrdfArm

        prior = self.settings['compliance_prior']
        return ElastostaticModel(UrdfArm.from_xml(urdf, TIP_FRAME),
                                 Priors(compliance=prior, shift=prior * LEVER,
                                        dead_band=self.settings['dead_band']),
                                 registration=False, terms=TERMS)

    def _fit_physical(self, joints: np.ndarray, payload: np.ndarray | None,
                      deflections: np.ndarray) -> None:
        from scipy.spatial.transform import Rotation

        arm = description()
        self._geometry = ArmGeometry.from_dict(arm)
        urdf = robot_description(self._geometry, arm['inertia'], hardware='')
        self._model = self._core(urdf)
        if payload is None:
            payload = np.full(len(joints), self.settings['payload'])
        self._trained_payload = float(payload.mean())
        pose = forward(self._geometry, joints) + deflections
        points = np.column_stack([pose[:, 0], np.zeros(len(pose)), pose[:, 1]])
        rotations = Rotation.from_rotvec(np.outer(-pose[:, 2], [0.0, 1.0, 0.0])).as_matrix()
        self._model.fit(joints, points, payload, rotations=rotations)
        self._error_shares = None
        if np.ptp(payload) <= PAYLOAD_TOLERANCE:     # one payload: the masses' prior decides
            self._error_shares = self._moment_error_shares(joints, payload,
                                                        arm['inertia_uncertainty'])
        self._residual: GpPredictor | None = None
        if self.settings['residual'] == 'gp':
            left = deflections - self._structure(joints, payload)
            self._residual = GpPredictor({
                'kernel': self.settings['residual_kernel'], 'seed': self.settings['seed'],
                'restarts': self.settings['residual_restarts'],
                'payload_input': self.settings['payload_input']}).fit(joints, left, payload)
        model = self._model
        self.metadata['greybox'] = {
            'urdf': urdf, 'arm': {k: v for k, v in arm.items() if k != 'inertia_uncertainty'},
            'trained_payload': self._trained_payload,
            'noise': {'position': model.noise, 'angle': model.rotation_noise},
            'elastic': {name: getattr(model, name).tolist() for name in model.terms},
            'moment_error_shares': (None if self._error_shares is None
                                    else self._error_shares.tolist()),
            'residual': None if self._residual is None else self._residual.metadata}

    def _moment_error_shares(self, joints: np.ndarray, payload: np.ndarray,
                             uncertainty: Mapping[str, Any]) -> np.ndarray:
        """(sources, n): per independent error of the inertia prior, each joint's moment's
        relative error it makes over the samples (the least-squares factor of its moment
        change on the moment, the axes pooled): one source moves every joint that carries
        what it is the error of, so their shares add before they are squared."""
        arm = self._model.arm
        chain = arm.chain_at(joints, self._model.offset)
        errors = arm.moment_errors(chain, float(uncertainty['common']),
                                   float(uncertainty['part']),
                                   float(uncertainty['end_effector_com']))
        moments = arm.gravity_moments(chain, payload)
        return (np.einsum('srkx,rkx->sk', errors, moments)
                / np.maximum(np.sum(moments ** 2, axis=(0, 2)), 1e-12))

    def _structure(self, joints: np.ndarray, payload: np.ndarray | float) -> np.ndarray:
        """The core's deflection (N, 3) at joints (N, 4) and the payload [kg]."""
        d = planar(*self._model.predict_pose(joints, payload))
        d -= forward(self._geometry, joints)
        d[:, 2] = wrap_angle(d[:, 2])
        return d

    def _at(self, payload: np.ndarray | None) -> np.ndarray | float:
        return self._trained_payload if payload is None else payload

    def _predict_physical(self, joints: np.ndarray, payload: np.ndarray | None) -> np.ndarray:
        y = self._structure(joints, self._at(payload))
        return y if self._residual is None else y + self._residual.predict(joints, payload)

    def position_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                     ) -> np.ndarray | float:
        """The residual GP's (:meth:`.GpPredictor.position_std`); 0 without one."""
        if self._residual is None:
            return super().position_std(joints, payload)
        return self._residual.position_std(joints, payload)

    def deflection_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                       ) -> np.ndarray:
        """The structure's, from its parameters' covariance, and the residual GP's."""
        q, p, single = self._query(joints, payload)
        self._require_fitted()
        std = self._model.pose_std(q, self._at(p))[:, [0, 2, 4]]     # x, z, the turn about y
        if self._residual is not None:
            std = np.hypot(std, self._residual.deflection_std(q, p))
        return std[0] if single else std

    def prior_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                  ) -> np.ndarray:
        """Trained at one payload, the compliances took up the masses' error with them:
        asked at another, each joint's share of the change is off by its moments' relative
        error under each error of the inertia prior, the shares of one error added, the
        errors in quadrature (module docstring). Zeros at the trained payload, or when the
        samples held several."""
        q, p, single = self._query(joints, payload)
        self._require_fitted()
        std = np.zeros((len(q), 3))
        asked = np.broadcast_to(self._at(p), (len(q),))
        if self._error_shares is not None:
            for kg in np.unique(asked):
                rows = asked == kg
                if abs(kg - self._trained_payload) <= PAYLOAD_TOLERANCE:
                    continue
                effects = self._model.load_effects(q[rows], self._trained_payload, kg)
                shares = np.einsum('sk,knx->snx', self._error_shares,
                                   effects[:, :, [0, 2, 4]])
                std[rows] = np.sqrt(np.sum(shares ** 2, axis=0))
        return std[0] if single else std

    def _state(self) -> dict[str, np.ndarray]:
        state = self._model.state()
        if self._residual is not None:
            state.update({f'residual.{k}': v for k, v in self._residual._state().items()})
        return state

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        meta = self.metadata['greybox']
        if 'urdf' not in meta:
            raise ValueError('a grey-box of the planar structure flexarm had before: '
                             'train a new one')
        self._model = self._core(meta['urdf']).restored(dict(state))
        self._geometry = ArmGeometry.from_dict(meta['arm'])
        self._trained_payload = float(meta['trained_payload'])
        spread = meta.get('moment_error_shares')
        self._error_shares = None if spread is None else np.asarray(spread, dtype=float)
        self._residual = None if meta['residual'] is None else restore(
            GpPredictor, meta['residual'], {
                'support': state['support'],
                **{k[len('residual.'):]: v for k, v in state.items()
                   if k.startswith('residual.')}})
