"""A node's claim of its arm: the client side of the arm owner
(:mod:`flexarm_motion.ros.arm_owner_node`, policy in
:mod:`flexarm_motion.arm_ownership`).

A motion claims the arm before anything moves (:meth:`ArmClaim.claimed`) and releases it when
it ends; meanwhile :meth:`ArmClaim.holds` says whether the claim still holds, from the arm
owner's latched ``arm/motion`` (subscribed while a claim is held, taken when asked, so it wakes
no executor): a claim ended by force (``flexarm cancel``), by the owner's restart or by anything
else is seen within one look, and the holder stops, holds the arm and keeps nothing measured
after. The calls wait in wall time, liveness-scaled (:mod:`flexarm_core.liveness`): the owner
answers at once unless the machine is starved or the owner is not there.
"""
from __future__ import annotations

import os
import socket
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.client import Client
from rclpy.node import Node
from rclpy.subscription import Subscription
from rclpy.task import Future

from flexarm_core import liveness, topics
from flexarm_core.goal_sender import full_name
from flexarm_core.ros.taken import Taken, take
from flexarm_motion.ros.arm_owner_node import LATCHED
from flexarm_msgs.msg import ArmMotion
from flexarm_msgs.srv import ClaimArm, ReleaseArm

CALL_WAIT = 5.0    # [s, wall] for the arm owner's answer (liveness-scaled)
NO_OWNER = ('no arm owner answers on {service}: is flexarm_arm_owner running (`flexarm '
            'status`)? Nothing moves without its claim')

Wait = Callable[[Future, float], bool]


class ArmBusy(RuntimeError):
    """The arm was not granted: another motion holds it (named), or no owner answered."""


def wait_on_event(future: Future, timeout: float) -> bool:
    """Wait for ``future`` while the node's executor spins in another thread."""
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    return done.wait(timeout)


class ArmClaim:
    """Claims the arm for this node's motions, one at a time (module docstring)."""

    def __init__(self, node: Node, wait: Wait = wait_on_event) -> None:
        self._node = node
        self._wait = wait
        group = ReentrantCallbackGroup()
        self._claim = node.create_client(ClaimArm, topics.CLAIM_ARM, callback_group=group)
        self._release = node.create_client(ReleaseArm, topics.RELEASE_ARM, callback_group=group)
        self._motion_input: Subscription | None = None
        self.motion_id = ''      # of the claim held now ('' : none)
        self.lost = ''           # why the claim held ended before its motion did ('' : it holds)
        self._others = ''        # the motion that holds the arm after ours ended ('' : none)

    @property
    def node_name(self) -> str:
        return full_name(self._node.get_namespace(), self._node.get_name())

    def acquire(self, kind: str, description: str, sender: str = '', within: str = '') -> str:
        """Claim the arm (or join the running motion ``within``); the motion's id.
        :class:`ArmBusy` with the owner's reason when refused or unanswered."""
        request = ClaimArm.Request(kind=kind, description=description, sender=sender,
                                   holder=self.node_name, holder_pid=os.getpid(),
                                   holder_host=socket.gethostname(), within=within)
        response = self._call(self._claim, request)
        if not response.granted:
            raise ArmBusy(response.reason)
        self.motion_id, self.lost, self._others = response.motion_id, '', ''
        if self._motion_input is None:
            self._motion_input = self._node.create_subscription(
                ArmMotion, topics.ARM_MOTION, lambda _: None, LATCHED, callback_group=Taken())
        return self.motion_id

    def release(self, motion_id: str = '', force: bool = False, by: str = '') -> str:
        """End a claim (``motion_id``; force: whichever runs); what the owner did."""
        response = self._call(self._release, ReleaseArm.Request(
            motion_id=motion_id, force=force, by=by or self.node_name))
        return response.message

    def holds(self) -> bool:
        """Whether the claim this node holds still holds the arm (False without one)."""
        if not self.motion_id:
            return False
        while self._motion_input is not None and (msg := take(self._motion_input)) is not None:
            if msg.motion_id != self.motion_id and not self.lost:
                self.lost = (f'motion {self.motion_id} no longer holds the arm: '
                             + (msg.ended or 'the arm owner restarted'))
            self._others = msg.motion_id if msg.motion_id != self.motion_id else ''
        return not self.lost

    def may_stop(self) -> bool:
        """Whether this node may stop the arm: under its claim, or after that ended while no
        other motion holds the arm; never without one."""
        self.holds()
        return bool(self.motion_id) and not self._others

    @contextmanager
    def claimed(self, kind: str, description: str, sender: str = '', within: str = ''
                ) -> Iterator[str]:
        """Hold the arm for the duration; released at the end unless joined (``within``:
        its holder releases it)."""
        motion_id = self.acquire(kind, description, sender, within)
        try:
            yield motion_id
        finally:
            if not within and not self.lost:
                try:
                    self.release(motion_id)
                except ArmBusy as exc:        # the owner went: its successor starts free
                    self._node.get_logger().warn(f'release of motion {motion_id}: {exc}')
            self.motion_id = ''
            if self._motion_input is not None:
                self._node.destroy_subscription(self._motion_input)
                self._motion_input = None

    def _call(self, client: Client, request: Any) -> Any:
        service = client.srv_name
        if not client.wait_for_service(timeout_sec=liveness.limit(CALL_WAIT)):
            raise ArmBusy(NO_OWNER.format(service=service))
        future = client.call_async(request)
        if not self._wait(future, liveness.limit(CALL_WAIT)) or future.result() is None:
            client.remove_pending_request(future)
            raise ArmBusy(f'the arm owner did not answer on {service} within '
                          f'{liveness.limit(CALL_WAIT):.0f} s')
        return future.result()
