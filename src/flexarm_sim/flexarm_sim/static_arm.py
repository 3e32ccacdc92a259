"""The simulated arm without its dynamics, for offline studies of the control policies (pure).

An :class:`~flexarm_motion.arm_motion.Arm` that arrives at once: a move applies the
error sources as the simulator's dynamics would at its end (:mod:`flexarm_sim.errors`: the servos'
repeatability error of the move, the friction play taken up along it, the thermal strain at the
simulated time) and advances the simulated time by the slowest joint's travel time at the
Table 1 speeds plus ``settle`` seconds of settling (no vibration is simulated: the vision node
measures only a settled tip). A measurement renders ``frames`` images of the plate at the true
tip pose with the true camera (:mod:`flexarm_sim.true_camera`), estimates each with the vision
node's estimator (the calibrated, believed camera) and averages the valid ones, as the vision
and the nodes do. :meth:`truth` is the tip pose the simulator would publish as ground truth.
"""
from __future__ import annotations

import numpy as np

from flexarm_core.measurement import Measurement, average_frames
from flexarm_sim.camera import CameraRenderer
from flexarm_sim.errors import ArmErrors
from flexarm_sim.plant import Plant
from flexarm_vision.pose_estimator import TipPoseEstimator


class StaticArm:
    def __init__(self, plant: Plant, errors: ArmErrors, start: np.ndarray,
                 camera: CameraRenderer, estimator: TipPoseEstimator,
                 rng: np.random.Generator, settle: float = 2.0, frame_rate: float = 30.0,
                 ) -> None:
        self.plant = plant
        self.errors = errors
        self.camera = camera
        self.estimator = estimator
        self.rng = rng                  # sensor noise of the images
        self.settle = settle            # [s] after every move
        self.frame_rate = frame_rate    # [Hz] of the camera
        self.time = 0.0                 # [s] simulated
        self.moves = 0
        self._q = np.asarray(start, dtype=float).copy()
        self._move = errors.start(self._q)
        self._motor = self._q.copy()
        self._play = np.zeros(4)

    controller_silent = False

    def positions(self) -> np.ndarray:
        return self._q.copy()

    def move(self, q: np.ndarray, tolerance: np.ndarray, timeout: float,
             abort=lambda: False) -> bool:
        target = np.asarray(q, dtype=float)
        self._move = self.errors.plan(self._move, self._q, target)
        motor = target + self._move.error(target)
        self._play = self.errors.slip(self._play, motor - self._motor)
        travel = np.abs(target - self._q) / self.plant.geometry.velocity
        self.time += float(np.max(travel)) + self.settle
        self._q, self._motor = target.copy(), motor
        self.moves += 1
        return True

    def hold(self) -> np.ndarray:
        return self._q.copy()

    def set_payload(self, payload: float) -> None:
        """The arm picks up or puts down a load [kg]."""
        self.plant = self.plant.with_payload(payload)

    def truth(self) -> np.ndarray:
        """The true tip pose (3,) [m, m, rad] now."""
        return self.plant.pose(self._motor, self.errors.band * self._play,
                               self.errors.strain(self.time))

    def measure(self, frames: int, timeout: float, abort=lambda: False) -> Measurement | None:
        truth = self.truth()
        self.time += frames / self.frame_rate
        estimates = [self.estimator.estimate(self.camera.render(truth, rng=self.rng))
                     for _ in range(frames)]
        valid = [e for e in estimates if e.valid]
        if len(valid) < frames:
            return None
        return average_frames(np.array([e.pose for e in valid]),
                              holes_used=min(e.holes_used for e in valid),
                              residual=max(e.residual for e in valid))
