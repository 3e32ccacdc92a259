"""One motion at a time per arm: the arm owner's policy (pure core, no rclpy).

ros2_control's rule, applied to whole motions: a command interface is claimed by exactly one
controller, and the controller manager refuses a second claim. Here every motion — a
MoveToPose goal, a collection, a refresh, a calibration, anything added later — claims its arm
from the arm's one owner before anything moves, and commands it only while the claim holds
(:class:`~flexarm_motion.ros.arm_interface.ArmInterface` sends nothing without one). A second
claim is refused with the running motion named: its kind, what it does, who sent it and which
node commands the arm for it.

A claim ends when its holder releases it, when it is ended by force (``flexarm cancel``: its
holder sees the claim gone, stops and holds the arm), or when its holder's process has ended
(:meth:`ArmOwnership.check`, called by the owner node while a claim is held): a crashed node
never keeps an arm. A motion may be joined (``within``): a calibration holds the arm across
its poses and each pose's MoveToPose goal runs within that claim; joining a motion that no
longer holds the arm is refused. A claim that ended stays ended: whoever held it can tell
that the arm was not held by their motion alone from then on.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Holder:
    """The node that commands the arm for a motion, and its process (to tell it ended)."""

    node: str                 # full node name, /ns/name
    pid: int = 0              # 0: unknown (judged by the graph alone)
    host: str = ''
    start_time: int | None = None   # its start (clock ticks: flexarm_core.processes), on this host


@dataclass(frozen=True)
class Motion:
    """A granted claim of the arm."""

    motion_id: str
    kind: str
    description: str
    sender: str
    holder: Holder
    started: float            # [s] graph time

    def text(self) -> str:
        """'collect "6 samples in region A" (goal sent by /cli), commanded by /learner'."""
        sender = f' ({self.sender})' if self.sender else ''
        return (f'{self.kind} "{self.description}"{sender}, commanded by {self.holder.node}, '
                f'motion {self.motion_id}')


@dataclass(frozen=True)
class Refused:
    """A claim refused: why, and the motion that holds the arm (None: none holds it)."""

    reason: str
    running: Motion | None = None


def busy_reason(running: Motion) -> str:
    """Why a motion cannot start while ``running`` holds the arm."""
    return (f'the arm is busy: {running.text()} holds it; nothing moved (wait for it to end, '
            'or end it with `flexarm cancel`)')


class ArmOwnership:
    """The claims of one arm: at most one motion holds it (module docstring)."""

    def __init__(self, new_id: Callable[[], str]) -> None:
        self._new_id = new_id
        self.running: Motion | None = None
        self.ended = ''           # how the last motion ended ('' before any)

    def claim(self, kind: str, description: str, sender: str, holder: Holder, now: float,
              within: str = '') -> Motion | Refused:
        """Grant the arm to a new motion, or to one joining the running motion ``within``."""
        if not kind or not holder.node:
            return Refused('a claim needs a kind and its holder node')
        running = self.running
        if within:
            if running is not None and running.motion_id == within:
                return running
            return Refused(
                f'motion {within} does not hold the arm (it ended: {self.ended or "unknown"})'
                + (f'; {busy_reason(running)}' if running is not None else ''), running)
        if running is not None:
            return Refused(busy_reason(running), running)
        self.running = Motion(self._new_id(), kind, description, sender, holder, now)
        return self.running

    def release(self, motion_id: str, force: bool = False, by: str = '') -> tuple[bool, str]:
        """End ``motion_id`` (force: whichever runs, if ``motion_id`` is ''); whether it
        ended, and what was ended or why nothing was."""
        running = self.running
        if running is None:
            return False, 'the arm is free: no motion holds it'
        if motion_id and motion_id != running.motion_id:
            return False, f'motion {motion_id} does not hold the arm; {running.text()} does'
        if not motion_id and not force:
            return False, 'no motion named (only a forced release ends whichever runs)'
        self.running = None
        self.ended = f'{running.kind} motion {running.motion_id} ' + (
            f'canceled by {by or "someone"}' if force else 'released')
        return True, f'ended {running.text()}'

    def check(self, alive: Callable[[Holder], bool]) -> Motion | None:
        """Free the arm if the running motion's holder has ended; the motion freed, if any."""
        running = self.running
        if running is None or alive(running.holder):
            return None
        self.running = None
        self.ended = (f'{running.kind} motion {running.motion_id} ended with its holder '
                      f'{running.holder.node}')
        return running
