"""An :class:`~flexarm_motion.arm_motion.Arm` for the policy tests: the simulator's
plant, no ROS. Joints arrive at once unless told otherwise; the tip is measured without noise."""
from __future__ import annotations

import numpy as np

from flexarm_core.measurement import Measurement, average_frames
from flexarm_sim.plant import Plant


class FakeArm:
    def __init__(self, plant: Plant, start: np.ndarray) -> None:
        self.plant = plant
        self.q = np.asarray(start, dtype=float).copy()
        self.commands: list[np.ndarray] = []
        self.holds = 0
        self.arrives = True           # moves reach their command
        self.silent = False           # the controller stopped reporting
        self.refusal = ''             # the controller's reason it ends every move ('' none)
        self.move_problem = ''
        self.blind_moves: set[int] = set()   # move numbers (1-based) measured as None
        self.cancel_at_move = 0       # abort requested during this move (0: never)
        self.braking = np.zeros(4)    # past its hold when read right after it (comes back)
        self.measurements = 0
        self.measurement_problem = ''
        self.blind_reason = 'fit residual 0.155 mm RMS too large'   # the vision node's, blind

    @property
    def controller_silent(self) -> bool:
        return self.silent

    def positions(self) -> np.ndarray | None:
        return self.q + (self.braking if self.holds else 0.0)

    def move(self, q, tolerance, timeout, abort=lambda: False) -> bool:
        self.commands.append(np.asarray(q, dtype=float).copy())
        self.timeout = timeout
        if len(self.commands) == self.cancel_at_move:
            self.q = (self.q + q) / 2          # stopped half-way
            self.cancelled = True
        self.move_problem = self.refusal
        if abort() or not self.arrives or self.silent or self.refusal:
            return False
        self.q = np.asarray(q, dtype=float).copy()
        return True

    def measure(self, frames, timeout, abort=lambda: False) -> Measurement | None:
        self.measurements += 1
        if abort() or len(self.commands) in self.blind_moves:
            self.measurement_problem = ('' if abort() else 'the vision node found no valid pose '
                                        f'in 25 frame(s): {self.blind_reason}')
            return None
        self.measurement_problem = ''
        return average_frames(np.repeat(self.plant.pose(self.q)[None], frames, axis=0),
                              holes_used=12, residual=1e-6)

    def hold(self) -> np.ndarray:
        self.holds += 1
        return self.q.copy()

    def abort(self) -> bool:
        """The cancel request a test makes at ``cancel_at_move``."""
        return getattr(self, 'cancelled', False)
