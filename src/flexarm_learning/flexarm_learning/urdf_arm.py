"""A serial arm read from its URDF through Pinocchio: the chain from the root to a tip link.

Pinocchio parses the URDF and does the rigid-body work — forward kinematics, the tip's frame
Jacobian, the joints' gravity wrenches (RNEA at rest) — so any serial arm is one file away.
What is ours is which joints count (the actuated ones on the path from the root to the tip,
in chain order: a gripper's fingers or a second branch stay at their neutral position) and
batching over rows of measurements.

Units are the URDF's (rad, m, kg); ``payload`` is a point mass [kg] at the measured target,
which the caller passes as an offset from the tip link.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

GRAVITY = np.array([0.0, 0.0, -9.80665])   # [m/s²] standard, in the root frame (REP 103: z up)
MASSLESS = 1e-6                         # [kg] a chain lighter than this has no inertials


class DescriptionError(ValueError):
    """The URDF cannot serve: unreadable, or without the tip link asked for."""


@dataclass(frozen=True)
class ChainState:
    """One row's rigid chain: the target point, the tip's rotation, the frames before each
    joint's motion (``placed``: where a geometric offset acts), the joint frames and the
    target's Jacobian by the chain's joints."""

    target: np.ndarray        # (3,) [m]
    tip_rotation: np.ndarray  # (3, 3)
    placed: list[pin.SE3]     # per chain joint: parent joint frame × its URDF origin
    joints: list[pin.SE3]     # per chain joint: after its motion
    jacobian: np.ndarray      # (3, n) d target / d q [m/rad or m/m]


class UrdfArm:
    """The chain of ``tip`` in the URDF: its joints, limits, masses and rigid kinematics."""

    def __init__(self, model: pin.Model, tip: str, source: str = 'URDF') -> None:
        links = sorted({f.name for f in model.frames if f.type == pin.FrameType.BODY})
        if tip not in links:
            raise DescriptionError(f'tip link {tip!r} is not in {source}; its links: '
                                   + ', '.join(links))
        self.model, self.tip = model, tip
        model.gravity.linear = GRAVITY
        self._data = model.createData()
        self._frame = model.getFrameId(tip, pin.FrameType.BODY)
        chain, joint = [], model.frames[self._frame].parentJoint
        while joint > 0:
            chain.append(joint)
            joint = model.parents[joint]
        self.chain = [j for j in reversed(chain) if model.joints[j].nv == 1]
        if not self.chain:
            raise DescriptionError(f'no actuated joint between the root of {source} and {tip!r}')
        self.joint_names = tuple(model.names[j] for j in self.chain)
        self._q_index = np.array([model.joints[j].idx_q for j in self.chain])
        self._v_index = np.array([model.joints[j].idx_v for j in self.chain])
        self._continuous = np.array([model.joints[j].nq == 2 for j in self.chain])
        self.lower = np.where(self._continuous, -np.inf,
                              model.lowerPositionLimit[self._q_index])
        self.upper = np.where(self._continuous, np.inf, model.upperPositionLimit[self._q_index])
        self.prismatic = np.array([model.joints[j].shortname().startswith('JointModelP')
                                   for j in self.chain])
        subtree = {int(k) for j in self.chain for k in model.subtrees[j]}
        self.mass = float(sum(model.inertias[k].mass for k in subtree))

    @classmethod
    def from_file(cls, path: str | Path, tip: str) -> UrdfArm:
        path = Path(path)
        try:
            xml = path.read_text(encoding='utf-8')
        except OSError as e:
            raise DescriptionError(f'cannot read the URDF {path}: {e.strerror}') from None
        except UnicodeDecodeError:
            raise DescriptionError(f'the URDF {path} is not a UTF-8 text file') from None
        return cls.from_xml(xml, tip, source=str(path))

    @classmethod
    def from_xml(cls, xml: str, tip: str, source: str = 'the URDF') -> UrdfArm:
        try:
            model = pin.buildModelFromXML(xml)
        except (RuntimeError, ValueError) as e:
            raise DescriptionError(f'{source} is no URDF Pinocchio can read: {e}') from None
        return cls(model, tip, source)

    @property
    def dof(self) -> int:
        return len(self.chain)

    @property
    def has_masses(self) -> bool:
        """Whether the URDF gives the chain's links inertials (many published ones do not)."""
        return self.mass > MASSLESS

    def configuration(self, joints: np.ndarray) -> np.ndarray:
        """Pinocchio's configuration vector of one row of chain joint positions."""
        q = pin.neutral(self.model)
        for k, value in enumerate(joints):
            i = self._q_index[k]
            if self._continuous[k]:
                q[i], q[i + 1] = np.cos(value), np.sin(value)
            else:
                q[i] = value
        return q

    def state(self, joints: np.ndarray, offset: np.ndarray,
              model: pin.Model | None = None) -> ChainState:
        """The chain at one row of joint positions, the target ``offset`` [m] from the tip
        link in its frame; ``model`` a copy of this one with other joint origins."""
        model = model or self.model
        data = self._data if model is self.model else model.createData()
        q = self.configuration(joints)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        tip = data.oMf[self._frame]
        arm = tip.rotation @ offset
        target = tip.translation + arm
        full = pin.getFrameJacobian(model, data, self._frame, pin.LOCAL_WORLD_ALIGNED)
        jac = full[:3] - pin.skew(arm) @ full[3:]
        placed = [data.oMi[model.parents[j]] * model.jointPlacements[j] for j in self.chain]
        return ChainState(target, tip.rotation.copy(), placed,
                          [data.oMi[j].copy() for j in self.chain], jac[:, self._v_index])

    def gravity_moments(self, joints: np.ndarray, payload: float = 0.0,
                        offset: np.ndarray | None = None) -> np.ndarray:
        """(n, 3) [N·m]: the moment gravity puts on what each chain joint carries (its
        subtree's links and the payload at the target) about the joint's origin on its
        parent (the URDF origin: a revolute joint's centre, a prismatic joint's guide, where
        the slide bends), in the joint's frame."""
        q = self.configuration(joints)
        model, data = self.model, self._data
        pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv))
        pin.framesForwardKinematics(model, data, q)          # RNEA leaves oMi as it was
        target = data.oMf[self._frame].act(np.zeros(3) if offset is None else offset)
        out = np.empty((self.dof, 3))
        for k, j in enumerate(self.chain):
            frame = data.oMi[j]
            pivot = (data.oMi[model.parents[j]] * model.jointPlacements[j]).translation
            carried = frame.rotation @ data.f[j].linear       # what the parent holds up
            moment = (frame.rotation @ data.f[j].angular
                      + np.cross(frame.translation - pivot, carried))
            load = np.cross(target - pivot, payload * GRAVITY)
            out[k] = frame.rotation.T @ (load - moment)
        return out

