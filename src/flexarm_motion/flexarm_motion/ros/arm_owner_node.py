"""The arm owner: the one node per arm that grants motions the arm, one at a time.

Offers ``arm/claim`` and ``arm/release`` (flexarm_msgs/srv/ClaimArm, ReleaseArm) and publishes
the motion that holds the arm on the latched ``arm/motion`` (flexarm_msgs/ArmMotion) whenever
it changes. The policy is :mod:`flexarm_motion.arm_ownership`; this node serves it
and frees the arm when the running motion's holder has ended. Motions claim through
:mod:`flexarm_motion.ros.arm_claim`.

Explained in docs/nodes.md#the-arm-owner-flexarm_arm_owner.
"""
from __future__ import annotations

import socket
import uuid

from rclpy.clock import Clock, ClockType
from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile

from flexarm_core import topics
from flexarm_core.health_report import OK, Status, status
from flexarm_core.processes import start_time
from flexarm_core.ros.diagnostics import DiagnosticsPublisher
from flexarm_core.ros.node_main import run
from flexarm_core.ros.stamps import GraphTime, to_ns
from flexarm_motion.arm_ownership import ArmOwnership, Holder, Motion, Refused
from flexarm_msgs.msg import ArmMotion
from flexarm_msgs.srv import ClaimArm, ReleaseArm

CHECK_PERIOD = 1.0      # [s, wall] between two looks for the running motion's holder
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def motion_msg(motion: Motion | None, stamp: object, ended: str = '') -> ArmMotion:
    """The ``arm/motion`` message of the running motion (None: the arm is free)."""
    if motion is None:
        return ArmMotion(stamp=stamp, ended=ended)
    return ArmMotion(stamp=stamp, motion_id=motion.motion_id, kind=motion.kind,
                     description=motion.description, sender=motion.sender,
                     holder=motion.holder.node)


class ArmOwnerNode(Node):

    def __init__(self, context: Context | None = None) -> None:
        super().__init__('flexarm_arm_owner', context=context)
        self._time = GraphTime(self)
        self._host = socket.gethostname()
        self._ownership = ArmOwnership(lambda: uuid.uuid4().hex[:12])
        self._granted = 0
        self._refused = 0
        self._motion_pub = self.create_publisher(ArmMotion, topics.ARM_MOTION, LATCHED)
        self._publish()
        self.create_service(ClaimArm, topics.CLAIM_ARM, self._claim)
        self.create_service(ReleaseArm, topics.RELEASE_ARM, self._release)
        self._check = self.create_timer(CHECK_PERIOD, self._check_holder,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._check.cancel()            # runs only while a claim is held
        self._diagnostics = DiagnosticsPublisher(self, self.statuses, stamp=self._time.stamp)

    def statuses(self) -> list[Status]:
        running = self._ownership.running
        message = (f'held by {running.text()}' if running is not None else
                   'free' + (f' (last: {self._ownership.ended})' if self._ownership.ended
                             else ''))
        return [status(self.get_name(), 'arm owner', OK, message,
                       {'motions granted': self._granted, 'claims refused': self._refused})]

    def _publish(self) -> None:
        self._motion_pub.publish(motion_msg(self._ownership.running, self._time.stamp(),
                                            self._ownership.ended))

    def _claim(self, request: ClaimArm.Request, response: ClaimArm.Response
               ) -> ClaimArm.Response:
        pid = int(request.holder_pid)
        here = request.holder_host == self._host and pid > 0
        holder = Holder(request.holder, pid, request.holder_host,
                        start_time(pid) if here else None)
        before = self._ownership.running
        outcome = self._ownership.claim(request.kind, request.description, request.sender,
                                        holder, to_ns(self._time.stamp()) * 1e-9,
                                        request.within)
        stamp = self._time.stamp()
        if isinstance(outcome, Refused):
            self._refused += 1
            response.reason = outcome.reason
            response.running = motion_msg(outcome.running, stamp)
            self.get_logger().info(f'claim of {request.holder} refused: {outcome.reason}')
            return response
        response.granted, response.motion_id = True, outcome.motion_id
        response.running = motion_msg(outcome, stamp)
        if outcome is not before:
            self._granted += 1
            self.get_logger().info(f'arm granted to {outcome.text()}')
            self._publish()
            self._check.reset()
        return response

    def _release(self, request: ReleaseArm.Request, response: ReleaseArm.Response
                 ) -> ReleaseArm.Response:
        response.released, response.message = self._ownership.release(
            request.motion_id, request.force, request.by)
        if response.released:
            self.get_logger().info(f'{self._ownership.ended}')
            self._freed()
        return response

    def _check_holder(self) -> None:
        freed = self._ownership.check(self._alive)
        if freed is not None:
            self.get_logger().warn(f'{self._ownership.ended}: the arm is free')
            self._freed()

    def _freed(self) -> None:
        self._check.cancel()
        self._publish()

    def _alive(self, holder: Holder) -> bool:
        """Whether the holder's process still runs (this host) or its node is in the graph."""
        if holder.start_time is not None:
            return start_time(holder.pid) == holder.start_time
        names = {f'{ns.rstrip("/")}/{name}' for name, ns in self.get_node_names_and_namespaces()}
        return holder.node in names


def main(args: list[str] | None = None) -> None:
    run(ArmOwnerNode, args)


if __name__ == '__main__':
    main()
