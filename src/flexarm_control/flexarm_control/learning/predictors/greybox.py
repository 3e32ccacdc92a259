"""Physics-informed grey-box predictor: the arm's gravity-moment structure with unknown
compliances, identified from the samples, plus an optional learned residual.

Each compliant element turns or bends by (its compliance) × (the gravity moment about it,
:mod:`flexarm_control.learning.gravity_moments`: the nominal masses and the payload, on the rigid
pose), propagated to the tip through the kinematic chain of :mod:`.kinematic` (with its kinematic
errors): joint1 and the joint-2 guide turn everything about joint1 (moments M1, M2); the No.2
arm bends — shifts joint3 sideways and turns it — by M2; joint3 turns and the third arm bends
by M3; joint4 turns and the fourth arm bends by M4 (tip shift, tip angle).
Backlash makes a joint's turn jump where its moment changes sign: one dead-band term per joint
element (J1, guide, J3, J4), a turn × tanh(M / ``dead_band``). The deflection is linear in the
14 element terms (10 compliances, 4 dead bands) and the 7 kinematic errors to first order;
nonlinear least squares from zero (:func:`.kinematic.solve`, its first step the linear one)
takes the second order (~0.2 mm at 0.015 rad of sag over 1.6 m) too, with a ridge ``ridge`` on
the terms in their effect units (each compliance × the RMS of its moment over the samples, rad
or m). One compliance per element: the sign dependence of Table 5 matters only where a moment
changes sign, like the backlash.

The simulated arm (:mod:`flexarm_sim.plant`) has exactly this structure, so there the grey-box
is near exact (`flexarm study`, 40 camera-measured samples, worst of 3 seeds over 200 held-out
poses: 0.003 mm in region A, 0.016 mm in B, the GP 0.044 and 0.437 mm); a real arm's departures
from it are left to the residual.

``residual`` 'gp': a Gaussian process (:mod:`.gp`, kernel ``residual_kernel``) learns what
the structure leaves (camera errors, friction, what the moments miss); training chooses
'none' or 'gp' by cross-validation.

The payload [kg] enters the moments linearly and the compliances do not depend on it, so the
model carries the payload physically (:attr:`payload_physical`): fitted on the samples'
payloads (or ``payload`` when they come without one), it predicts at whatever payload it is
asked, ``payload_input`` or not — also from samples at a single payload. A query without a
payload is at the payload trained at (``greybox.trained_payload``: the samples' mean). The
residual GP takes the payload only with ``payload_input``; otherwise it stays as trained at
every payload: what it learns (camera errors, friction, thermal growth) does not grow with the
load. Kept, dropped or scaled with the structure's sag, it changed the error at 5 kg by at most
0.04 mm (benchmarks/payload.py ``--trained 0``): kept, the simplest. From one payload the error
grows with the payload step: the compliances are told apart from the kinematic errors only by
how the moments vary over the region, so the samples' noise in them is multiplied by the step
(realistic world, 20 samples at 0 kg: max 0.15 mm at 0 kg, 0.69 mm at 5 kg in region A; 40
samples: 0.44 mm); and where a moment changes sign in the samples (joint4 in region B), one
compliance per element averages the plant's two of Table 5, which the payload then
extrapolates (without noise, 20 samples: 0.05 mm at 0 kg, 0.22 mm at 5 kg in region B,
0.003 mm in A).

Uncertainty (:meth:`GreyboxPredictor.deflection_std`, :meth:`GreyboxPredictor.prior_std`): the
identified parameters' Gauss-Newton covariance carried to the prediction, with the residual
GP's posterior; and, from samples at a single payload, what they cannot tell — the
compliances took up the nominal masses' error with them, so a payload's change is off by the
parts' moments' relative spread under the inertia prior (config/arm.yaml
``arm.inertia_uncertainty``; :func:`~flexarm_control.learning.gravity_moments.moment_spread`),
element by element. Samples at two payloads tell the two apart: no prior term then.

The masses and geometry used are kept in the metadata (``greybox.arm``) with the identified
compliances: a saved model is self-contained. A model saved before the moments took the
samples' payload without ``payload_input`` (no ``greybox.trained_payload``) identified its
compliances at ``payload`` whatever the samples carried: it cannot carry another one and
predicts at that.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from flexarm_control.learning.gravity_moments import (
    ArmMasses,
    InertiaUncertainty,
    moment_spread,
)
from flexarm_control.learning.predictors.base import PAYLOAD_TOLERANCE, Predictor, restore
from flexarm_control.learning.predictors.gp import KERNELS, GpPredictor
from flexarm_control.learning.predictors.kinematic import (
    KINEMATIC,
    PARAMETERS,
    covariance,
    pose_change,
    pose_jacobian,
    propagated_std,
    read_config,
    solve,
    weighted,
)

# (name, moment: index into gravity_moments.ELEMENTS, dead band?, slot): slots 0-3 turn at
# joint1, joint3, joint4 and the tip frame; 4-6 shift joint3, joint4 and the tip sideways.
TERMS = (('joint1', 0, False, 0), ('guide2', 1, False, 0), ('arm2_deflection', 1, False, 4),
         ('arm2_angle', 1, False, 1), ('joint3', 2, False, 1), ('arm3_deflection', 2, False, 5),
         ('arm3_angle', 2, False, 2), ('joint4', 3, False, 2), ('arm4_deflection', 3, False, 6),
         ('arm4_angle', 3, False, 3), ('joint1_play', 0, True, 0), ('guide2_play', 1, True, 0),
         ('joint3_play', 2, True, 1), ('joint4_play', 3, True, 2))
_MOMENT = np.array([t[1] for t in TERMS])
_PLAY = np.array([t[2] for t in TERMS])
_SLOTS = np.eye(7)[[t[3] for t in TERMS]]       # (terms, 7): term -> slot
RESIDUALS = ('none', 'gp')


def load_arm() -> ArmMasses:
    """The arm as the robot description has it (config/arm.yaml ``arm``: nominal masses)."""
    return ArmMasses.from_description(read_config('arm.yaml')['arm'])


def load_inertia_uncertainty() -> InertiaUncertainty:
    """How far the description's masses may be off (``arm.inertia_uncertainty``)."""
    return InertiaUncertainty.from_dict(read_config('arm.yaml')['arm']['inertia_uncertainty'])


class GreyboxPredictor(Predictor):
    """Compliances × gravity moments through the kinematic chain, plus an optional GP."""

    kind: ClassVar[str] = 'greybox'
    defaults: ClassVar[dict[str, Any]] = {
        'ridge': 1e-8, 'dead_band': 0.5, 'payload': 0.0, 'residual': 'gp',
        'residual_kernel': 'matern32', 'residual_restarts': 0, 'seed': 0,
        'payload_input': False}
    cv_choices: ClassVar[dict[str, list[Any]]] = {'residual': list(RESIDUALS)}
    physical: ClassVar[bool] = True

    def _check_settings(self) -> None:
        s = self.settings
        if s['ridge'] < 0 or s['dead_band'] <= 0 or s['payload'] < 0:
            raise ValueError("greybox needs 'ridge' >= 0, 'dead_band' > 0 and 'payload' >= 0")
        if s['residual'] not in RESIDUALS:
            raise ValueError(f"greybox 'residual' must be one of {list(RESIDUALS)}, "
                             f"got {s['residual']!r}")
        if s['residual_kernel'] not in KERNELS or s['residual_restarts'] < 0:
            raise ValueError(f"greybox 'residual_kernel' must be one of {sorted(KERNELS)} "
                             "and 'residual_restarts' >= 0")

    @property
    def payload_physical(self) -> bool:
        """True but for a model saved before its moments took the samples' payload without
        ``payload_input`` (module docstring)."""
        self._require_fitted()
        return self._carries

    def _features(self, joints: np.ndarray, payload: np.ndarray | float) -> np.ndarray:
        """Per sample (N, terms): the moment of each compliance term [N·m], tanh of it for a
        dead-band term."""
        return self._features_of(self._arm.moments(joints, payload))

    def _features_of(self, moments: np.ndarray) -> np.ndarray:
        """:meth:`_features` of the moments (N, 4) about the elements."""
        moments = moments[:, _MOMENT]
        return np.where(_PLAY, np.tanh(moments / self.settings['dead_band']), moments)

    def _geometry(self) -> dict[str, float]:
        return {'link3': self._arm.link3, 'link4': self._arm.link4, 'offset': self._arm.offset}

    def _structure(self, joints: np.ndarray, features: np.ndarray, kinematic: np.ndarray,
                   compliance: np.ndarray) -> np.ndarray:
        """Deflection (N, 3) of the structure with these parameters."""
        slots = (features * compliance) @ _SLOTS
        return pose_change(self._geometry(), joints, kinematic, slots[:, :4], slots[:, 4:])

    def _parameter_jacobian(self, joints: np.ndarray, features: np.ndarray,
                            kinematic: np.ndarray, compliance: np.ndarray) -> np.ndarray:
        """Derivatives (N, 3, 21) of the structure's deflection by the kinematic errors and
        the compliances: the kinematic errors' own, and each term's through its slot."""
        slots = (features * compliance) @ _SLOTS
        jac = pose_jacobian(self._geometry(), joints, kinematic, slots[:, :4], slots[:, 4:])
        terms = (jac[:, :, KINEMATIC:] @ _SLOTS.T) * features[:, None]
        return np.concatenate([jac[:, :, :KINEMATIC], terms], axis=2)

    def _fit_physical(self, joints: np.ndarray, payload: np.ndarray | None,
                      deflections: np.ndarray) -> None:
        self._arm = load_arm()
        if payload is None:
            payload = np.full(len(joints), self.settings['payload'])
        self._trained_payload, self._carries = float(payload.mean()), True
        features = self._features(joints, payload)
        scale = np.sqrt(np.mean(features ** 2, axis=0))
        scale = np.where(scale > 0, scale, 1.0)     # a term without moment stays at 0
        column = np.concatenate([np.ones(KINEMATIC), 1.0 / scale])   # p -> the parameters

        def residuals(p: np.ndarray) -> np.ndarray:
            return weighted(self._structure(joints, features, p[:KINEMATIC],
                                            p[KINEMATIC:] / scale) - deflections)

        def jacobian(p: np.ndarray) -> np.ndarray:
            return weighted(self._parameter_jacobian(
                joints, features, p[:KINEMATIC], p[KINEMATIC:] / scale) * column)

        ridge = self.settings['ridge']
        p = solve(residuals, jacobian, KINEMATIC + len(TERMS), ridge)
        self._kinematic, self._compliance = p[:KINEMATIC], p[KINEMATIC:] / scale
        self._covariance = column[:, None] * covariance(jacobian(p), residuals(p), ridge) * column
        self._relative_spread = None
        if np.ptp(payload) <= PAYLOAD_TOLERANCE:     # one payload: the masses' prior decides
            moments = self._arm.moments(joints, payload)
            self._relative_spread = np.sqrt(
                np.mean(moment_spread(self._arm, load_inertia_uncertainty(), joints) ** 2,
                        axis=0)
                / np.maximum(np.mean(moments ** 2, axis=0), 1e-12))
        self._residual: GpPredictor | None = None
        if self.settings['residual'] == 'gp':
            left = deflections - self._structure(joints, features, self._kinematic,
                                                 self._compliance)
            self._residual = GpPredictor({
                'kernel': self.settings['residual_kernel'], 'seed': self.settings['seed'],
                'restarts': self.settings['residual_restarts'],
                'payload_input': self.settings['payload_input']}).fit(joints, left, payload)
        self.metadata['greybox'] = {
            'arm': self._arm.as_dict(), 'trained_payload': self._trained_payload,
            'kinematic': dict(zip(PARAMETERS, self._kinematic.tolist())),
            'compliance': {t[0]: float(c) for t, c in zip(TERMS, self._compliance)},
            'relative_moment_spread': (None if self._relative_spread is None
                                       else self._relative_spread.tolist()),
            'residual': None if self._residual is None else self._residual.metadata}

    def _predict_physical(self, joints: np.ndarray, payload: np.ndarray | None) -> np.ndarray:
        y = self._structure(joints, self._features_of(self._moments_at(joints, payload)),
                            self._kinematic, self._compliance)
        return y if self._residual is None else y + self._residual.predict(joints, payload)

    def position_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                     ) -> np.ndarray | float:
        """The residual GP's (:meth:`.GpPredictor.position_std`); 0 without one."""
        if self._residual is None:
            return super().position_std(joints, payload)
        return self._residual.position_std(joints, payload)

    def _moments_at(self, joints: np.ndarray, payload: np.ndarray | None) -> np.ndarray:
        return self._arm.moments(joints, payload if payload is not None and self._carries
                                 else self._trained_payload)

    def deflection_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                       ) -> np.ndarray:
        """The structure's, from its parameters' covariance, and the residual GP's."""
        q, p, single = self._query(joints, payload)
        self._require_fitted()
        std = propagated_std(self._parameter_jacobian(
            q, self._features_of(self._moments_at(q, p)), self._kinematic, self._compliance),
            self._covariance)
        if self._residual is not None:
            std = np.hypot(std, self._residual.deflection_std(q, p))
        return std[0] if single else std

    def prior_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                  ) -> np.ndarray:
        """Trained at one payload, the compliances took up the masses' error with them:
        asked at another, each element's share of the change is off by the parts' moment's
        relative spread there (module docstring). Zeros at the trained payload, or when
        the samples held several."""
        q, p, single = self._query(joints, payload)
        self._require_fitted()
        std = np.zeros((len(q), 3))
        if self._relative_spread is not None:
            trained = self._arm.moments(q, self._trained_payload)
            asked = self._moments_at(q, p)
            before = self._structure(q, self._features_of(trained), self._kinematic,
                                     self._compliance)
            for element, spread in enumerate(self._relative_spread):
                moved = trained.copy()
                moved[:, element] = asked[:, element]
                change = self._structure(q, self._features_of(moved), self._kinematic,
                                         self._compliance) - before
                std = np.hypot(std, spread * change)
        return std[0] if single else std

    def _state(self) -> dict[str, np.ndarray]:
        state = {'kinematic': self._kinematic, 'compliance': self._compliance,
                 'covariance': self._covariance}
        if self._residual is not None:
            state.update({f'residual.{k}': v for k, v in self._residual._state().items()})
        return state

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        meta = self.metadata['greybox']
        self._arm = ArmMasses.from_dict(meta['arm'])
        self._carries = 'trained_payload' in meta or self.settings['payload_input']
        self._trained_payload = meta.get('trained_payload', self.settings['payload'])
        self._kinematic = np.asarray(state['kinematic'], dtype=float).reshape(KINEMATIC)
        self._compliance = np.asarray(state['compliance'], dtype=float).reshape(len(TERMS))
        size = KINEMATIC + len(TERMS)
        self._covariance = np.asarray(state.get('covariance', np.zeros((size, size))),
                                      dtype=float).reshape(size, size)
        spread = meta.get('relative_moment_spread')
        self._relative_spread = None if spread is None else np.asarray(spread, dtype=float)
        self._residual = None if meta['residual'] is None else restore(
            GpPredictor, meta['residual'], {
                'support': state['support'],
                **{k[len('residual.'):]: v for k, v in state.items()
                   if k.startswith('residual.')}})
