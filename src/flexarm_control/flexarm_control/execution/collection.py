"""The collection loop of ``/collect_samples`` (pure core of the learner node; paper section
2-1 step 2).

For every learning pose, in the order given: move there, measure the tip, and build the
deflection sample from the joints the controller reports and the measured pose
(:func:`deflection_sample`); a failed move or measurement is retried ``retries`` times, then
the pose is skipped and counted, never stored; the warning of a failed measurement gives the
vision node's reason. Each sample is handed to ``store`` (the dataset writer: on disk before
the next move) as soon as it is taken. Cancel ends the loop with the arm held and every stored
sample kept. A sample is stored only while the arm is held by the collection's own motion
(its claim, recorded in the sample): one measured after the claim ended is refused, with the
reason. A controller that fell silent ends it too: no later pose could be reached. So do
``BLIND_POSES`` poses in a row without a valid measurement: a camera that measures nothing at
three poses will not at the next ones, and a campaign that skips through all of them would
only spend its time (the collection fails with the vision node's reason).
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from flexarm_core.kinematics import ArmGeometry, forward, wrap_angle
from flexarm_core.measurement import Measurement
from flexarm_deflection.dataset import Sample
from flexarm_motion.arm_motion import Abort, ArmMotion, Canceled, MoveFailed, never

BLIND_POSES = 3     # poses in a row skipped for want of a valid measurement: the camera is blind


def deflection_sample(geometry: ArmGeometry, joints: np.ndarray, measurement: Measurement,
                      payload: float, stamp: float, motion: str = '') -> Sample:
    """The learning pair at reported ``joints``: measured minus rigid tip pose, φ wrapped."""
    rigid = forward(geometry, joints)
    deflection = measurement.pose - rigid
    deflection[2] = wrap_angle(deflection[2])
    return Sample(stamp=stamp, joints=joints, payload=payload, rigid_pose=rigid,
                  measured_pose=measurement.pose, deflection=deflection,
                  holes_used=measurement.holes_used, residual=measurement.residual,
                  motion=motion)


@dataclass
class Collected:
    """Counts of one collection."""

    collected: int = 0
    skipped: int = 0
    canceled: bool = False
    stopped: str = ''      # why the loop ended early ('' if it did not), e.g. controller lost


class Collector:
    """Visits learning poses with an :class:`ArmMotion` and takes a sample at each."""

    def __init__(self, motion: ArmMotion, geometry: ArmGeometry, retries: int,
                 clock: Callable[[], float], warn: Callable[[str], None] = lambda _: None,
                 ) -> None:
        if retries < 0:
            raise ValueError('measurement retries must be >= 0')
        self.motion = motion
        self.geometry = geometry
        self.retries = retries
        self.clock = clock        # [s] the node's time, stamped on each sample
        self.warn = warn
        self.blind = ''           # why the last pose's measurements failed ('' if they did not)

    def sample_at(self, joints: np.ndarray, payload: float, abort: Abort = never,
                  motion: str = '') -> Sample | None:
        """Move to ``joints`` and measure; the sample, or None after the retries failed.
        Raises :class:`Canceled`, and :class:`MoveFailed` when the controller is lost."""
        self.blind = ''
        for attempt in range(1, 2 + self.retries):
            try:
                self.motion.move_to(joints, abort)
            except MoveFailed as exc:
                if exc.controller_lost:
                    raise
                self.warn(f'joints did not arrive (attempt {attempt}): {exc}')
                self.blind = ''
                continue
            measurement = self.motion.measure(abort)
            if measurement is None:
                self.blind = self.motion.arm.measurement_problem or 'no reason given'
                self.warn(f'no valid settled tip pose (attempt {attempt}): {self.blind}')
                continue
            self.blind = ''
            reported = self.motion.arm.positions()
            return deflection_sample(self.geometry, reported, measurement, payload,
                                     self.clock(), motion)
        return None

    def collect(self, poses: Iterable[np.ndarray], payload: float,
                store: Callable[[Sample], None], abort: Abort = never,
                progress: Callable[[int, Collected, Sample | None], None] = lambda *_: None,
                motion: str = '', lost: Callable[[], str] = lambda: '') -> Collected:
        """Take a sample at every pose (module docstring); ``progress(k, counts, sample)``
        after the k-th pose (sample None if it was skipped). Each sample records ``motion``,
        the claim of the arm it was taken in; once ``lost()`` gives a reason (the arm is no
        longer held by that motion alone) no sample is stored any more and the loop ends."""
        counts = Collected()
        blind = 0        # poses in a row without a valid measurement
        for k, joints in enumerate(poses, start=1):
            try:
                sample = self.sample_at(np.asarray(joints, dtype=float), payload, abort, motion)
            except Canceled:
                counts.canceled = True
                return counts
            except MoveFailed as exc:
                counts.stopped = str(exc)
                return counts
            if (reason := lost()):
                counts.stopped = (f'sample {k} refused: the arm was not held by this motion '
                                  f'alone ({reason})')
                return counts
            if sample is None:
                counts.skipped += 1
                blind = blind + 1 if self.blind else 0
            else:
                store(sample)
                counts.collected += 1
                blind = 0
            progress(k, counts, sample)
            if blind >= BLIND_POSES:
                counts.stopped = (
                    f'no valid tip measurement at {blind} poses in a row, the camera cannot '
                    f'measure: {self.blind}')
                return counts
        return counts
