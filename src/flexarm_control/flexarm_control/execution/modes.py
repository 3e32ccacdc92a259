"""The ways a ``/move_to_pose`` goal is executed: one enum for the server, the client,
the CLI and the benchmarks. Its values are the goal's ``MODE_*`` constants (a test checks it).

* RIGID: the rigid inverse kinematics of the target.
* PREDICTIVE: the paper, ``x* = x_d - Delta(theta)`` solved to its fixed point.
* CLOSED_LOOP: PREDICTIVE, then corrected from the measured tip until within tolerance.
* AUTO: PREDICTIVE where the plan's 95 % error bound is within the tolerance, else CLOSED_LOOP
  (:mod:`flexarm_control.execution.planning`).
"""
from __future__ import annotations

from enum import IntEnum


class Mode(IntEnum):
    RIGID = 0
    PREDICTIVE = 1
    CLOSED_LOOP = 2
    AUTO = 3

    @property
    def label(self) -> str:
        """The name users type and read: 'rigid', 'predictive', 'closed_loop'."""
        return self.name.lower()

    @classmethod
    def of(cls, value: Mode | str | int) -> Mode:
        """The mode of a label or number; ValueError naming the known labels."""
        if isinstance(value, str):
            try:
                return cls[value.upper()]
            except KeyError:
                raise ValueError(f'unknown mode {value!r}; use one of '
                                 f'{", ".join(MODE_LABELS)}') from None
        return cls(value)


MODE_LABELS = tuple(mode.label for mode in Mode)
