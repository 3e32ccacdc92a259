"""A serial arm read from its URDF through Pinocchio: the chain from the root to a tip link.

Pinocchio parses the URDF and does the rigid-body work — forward kinematics, the tip's frame
Jacobian, the bodies' centres of mass — so any serial arm is one file away. The gravity
moments are then one vectorised sum over the rows (Σ over a joint's subtree of
(centre − pivot) × m·g): RNEA's per-joint wrenches, read out joint by joint in Python, cost
150 µs a row, several times the compensator's budget for a whole plan.
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
SAME_POINT = 1e-6                       # [m] pivots closer than this coincide
LEVI_CIVITA = np.zeros((3, 3, 3))
LEVI_CIVITA[[0, 1, 2], [1, 2, 0], [2, 0, 1]], LEVI_CIVITA[[0, 1, 2], [2, 0, 1], [1, 2, 0]] = 1, -1


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b over the last axis, broadcast: one einsum (numpy's cross moves axes about and
    cost a compensation step a tenth of its budget on a handful of rows)."""
    return np.einsum('ijk,...j,...k->...i', LEVI_CIVITA, a, b)


class DescriptionError(ValueError):
    """The URDF cannot serve: unreadable, or without the tip link asked for."""


@dataclass(frozen=True)
class Chain:
    """Rows of the rigid chain: the target point, the tip's rotation, each joint's pivot (its
    URDF origin on the parent, before its motion: where a geometric offset and a compliant
    turn act) and frame (after its motion), the next pivot down the chain (the target after
    the last joint: where a link's bending turns it), the target's Jacobian by the chain's
    joints, and what gravity needs: each joint's subtree's mass-weighted centre."""

    target: np.ndarray            # (N, 3) [m]
    tip_rotation: np.ndarray      # (N, 3, 3)
    pivots: np.ndarray            # (N, n, 3) [m]
    placed: np.ndarray            # (N, n, 3, 3): the pivot's rotation, before the motion
    frames: np.ndarray            # (N, n, 3, 3): the joint's rotation, after the motion
    next_pivots: np.ndarray       # (N, n, 3) [m]
    jacobian: np.ndarray          # (N, 3, n) d target / d q [m/rad or m/m]
    carried: np.ndarray           # (N, n, 3) [kg·m] Σ mass × centre over each subtree
    centres: np.ndarray           # (N, bodies, 3) [m] each body's centre of mass


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
        self._neutral = pin.neutral(model)
        self._plain, self._turning = np.flatnonzero(~self._continuous), np.flatnonzero(
            self._continuous)
        self._plain_q, self._turning_q = self._q_index[self._plain], self._q_index[self._turning]
        self._parents = [model.parents[j] for j in self.chain]
        self._levers = np.array([model.inertias[j].lever for j in range(model.njoints)])
        self._tip_body = model.frames[self._frame].parentJoint
        self._placed_in: tuple[pin.Model, np.ndarray, np.ndarray] | None = None
        masses = np.array([model.inertias[j].mass for j in range(model.njoints)])
        self._masses = masses
        self._subtree_masses = np.zeros((self.dof, model.njoints))   # (n, joints) [kg]
        for k, j in enumerate(self.chain):
            subtree = list(model.subtrees[j])
            self._subtree_masses[k, subtree] = masses[subtree]
        self._carried_mass = self._subtree_masses.sum(axis=1)
        self.mass = float(self._carried_mass[0])
        self.link_directions = self._link_directions()

    def _link_directions(self) -> np.ndarray:
        """(n, 3) unit vectors in each joint's frame along what it carries to the next pivot
        (the tip link after the last joint), a prismatic joint's along its slide: the beam a
        moment bends sideways. Zero where the next pivot is on the joint's own origin."""
        q = pin.neutral(self.model)
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, q)
        ends = [data.oMi[j].translation.copy() for j in self.chain[1:]]
        ends.append(data.oMf[self._frame].translation.copy())
        out = np.zeros((self.dof, 3))
        for k, j in enumerate(self.chain):
            frame = data.oMi[j]
            if self.prismatic[k]:
                moved = q.copy()
                moved[self._q_index[k]] += 1.0
                other = self.model.createData()
                pin.forwardKinematics(self.model, other, moved)
                along = other.oMi[j].translation - frame.translation
            else:
                along = ends[k] - frame.translation
            length = np.linalg.norm(along)
            if length > SAME_POINT:
                out[k] = frame.rotation.T @ along / length
        return out

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
        """Pinocchio's configuration vectors (N, nq) of rows (N, n) of chain joint positions
        (one row (n,) gives one vector); a continuous joint is its angle's cosine and sine."""
        joints = np.asarray(joints, float)
        rows = np.atleast_2d(joints)
        q = np.empty((len(rows), self.model.nq))
        q[:] = self._neutral
        q[:, self._plain_q] = rows[:, self._plain]
        if self._turning.size:
            q[:, self._turning_q] = np.cos(rows[:, self._turning])
            q[:, self._turning_q + 1] = np.sin(rows[:, self._turning])
        return q if joints.ndim > 1 else q[0]

    def chain_at(self, joints: np.ndarray, offset: np.ndarray,
                 model: tuple[pin.Model, pin.Data] | None = None, jacobian: bool = True,
                 ) -> Chain:
        """The chain at rows (N, n) (or one row (n,)) of joint positions, the target
        ``offset`` [m] from the tip link in its frame; ``model`` a copy of this one with other
        joint origins, and its data. Without ``jacobian`` the Jacobian is left at 0 (a
        prediction needs none: Pinocchio's forward kinematics alone, a third of the time).
        Pinocchio places the joints row by row; the rest is numpy over all rows."""
        joints = np.atleast_2d(np.asarray(joints, float))
        model, data = model or (self.model, self._data)
        rows, n, bodies = len(joints), self.dof, model.njoints
        placements = np.empty((rows, bodies, 4, 4))
        placements[:, 0] = np.eye(4)                           # the root's: the world
        jacobians = np.zeros((rows, 3, n))
        for r, q in enumerate(self.configuration(joints)):
            if jacobian:
                pin.computeJointJacobians(model, data, q)
                pin.updateFramePlacements(model, data)
                full = pin.getFrameJacobian(model, data, self._frame, pin.LOCAL_WORLD_ALIGNED)
                arm = data.oMf[self._frame].rotation @ offset
                jacobians[r] = (full[:3] - pin.skew(arm) @ full[3:])[:, self._v_index]
            else:
                pin.forwardKinematics(model, data, q)
            placements[r, 1:] = [data.oMi[j].homogeneous for j in range(1, bodies)]
        placement, tip = self._placements(model)
        rotations, origins = placements[..., :3, :3], placements[..., :3, 3]
        tip = placements[:, self._tip_body] @ tip                          # the tip link's
        tip_rotation = tip[:, :3, :3]
        target = tip[:, :3, 3] + tip_rotation @ offset
        parent_rotations = rotations[:, self._parents]                # (N, n, 3, 3)
        pivots = (np.einsum('rkxy,ky->rkx', parent_rotations, placement[:, :3, 3])
                  + origins[:, self._parents])
        placed = parent_rotations @ placement[:, :3, :3]
        centres = np.einsum('rjxy,jy->rjx', rotations, self._levers) + origins
        next_pivots = np.concatenate([pivots[:, 1:], target[:, None]], axis=1)
        carried = np.einsum('kj,rjx->rkx', self._subtree_masses, centres)
        return Chain(target, tip_rotation, pivots, placed, rotations[:, self.chain],
                     next_pivots, jacobians, carried, centres)

    def _placements(self, model: pin.Model) -> tuple[np.ndarray, np.ndarray]:
        """The chain joints' origins on their parents (n, 4, 4) and the tip link's placement
        on its joint (4, 4) in ``model``, kept for the model last asked (a prediction asks
        the same one again and again)."""
        if self._placed_in is None or self._placed_in[0] is not model:
            self._placed_in = (model, np.array([model.jointPlacements[j].homogeneous
                                                for j in self.chain]),
                               model.frames[self._frame].placement.homogeneous)
        return self._placed_in[1:]

    def gravity_moments(self, chain: Chain, payload: np.ndarray | float = 0.0) -> np.ndarray:
        """(N, n, 3) [N·m]: the moment gravity puts on what each chain joint carries (its
        subtree's links and the ``payload`` [kg] at the target) about the joint's pivot (its
        URDF origin: a revolute joint's centre, a prismatic joint's guide, where the slide
        bends), in the joint's frame."""
        payload = np.broadcast_to(np.asarray(payload, float), (len(chain.target),))
        lever = (chain.carried - self._carried_mass[None, :, None] * chain.pivots
                 + payload[:, None, None] * (chain.target[:, None] - chain.pivots))
        return np.einsum('rkxy,rkx->rky', chain.frames, cross(lever, GRAVITY))

    def moment_errors(self, chain: Chain, common: float, part: float, tool_centre: float,
                      ) -> np.ndarray:
        """(sources, N, n, 3) [N·m]: how :meth:`gravity_moments` (without the payload: it is
        declared) moves under each independent one-sigma error of the URDF's inertials —
        every body's mass off by ``common`` (relative, all together), each body's by ``part``
        (relative, on its own), the last body's centre of mass by ``tool_centre`` [m] along
        its link (a tool's, the least known). Linear in the masses: each body's own moment
        is the derivative. Each source moves every joint that carries the body at once."""
        carries = self._subtree_masses > 0                            # (n, bodies)
        levers = chain.centres[:, None] - chain.pivots[:, :, None]       # (N, n, bodies, 3)
        own = cross(self._masses[None, None, :, None] * carries[None, :, :, None] * levers,
                    GRAVITY)
        own = np.einsum('rkxy,rkbx->brky', chain.frames, own)          # (bodies, N, n, 3)
        last = self.chain[-1]
        along = np.einsum('rxy,y->rx', chain.frames[:, -1], self.link_directions[-1])
        tool = np.einsum('rkxy,rx->rky', chain.frames,
                         cross(self._masses[last] * along, GRAVITY)) * carries[:, last, None]
        massive = self._masses > 0
        return np.concatenate([common * own.sum(axis=0)[None], part * own[massive],
                               tool_centre * tool[None]])
