"""The arm's physics from its URDF, identified from measurements: where the instrument sees
the target, and how it holds it, given the joints and the payload; to first order,

    point    = R_reg · (target + Σ_k [(ω_k + π_k) × (target − o_k) + β_k × (target − p_k)
                                      + τ_k]) + t_reg
    rotation = R_reg · exp(Σ_k ω_k + β_k + π_k) · R_tip · R_tool

with, for chain joint k of frame R_k, pivot o_k, next pivot p_k (the target after the last
joint) and M_k its gravity moment in its frame (:meth:`.UrdfArm.gravity_moments`):

- **Registration** (R_reg, t_reg): the instrument's frame to the arm's root, the target's
  offset from the tip link (a probe, a camera's hole plate) and, where orientations are
  measured, the target's rotation R_tool: free, as every calibration tool has them; the
  instrument's held (``registration=False``) where it is calibrated already (the graph's
  camera measures the tip in the arm's frame), the target's kept free: the last link's own
  length error is in it.
- **Geometry**: each chain joint's URDF origin moved by a small twist (3 translations, 3
  rotations), with a prior toward the nominal (``Priors``: 1 mm, 1 mrad) — the redundant
  directions (the first joint's origin and the registration, a joint's offset and its
  origin's turn about its axis) stay where the prior holds them.
- **Elasticity** (deflection = J · C · τ_g), three terms per joint, each per axis of the
  joint's frame, none negative (the arm gives way to its load):
  ω_k = R_k (c_k ⊙ M_k), the joint turning at its pivot (the drive's compliance, the
  bearings' tilt); β_k = R_k (b_k ⊙ M_k), the link it carries turning at its far end
  (a beam's end rotation); τ_k = R_k (d_k ⊙ (M_k × ℓ_k)), the far end shifted sideways of the
  link's direction ℓ_k (:attr:`.UrdfArm.link_directions`; a beam's deflection, a slide's
  that does not grow with its stroke).
- **Backlash**: π_k = R_k (a_k ⊙ tanh(M_k / ``dead_band``)), each joint sitting at its play's
  side the moment pushes it to, smoothed over ``dead_band`` [N·m] (static friction).

``terms`` chooses among them: the joints' compliances alone by default (``JOINTS_ONLY``), all
of ``TERMS`` for a long, thin arm whose links bend and whose drives have play (the JAERI arm:
benchmarks/core_on_jaeri.py). All four on the UR10 of ../shared/data (six joints: 12 + 36 +
72 parameters) left 40 rows of series C nothing for the joint-error GP to learn from (its
covariance lost definiteness); its figures (docs/accuracy.md) are the compliances' alone.
The formula above is the first order: the turns are composed exactly, the far end first
(:func:`_turn`); Gauss-Newton's Jacobian is their first order, all it needs to converge.

The elastic priors are ``Priors.compliance`` [rad] of turn (``Priors.shift`` [m] of shift)
at the moment's RMS over the arm's workspace (``WORKSPACE`` configurations drawn within the
joint limits, the payload the samples' mean): the workspace's, not the samples' — a moment the
samples hardly vary (the wrist's, on the UR10 of ../shared/data) let a compliance grow to
mrad/N·m that a pose with more moment turned into a 12 mm miss. The moments are taken on the
rigid pose (sub-mrad on an industrial arm, ~15 mrad on the JAERI arm, whose simulated plant
does the same). A URDF without inertials has no moment to scale: the model is then
registration and geometry (:attr:`gravity` says which), and what gravity does is left to the
residual.

Maximum a posteriori by Gauss-Newton on the analytic Jacobian, the measurement noise (of the
points, and of the rotations where measured) re-estimated from the residuals, over the degrees
of freedom the parameters leave them, until it settles (the first guess, the rigid model's
residual, weighed the priors against a noise 3-50 times too large). :attr:`covariance` is
the Laplace covariance of the parameters, :meth:`pose_std` what it leaves in a prediction,
and :attr:`registration_std` the registration's and the target offset's: large where the
rows cannot tell them apart (poses that all hold the tool the same way leave the offset along
the tool to the instrument's translation). The Jacobian of the target by the joints
(:meth:`joint_jacobians`, Pinocchio's frame Jacobian, in the instrument's
frame) carries a learned joint error to the instrument (:mod:`.joint_error`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.optimize import lsq_linear
from scipy.spatial.transform import Rotation

from flexarm_learning.registration import kabsch
from flexarm_learning.urdf_arm import Chain, UrdfArm, cross

REGISTRATION = 12       # rotation, translation, target offset, target rotation
ITERATIONS = 8          # Gauss-Newton steps at most
NOISE_FLOOR = 1e-6      # [m or rad] the noise estimate's floor (an exact fit: simulated data)
PASSES = 40             # noise re-estimates at most: the fit is weighed by its own residual
                        # (an exact fit, simulated data, takes ~25 to reach the floor)
NOISE_SETTLED = 0.05    # a noise estimate within 5 % of the last ends them
CONVERGED = 1e-8        # [m or rad] a step this small ends the iterations
WORKSPACE = 200         # configurations whose moments scale the elastic priors
IDLE = 1e-9             # a moment this small against the largest drives nothing
ANGLE_LENGTH = 1.0      # [m] a turn's residual weighs as a point's over this lever
HALVINGS = 12           # a step is halved at most this often until the cost drops
TERMS = ('compliances', 'bending', 'shift', 'play')   # the elastic terms, 3 per joint each
STATE = ('rotation', 'translation', 'offset', 'tool', 'twists', *TERMS, 'covariance', 'fixed',
         'noises')
JOINTS_ONLY = ('compliances',)   # what an industrial arm's few rows can tell (module docstring)


@dataclass(frozen=True)
class Priors:
    """Standard deviations of the prior toward the nominal description."""

    translation: float = 1e-3    # [m] a joint origin's shift
    rotation: float = 1e-3       # [rad] a joint origin's turn
    compliance: float = 1e-3     # [rad] a compliant turn at the RMS moment
    shift: float = 1e-3          # [m] a link's sideways shift at the RMS moment
    play: float = 1e-3           # [rad] a joint's half play
    dead_band: float = 0.5       # [N·m] the moment over which a joint crosses its play


class ElastostaticModel:
    """Registration, geometry, elasticity and backlash of one arm, identified from measured
    points (and rotations)."""

    def __init__(self, arm: UrdfArm, priors: Priors | None = None, compliance: bool = True,
                 geometry: bool = True, registration: bool = True,
                 terms: tuple[str, ...] = JOINTS_ONLY) -> None:
        self.arm, self.priors = arm, priors or Priors()
        self.geometry, self.registration = geometry, registration
        self.compliance = compliance and arm.has_masses
        unknown = set(terms) - set(TERMS)
        if unknown or 'compliances' not in terms:
            raise ValueError(f'elastic terms are {TERMS}, the compliances among them; '
                             f'got {terms}')
        self.terms = tuple(t for t in TERMS if t in terms) if self.compliance else ()
        self.gravity = ('URDF inertials' if self.compliance else
                        'none (the URDF has no inertials)' if compliance and not arm.has_masses
                        else 'not modelled')
        n = arm.dof
        self.rotation, self.translation = np.eye(3), np.zeros(3)
        self.offset, self.tool = np.zeros(3), np.eye(3)
        self.twists = np.zeros((n, 6))
        self._idle = np.zeros(0, bool)
        self._twisted: tuple[bytes, pin.Model, pin.Data] | None = None
        for name in TERMS:
            setattr(self, name, np.zeros((n, 3)))

    # -- parameters: [registration 12 | geometry 6n | each term chosen, 3n] ---------------
    @property
    def size(self) -> int:
        n = self.arm.dof
        return REGISTRATION + 6 * n * self.geometry + 3 * n * len(self.terms)

    def fit(self, joints: np.ndarray, points: np.ndarray, payload: np.ndarray | None = None,
            start: ElastostaticModel | None = None, rotations: np.ndarray | None = None,
            ) -> ElastostaticModel:
        """Identify the parameters from rows of joints (N, n) and measured points (N, 3) [m],
        and the target's measured rotations (N, 3, 3) where the instrument gives them; from
        ``start``'s parameters and noise (a model of the same kind fitted on similar rows:
        cross-validation's folds) instead of Kabsch's registration (or the one held) and the
        nominal."""
        joints, points = np.asarray(joints, float), np.asarray(points, float)
        payload = np.zeros(len(joints)) if payload is None else np.asarray(payload, float)
        if start is not None:
            for name in ('offset', 'twists', 'rotation', 'translation', 'tool', *TERMS):
                setattr(self, name, getattr(start, name).copy())
        elif self.registration:
            rigid = self.arm.chain_at(joints, self.offset).target
            self.rotation, self.translation = kabsch(rigid, points)
        self._measured_rotations = rotations is not None
        scale, self._idle = self._workspace_scale(float(payload.mean()))
        prior = np.concatenate([np.zeros(REGISTRATION), self._geometry_prior(), scale])
        floor = np.where(np.arange(self.size) < self.size - len(scale), -np.inf, 0.0)
        fixed = self._fixed()
        noise = None if start is None else start.noises
        for _ in range(PASSES):
            for _ in range(ITERATIONS):
                residual, jac = self._linearise(joints, payload, points, rotations)
                jac[:, fixed] = 0.0
                if noise is None:
                    noise = self._noise_of(residual)
                step = self._step(residual, jac, noise, prior, floor)
                step = self._descend(step, residual, noise, prior,
                                     (joints, payload, points, rotations))
                if np.max(np.abs(step)) < CONVERGED:
                    break
            residual, jac = self._linearise(joints, payload, points, rotations)
            jac[:, fixed] = 0.0
            weighted = jac / self._row_noise(noise, len(joints))[:, None]
            self.covariance = np.linalg.pinv(weighted.T @ weighted + np.diag(prior ** 2),
                                             hermitian=True)
            settled = self._noise_of(residual, np.einsum('ip,pq,iq->i', weighted,
                                                         self.covariance, weighted))
            done = np.all(np.abs(settled - noise) <= NOISE_SETTLED * noise)
            noise = settled
            if done:
                break
        self.noises = noise
        self.noise = float(noise[0])
        self.rotation_noise = float(noise[1]) if rotations is not None else None
        self.fixed = fixed
        self.registration_std = np.sqrt(np.abs(np.diag(self.covariance)[:9]))
        return self

    def _fixed(self) -> np.ndarray:
        """Mask of the parameters held: the instrument's registration where it is known
        (the target's offset stays free: the last link's own length error is in it), the
        target's rotation where no rotation is measured, the terms nothing drives."""
        fixed = np.zeros(self.size, bool)
        fixed[self.size - len(self._idle):] = self._idle
        if not self.registration:
            fixed[:6] = True
        if not self._measured_rotations:
            fixed[9:REGISTRATION] = True
        return fixed

    def _geometry_prior(self) -> np.ndarray:
        p = self.priors
        return np.tile([1 / p.translation] * 3 + [1 / p.rotation] * 3,
                       self.arm.dof * self.geometry)

    def _workspace_scale(self, payload: float) -> tuple[np.ndarray, np.ndarray]:
        """The elastic terms' prior weights (4 × 3n): each term's effect at the RMS over
        ``WORKSPACE`` seeded configurations within the joint limits (a continuous joint over
        one turn) of what drives it, over its prior; and which terms nothing drives there
        (a moment about an axis no load reaches: held at 0, as no prior would hold them)."""
        if not self.terms:
            return np.zeros(0), np.zeros(0, bool)
        rng = np.random.default_rng(0)
        low = np.where(np.isfinite(self.arm.lower), self.arm.lower, -np.pi)
        high = np.where(np.isfinite(self.arm.upper), self.arm.upper, np.pi)
        rows = rng.uniform(low, high, (WORKSPACE, self.arm.dof))
        chain = self.arm.chain_at(rows, self.offset)
        moments = self.arm.gravity_moments(chain, payload)
        rms = np.sqrt(np.mean(moments ** 2, axis=0)).ravel()
        lateral = cross(moments, self.arm.link_directions)
        lateral_rms = np.sqrt(np.mean(lateral ** 2, axis=0)).ravel()
        p, floor = self.priors, IDLE * rms.max()
        weights = {'compliances': (rms / p.compliance, rms <= floor),
                   'bending': (rms / p.compliance, rms <= floor),
                   'shift': (lateral_rms / p.shift, lateral_rms <= floor),
                   'play': (np.full(rms.size, 1 / p.play), rms <= floor)}
        return (np.concatenate([weights[t][0] for t in self.terms]),
                np.concatenate([weights[t][1] for t in self.terms]))

    def _noise_of(self, residual: np.ndarray, leverage: np.ndarray | None = None,
                  ) -> np.ndarray:
        """The noise of the point rows [m] and of the rotation rows [rad] (0 where none are
        measured), above ``NOISE_FLOOR``: one figure, the residual's RMS with a turn counted
        over ``ANGLE_LENGTH``, over the degrees of freedom the parameters leave the rows
        (``leverage``: each row's diagonal of the hat matrix). A fit with as many parameters
        as an arm has (~100 for six joints) leaves 40 rows a residual far below the
        instrument's noise, and a noise taken from it weakens the priors until the fit
        follows the noise; two figures apart let a fit settle on points alone, the turns'
        noise taken as large as what it left of them (20 samples of the JAERI arm at 5 kg:
        1 mrad)."""
        width = 6 if self._measured_rotations else 3
        rows = residual.reshape(-1, width) ** 2
        rows[:, 3:] *= ANGLE_LENGTH ** 2
        free = np.ones_like(rows) if leverage is None else 1.0 - leverage.reshape(-1, width)
        noise = max(np.sqrt(rows.sum() / max(free.sum(), 1.0)), NOISE_FLOOR)
        return np.array([noise, noise / ANGLE_LENGTH if self._measured_rotations else 0.0])

    def _row_noise(self, noise: np.ndarray, rows: int) -> np.ndarray:
        per = np.repeat(noise, 3) if self._measured_rotations else np.repeat(noise[:1], 3)
        return np.tile(per, rows)

    def _parameters(self) -> np.ndarray:
        return np.concatenate([np.zeros(6), self.offset, np.zeros(3),
                               self.twists.ravel() if self.geometry else [],
                               *[getattr(self, t).ravel() for t in self.terms]])

    def _step(self, residual: np.ndarray, jac: np.ndarray, noise: np.ndarray,
              prior: np.ndarray, floor: np.ndarray) -> np.ndarray:
        """The Gauss-Newton step of the MAP problem: data weighted by the noise, each
        parameter drawn to 0 by its prior (registration: none), none below its ``floor``."""
        x = self._parameters()
        row_noise = self._row_noise(noise, len(residual) // (6 if self._measured_rotations
                                                             else 3))
        a = np.concatenate([jac / row_noise[:, None], np.diag(prior)])
        b = np.concatenate([-residual / row_noise, -prior * x])
        active = np.any(jac != 0, axis=0)
        step = np.zeros(self.size)
        lower = np.minimum(floor[active] - x[active], 0.0)
        step[active] = lsq_linear(a[:, active], b, bounds=(lower, np.inf)).x
        return step

    def _apply(self, step: np.ndarray) -> None:
        n = self.arm.dof
        self.rotation = pin.exp3(step[:3]) @ self.rotation
        self.translation = self.translation + step[3:6]
        self.offset = self.offset + step[6:9]
        self.tool = self.tool @ pin.exp3(step[9:12])
        k = REGISTRATION
        if self.geometry:
            self.twists = self.twists + step[k:k + 6 * n].reshape(n, 6)
            k += 6 * n
        for name in self.terms:
            setattr(self, name, getattr(self, name) + step[k:k + 3 * n].reshape(n, 3))
            k += 3 * n

    def _model(self) -> tuple[pin.Model, pin.Data] | None:
        """The URDF's model with each chain joint's origin moved by its twist, and its data
        (None: the URDF's own); kept while the twists stay (a copy and its data cost a
        compensation step a fifth of its budget)."""
        if not self.geometry or not np.any(self.twists):
            return None
        key = self.twists.tobytes()
        if self._twisted is None or self._twisted[0] != key:
            model = self.arm.model.copy()
            for k, j in enumerate(self.arm.chain):
                model.jointPlacements[j] = model.jointPlacements[j] * pin.exp6(
                    pin.Motion(self.twists[k, :3], self.twists[k, 3:]))
            self._twisted = (key, model, model.createData())
        return self._twisted[1:]

    def _drives(self, moments: np.ndarray) -> dict[str, np.ndarray]:
        """What drives each elastic term, (N, n, 3) each in the joint's frame: the moment
        (compliance, bending), its cross product with the link's direction (shift), its
        tanh over the dead band (play)."""
        return {'compliances': moments, 'bending': moments,
                'shift': cross(moments, self.arm.link_directions),
                'play': np.tanh(moments / self.priors.dead_band)}

    def _evaluate(self, joints: np.ndarray, payload: np.ndarray, jacobian: bool,
                  moments: np.ndarray | None = None,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Points (N, 3), rotations (N, 3, 3) in the instrument's frame and, with
        ``jacobian``, their derivatives by the parameters (N, 6, size): point rows, then the
        rotation's (a small turn on the left, in the instrument's frame). ``moments``
        (N, n, 3) replace the gravity moments of the payload.

        The chain is bent joint by joint from the far end (:class:`_Bend`), each parameter's
        derivative taken where it acts and carried by every turn nearer the root: the
        turns split between a joint's pivot and its link's far end differ only to second
        order, which a first-order Jacobian cannot see (20 mrad of sag at the JAERI arm's
        wrist left 0.04 mm that Gauss-Newton never took up).
        """
        chain = self.arm.chain_at(joints, self.offset, self._model(), jacobian=False)
        rows, n = len(chain.target), self.arm.dof
        along: dict[str, np.ndarray] = {}          # (N, n, axis, 3) per term, for derivatives
        vectors = dict.fromkeys(TERMS, np.zeros((rows, n, 3)))
        if self.terms:
            if moments is None:
                moments = self.arm.gravity_moments(chain, payload)
            drives = self._drives(moments)
            turned = np.einsum('rkxa,trka->trkx', chain.frames, np.array(
                [drives[name] * getattr(self, name) for name in self.terms]))
            vectors.update(zip(self.terms, turned))
            if jacobian:
                axes = np.swapaxes(chain.frames, -1, -2)     # (N, n, axis, 3) in the root
                along = {name: axes * drives[name][..., None] for name in self.terms}
        ends, roots = vectors['bending'], vectors['compliances'] + vectors['play']
        turns = Rotation.from_rotvec(np.concatenate([ends, roots], 1).reshape(
            -1, 3)).as_matrix().reshape(rows, 2, n, 3, 3) if self.terms else None
        if not jacobian:
            points, tips = (_bent(chain, turns, vectors['shift']) if self.terms
                            else (chain.target, chain.tip_rotation))
            return (points @ self.rotation.T + self.translation,
                    self.rotation @ tips @ self.tool, None)
        bend = _Bend(chain)
        for k in reversed(range(n)):          # the far end first: a joint's turn carries it
            if self.terms:
                bend.turn(turns[:, 0, k], ends[:, k], chain.next_pivots[:, k],
                          _at(along, k, 'bending'))
                bend.shift(vectors['shift'][:, k], _at(along, k, 'shift').get('shift'))
                bend.turn(turns[:, 1, k], roots[:, k], chain.pivots[:, k],
                          _at(along, k, 'compliances', 'play'))
            if self.geometry:
                bend.twist(np.swapaxes(chain.placed[:, k], -1, -2), chain.pivots[:, k])
        point = bend.points @ self.rotation.T + self.translation
        rotation = self.rotation @ bend.rotations @ self.tool
        d = np.zeros((rows, 6, self.size))
        d[:, :3, :3] = -np.array([pin.skew(p - self.translation) for p in point])
        d[:, 3:, :3] = np.eye(3)
        d[:, :3, 3:6] = np.eye(3)
        d[:, :, 6:9] = bend.offset.transpose(0, 2, 1)
        d[:, 3:, 9:12] = rotation
        k = REGISTRATION
        blocks = ([bend.columns('twist')] if self.geometry else []) + [
            bend.columns(name) for name in self.terms]
        for block in blocks:
            width = block.shape[1]
            d[:, :, k:k + width] = block.transpose(0, 2, 1)
            k += width
        d[:, :3, 6:] = self.rotation @ d[:, :3, 6:]
        d[:, 3:, 6:9] = self.rotation @ d[:, 3:, 6:9]
        d[:, 3:, REGISTRATION:] = self.rotation @ d[:, 3:, REGISTRATION:]
        return point, rotation, d

    def _linearise(self, joints: np.ndarray, payload: np.ndarray, points: np.ndarray,
                   rotations: np.ndarray | None, jacobian: bool = True,
                   ) -> tuple[np.ndarray, np.ndarray | None]:
        point, rotation, d = self._evaluate(joints, payload, jacobian)
        if rotations is None:
            return (point - points).ravel(), None if d is None else d[:, :3].reshape(
                -1, self.size)
        turn = np.array([pin.log3(p @ m.T) for p, m in zip(rotation, rotations)])
        return (np.concatenate([point - points, turn], axis=1).ravel(),
                None if d is None else d.reshape(-1, self.size))

    def _objective(self, residual: np.ndarray, noise: np.ndarray, prior: np.ndarray,
                   ) -> float:
        """The MAP problem's cost: the weighted residual's and the priors' squares."""
        weighted = residual / self._row_noise(noise, len(residual) // (
            6 if self._measured_rotations else 3))
        return float(weighted @ weighted + np.sum((prior * self._parameters()) ** 2))

    def _descend(self, step: np.ndarray, residual: np.ndarray, noise: np.ndarray,
                 prior: np.ndarray, rows: tuple) -> np.ndarray:
        """Take ``step``, halved until the cost on the ``rows`` (joints, payload, points,
        rotations) is no more than before it (``residual``): the bent chain is far from
        linear where the priors are weak (a 3 mrad compliance prior on the JAERI arm sent
        the plain Gauss-Newton steps to 1e14 m).
        Returns the step taken (0 if no halving helped)."""
        before = self._objective(residual, noise, prior)
        saved = {name: np.copy(getattr(self, name)) for name in STATE[:-3]}
        for _ in range(HALVINGS):
            self._apply(step)
            if self._objective(self._linearise(*rows, False)[0], noise, prior) <= before:
                return step
            for name, value in saved.items():
                setattr(self, name, np.copy(value))
            step = step / 2
        return np.zeros_like(step)

    def predict(self, joints: np.ndarray, payload: np.ndarray | None = None) -> np.ndarray:
        """(N, 3) [m]: where the instrument would see the target."""
        return self.predict_pose(joints, payload)[0]

    def predict_pose(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Points (N, 3) [m] and the target's rotations (N, 3, 3) in the instrument's frame."""
        joints = np.atleast_2d(np.asarray(joints, float))
        point, rotation, _ = self._evaluate(joints, self._payload(joints, payload), False)
        return point, rotation

    def pose_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                 ) -> np.ndarray:
        """(N, 6): the standard deviation the parameters' covariance leaves in each point
        coordinate [m] and each small turn of the rotation [rad]."""
        joints = np.atleast_2d(np.asarray(joints, float))
        _, _, d = self._evaluate(joints, self._payload(joints, payload), True)
        d[:, :, self.fixed] = 0.0
        return np.sqrt(np.einsum('rip,pq,riq->ri', d, self.covariance, d))

    def register_target_rotation(self, joints: np.ndarray, rotations: np.ndarray,
                                 payload: np.ndarray | None = None) -> None:
        """Set the target's rotation on the tip link (``tool``) to the one that best meets
        measured rotations (N, 3, 3) with everything else as fitted: the chordal mean of
        what each row leaves, by SVD."""
        self.tool = np.eye(3)
        _, predicted = self.predict_pose(joints, payload)
        left = np.einsum('rxy,rxz->yz', predicted, rotations)       # Σ Rpredᵀ Rmeasured
        u, _, vt = np.linalg.svd(left)
        self.tool = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt

    def state(self) -> dict[str, np.ndarray]:
        """The fitted parameters, their covariance, the noise and which parameters were
        held: all :meth:`restored` needs besides the arm and the choices."""
        return {name: np.asarray(getattr(self, name)) for name in STATE}

    def restored(self, state: dict[str, np.ndarray]) -> ElastostaticModel:
        """This model (of the arm and choices it was fitted with) with a :meth:`state`."""
        for name in STATE:
            value = np.asarray(state[name])
            setattr(self, name, value.astype(bool) if name == 'fixed' else value.astype(float))
        self.noise = float(self.noises[0])
        self._measured_rotations = self.noises[1] > 0
        self.rotation_noise = float(self.noises[1]) if self._measured_rotations else None
        if self.covariance.shape != (self.size, self.size) or self.fixed.shape != (self.size,):
            raise ValueError(f'a state of {len(self.fixed)} parameters for a model of '
                             f'{self.size}')
        return self

    def load_effects(self, joints: np.ndarray, trained: float, asked: float) -> np.ndarray:
        """(n, N, 6): per joint, how the target moves [m] and turns [rad] when that joint's
        gravity moments alone go from the payload ``trained`` at to the one ``asked`` [kg],
        the others held: what an error in that joint's moments (the masses' it was fitted
        with) carries to another payload."""
        joints = np.atleast_2d(np.asarray(joints, float))
        chain = self.arm.chain_at(joints, self.offset, self._model(), jacobian=False)
        before = self.arm.gravity_moments(chain, trained)
        after = self.arm.gravity_moments(chain, asked)
        zero = np.zeros(len(joints))
        point, rotation, _ = self._evaluate(joints, zero, False, before)
        effects = np.zeros((self.arm.dof, len(joints), 6))
        for k in range(self.arm.dof if self.terms else 0):
            moved = before.copy()
            moved[:, k] = after[:, k]
            p, r, _ = self._evaluate(joints, zero, False, moved)
            effects[k, :, :3] = p - point
            effects[k, :, 3:] = [pin.log3(a @ b.T) for a, b in zip(r, rotation)]
        return effects

    @staticmethod
    def _payload(joints: np.ndarray, payload: np.ndarray | float | None) -> np.ndarray:
        return np.broadcast_to(np.asarray(0.0 if payload is None else payload, float),
                               (len(joints),))

    def joint_jacobians(self, joints: np.ndarray) -> np.ndarray:
        """(N, 3, n): the point's derivative by each joint, in the instrument's frame."""
        chain = self.arm.chain_at(joints, self.offset, self._model())
        return self.rotation @ chain.jacobian


def _bent(chain: Chain, turns: np.ndarray, shifts: np.ndarray,
          ) -> tuple[np.ndarray, np.ndarray]:
    """The target's points (N, 3) and rotations (N, 3, 3) bent as :class:`_Bend` bends them,
    each joint's three steps (a turn about its link's far end, the shift, a turn about its
    pivot) made one rigid motion for all joints at once: a prediction needs no derivative,
    and a compensation step's budget no step of numpy it can save (half of it went to
    bending the chain one step at a time). ``turns`` (N, 2, n, 3, 3): the far ends', then the
    pivots'."""
    ends, roots = turns[:, 0], turns[:, 1]
    centres = np.stack([chain.next_pivots, chain.pivots], 1)              # (N, 2, n, 3)
    moved = centres - (turns @ centres[..., None])[..., 0]                # x -> R x + moved
    rotations = roots @ ends                                              # (N, n, 3, 3)
    offsets = (roots @ (moved[:, 0] + shifts)[..., None])[..., 0] + moved[:, 1]
    # joint 0's motion last: x -> R0 (R1 (... x + t1) ...) + t0 = P_n x + sum P_k t_k
    prefix = [np.broadcast_to(np.eye(3), rotations[:, 0].shape)]
    for k in range(rotations.shape[1]):
        prefix.append(prefix[-1] @ rotations[:, k])
    carried = np.stack(prefix[:-1], 1)                                    # P_k, (N, n, 3, 3)
    points = ((prefix[-1] @ chain.target[..., None])[..., 0]
              + (carried @ offsets[..., None])[..., 0].sum(axis=1))
    return points, prefix[-1] @ chain.tip_rotation


def _at(along: dict[str, np.ndarray], k: int, *names: str) -> dict[str, np.ndarray]:
    """Joint k's derivative directions of the terms ``names`` that are fitted."""
    return {name: along[name][:, k] for name in names if name in along}


class _Bend:
    """The rigid chain's target bent by turns about pivots and shifts, from the far end to the
    root, with each parameter's derivative columns (N, 6) [point, turn]: taken where the
    parameter acts and turned by every turn after it (nearer the root). A prediction, which
    needs no derivative, bends the chain in one go (:func:`_bent`)."""

    def __init__(self, chain: Chain) -> None:
        self.points, self.rotations = chain.target.copy(), chain.tip_rotation.copy()
        self._columns: dict[str, list[np.ndarray]] = {}
        self.offset = np.zeros((len(self.points), 3, 6))   # the target's offset: at the tip
        self.offset[:, :, :3] = np.swapaxes(chain.tip_rotation, 1, 2)
        self._carried = [self.offset]

    def turn(self, turns: np.ndarray, vectors: np.ndarray, pivots: np.ndarray,
             parts: dict[str, np.ndarray]) -> None:
        """Turn by rotations (N, 3, 3) of rotation vectors (N, 3) about pivots (N, 3);
        ``parts``: per term its derivative directions (N, axis, 3) in the root frame, turned
        by the left Jacobian of the turn. Nothing to do for no turn and no derivative."""
        if not parts and not vectors.any():
            return
        self.points = pivots + (turns @ (self.points - pivots)[..., None])[..., 0]
        self.rotations = turns @ self.rotations
        for carried in self._carried:
            carried[..., :3] = np.einsum('rxy,ray->rax', turns, carried[..., :3])
            carried[..., 3:] = np.einsum('rxy,ray->rax', turns, carried[..., 3:])
        left = np.array([pin.Jexp3(v).T for v in vectors])          # (N, 3, 3)
        lever = self.points - pivots
        for name, directions in parts.items():
            turned = np.einsum('rxy,ray->rax', left, directions)
            self._add(name, np.concatenate([cross(turned, lever[:, None]), turned], -1))

    def shift(self, vectors: np.ndarray, directions: np.ndarray | None) -> None:
        """Shift by vectors (N, 3); ``directions`` (N, axis, 3): the shift term's."""
        self.points = self.points + vectors
        if directions is not None:
            self._add('shift', np.concatenate([directions, np.zeros_like(directions)], -1))

    def twist(self, placed: np.ndarray, pivots: np.ndarray) -> None:
        """A joint origin's twist (its frame's axes (N, axis, 3)) moves what it carries as
        bent so far: 3 translations, then 3 turns about the pivot."""
        lever = self.points - pivots
        self._add('twist', np.concatenate([
            np.concatenate([placed, np.zeros_like(placed)], -1),
            np.concatenate([cross(placed, lever[:, None]), placed], -1)], axis=1))

    def _add(self, name: str, columns: np.ndarray) -> None:
        self._columns.setdefault(name, []).append(columns)
        self._carried.append(columns)

    def columns(self, name: str) -> np.ndarray:
        """(N, width, 6): the term's columns in the chain's order (they were taken from the
        far end)."""
        return np.concatenate(self._columns[name][::-1], axis=1)
