"""Bridge to a real robot controller: the ros2_control topic contract over the flexarm wire
protocol (src/flexarm_bridge/PROTOCOL.md).

Forwards ``/forward_position_controller/commands`` as JOINT_COMMAND frames, with the
simulator's checks (length, finite, joint limits from config/arm.yaml), and publishes
``/joint_states`` from the controller's JOINT_STATE frames, so nothing else in the graph
changes between ``--robot sim`` and ``--robot bridge``. The frames are
:mod:`flexarm_bridge.controller_protocol`, the authentication with a site key
:mod:`flexarm_bridge.link_auth`; this node keeps the link up in a thread of its own (ROS
callbacks never block).

Explained in docs/nodes.md#the-bridge-flexarm_bridge.
"""
from __future__ import annotations

import socket
import threading
import time
from dataclasses import dataclass, field

from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from flexarm_bridge import controller_protocol as proto
from flexarm_bridge.link_auth import PC, LinkAuth, site_key_for
from flexarm_bridge.tcp_link import connect
from flexarm_core import topics
from flexarm_core.health_report import ERROR, OK, WARN, CommandLog, Status, status
from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry, command_error
from flexarm_core.ros.diagnostics import DiagnosticsPublisher
from flexarm_core.ros.node_main import run
from flexarm_core.ros.node_params import declare, declare_tree


def link_status(node: str, controller: str, linked: bool, down_for: float, last_error: str,
                connects: int, retry_max: float) -> Status:
    """``<node>: controller link``: OK while linked (a joint state of the connection accepted,
    authenticated with a key); WARN while reconnecting, i.e. down for at most ``retry_max``
    (the longest backoff); ERROR once down longer (or not linked that long after start):
    commands are dropped meanwhile."""
    values = {'controller': controller, 'linked': linked,
              'down for [s]': 0.0 if linked else round(down_for, 1),
              'reconnects': max(connects - 1, 0), 'last error': last_error}
    if linked:
        return status(node, 'controller link', OK, f'linked to {controller}', values, controller)
    if down_for <= retry_max:
        return status(node, 'controller link', WARN, f'reconnecting to {controller}'
                      + (f' ({last_error})' if last_error else ''), values, controller)
    return status(node, 'controller link', ERROR, f'link down for {down_for:.0f} s: '
                  f'{last_error or "no joint state from the controller"}', values, controller)


@dataclass
class Connection:
    """One connection to the controller: its socket, authentication (with a site key), frames
    and what the controller said before the link came up."""
    sock: socket.socket
    auth: LinkAuth | None
    encoder: proto.Encoder = field(init=False)
    hello: bool = False           # its HELLO accepted (version, joints)
    heard: float = field(default_factory=time.monotonic)   # last sign of life
    beat: float = field(default_factory=time.monotonic)    # last HEARTBEAT sent
    refusal: str = ''             # the controller's ERROR before the link came up

    def __post_init__(self) -> None:
        self.encoder = proto.Encoder(self.auth)

    def counts(self, frame: proto.Frame) -> bool:
        """Whether ``frame`` is a sign of life: any valid frame without a key, else only
        authenticated session frames (replayed, reflected or handshake frames never are)."""
        return self.auth is None or frame.authenticated


class BridgeNode(Node):

    def __init__(self) -> None:
        super().__init__('flexarm_bridge')
        self._geometry = ArmGeometry.from_dict(declare_tree(self, 'arm', 'config/arm.yaml'))
        self._host = declare(self, 'host', 'config/bridge.yaml')
        self._port = declare(self, 'port', 'config/bridge.yaml')
        self._retry_min = declare(self, 'retry_min', 'config/bridge.yaml')
        self._retry_max = declare(self, 'retry_max', 'config/bridge.yaml')
        self._heartbeat = declare(self, 'heartbeat_period', 'config/bridge.yaml')
        self._timeout = declare(self, 'heartbeat_timeout', 'config/bridge.yaml')
        self._max_errors = declare(self, 'max_errors', 'config/bridge.yaml')
        key_file = declare(self, 'link_key_file', 'config/bridge.yaml')
        try:
            self._site_key = site_key_for(self._host, key_file)
        except ValueError as exc:
            self.get_logger().fatal(f'refusing to connect: {exc}')
            raise SystemExit(1) from None
        self._pub = self.create_publisher(JointState, topics.JOINT_STATES, 10)
        self.create_subscription(Float64MultiArray, topics.JOINT_COMMANDS, self._on_command, 10)
        self._lock = threading.Lock()         # guards _linked and every send
        self._linked: Connection | None = None    # the connection whose link is up
        self._commands = CommandLog()
        self._down_since: float | None = time.monotonic()   # None while linked
        self._connects = 0            # links that came up
        self._last_error = ''         # why the link last failed
        self._running = True
        threading.Thread(target=self._link_loop, daemon=True).start()
        self._diagnostics = DiagnosticsPublisher(self, self.statuses)

    def statuses(self) -> list[Status]:
        """The node's health (docs/nodes.md): controller link, commands."""
        controller, down_since = f'{self._host}:{self._port}', self._down_since
        return [link_status(self.get_name(), controller, down_since is None,
                            0.0 if down_since is None else time.monotonic() - down_since,
                            self._last_error, self._connects, self._retry_max),
                self._commands.status(self.get_name(), controller)]

    # --- PC -> controller --------------------------------------------------------------------
    def _on_command(self, msg: Float64MultiArray) -> None:
        values = list(msg.data)
        reason = command_error(values, self._geometry)
        if reason is not None:
            self._commands.record(reason)
            self.get_logger().error(f'joint command rejected, not forwarded: {reason}')
            return
        with self._lock:
            sent = self._linked is not None and self._send(self._linked, proto.JOINT_COMMAND,
                                                           positions=values)
        self._commands.record(None if sent else 'dropped: no link to the controller')
        if not sent:
            self.get_logger().error('joint command dropped: no link to the controller '
                                    '(send a fresh command once it is back)')

    def _send(self, conn: Connection, frame_type: int, **fields) -> bool:
        """Send one frame (hold ``_lock``); whether it went out (with a key, nothing but AUTH
        before the session)."""
        data = conn.encoder.encode(frame_type, **fields)
        if data is None:
            return False
        try:
            conn.sock.sendall(data)
            return True
        except OSError:
            return False

    # --- link ---------------------------------------------------------------------------------
    def _link_loop(self) -> None:
        delay = self._retry_min
        while self._running:
            try:
                sock = connect(self._host, self._port, timeout=2.0)
            except OSError as exc:
                self._last_error = f'unreachable ({exc})'
                self.get_logger().error(
                    f'controller {self._host}:{self._port} unreachable ({exc}); retrying in '
                    f'{delay:.1f} s', throttle_duration_sec=5.0)
                time.sleep(delay)
                delay = min(2 * delay, self._retry_max)
                continue
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)   # small frames, now
            sock.settimeout(0.05)
            self.get_logger().info(f'connected to the controller at {self._host}:{self._port}')
            conn = Connection(sock, None if self._site_key is None
                              else LinkAuth(self._site_key, PC))
            reason = self._receive(conn)
            with self._lock:
                linked, self._linked = self._linked is conn, None
            sock.close()
            if not self._running:
                break
            self._last_error = reason
            if linked:
                delay = self._retry_min
                self._down_since = time.monotonic()
            self.get_logger().error(f'link to the controller lost: {reason}; commands are not '
                                    f'forwarded until it is back; reconnecting in {delay:.1f} s',
                                    throttle_duration_sec=5.0)
            time.sleep(delay)
            delay = min(2 * delay, self._retry_max)

    def _receive(self, conn: Connection) -> str:
        """Read frames until the link fails; the reason it did."""
        decoder = proto.Decoder(conn.auth)
        errors = 0
        while self._running:
            now = time.monotonic()
            if now - conn.beat >= self._heartbeat:
                with self._lock:
                    self._send(conn, proto.HEARTBEAT, time=now)
                conn.beat = now
            if now - conn.heard > self._timeout:
                return self._loss(conn, f'no frame for {self._timeout:.1f} s' if (
                    conn.auth is None or conn.auth.established) else
                    f'no authenticated session within {self._timeout:.1f} s')
            try:
                data = conn.sock.recv(65536)
            except TimeoutError:
                continue
            except OSError as exc:
                return self._loss(conn, str(exc))
            if not data:
                return self._loss(conn, 'closed by the controller')
            rejected = decoder.rejected
            frames, problems = decoder.feed(data)
            for problem in problems:
                self.get_logger().warning(f'rejected from the controller: {problem}',
                                          throttle_duration_sec=1.0)
            live = [frame for frame in frames if conn.counts(frame)]
            errors = 0 if live else errors + decoder.rejected - rejected
            if errors >= self._max_errors:
                return f'{errors} consecutive malformed frames'
            for frame in frames:
                if conn.counts(frame):
                    conn.heard = time.monotonic()
                self._handle(frame, conn)
        return 'shutting down'

    @staticmethod
    def _loss(conn: Connection, reason: str) -> str:
        """``reason`` with what the controller said before the link came up, if it did."""
        return f'{reason} ({conn.refusal})' if conn.refusal else reason

    def _handle(self, frame: proto.Frame, conn: Connection) -> None:
        if frame.type == proto.HELLO:
            self._hello(frame, conn)
        elif frame.type == proto.AUTH_OK:           # its proof verified by the decoder
            conn.heard, conn.beat = time.monotonic(), 0.0    # the session starts: beat at once
            self.get_logger().info('controller proved the site key: link authenticated')
        elif frame.type == proto.JOINT_STATE and conn.hello and conn.counts(frame):
            if len(frame.fields['positions']) != len(JOINT_NAMES):
                self.get_logger().warning('JOINT_STATE with the wrong number of joints dropped')
                return
            if self._linked is not conn:
                with self._lock:
                    self._linked = conn
                    self._down_since, self._connects = None, self._connects + 1
                self.get_logger().info('linked: joint states flow, forwarding fresh commands')
            msg = JointState(name=list(JOINT_NAMES), position=frame.fields['positions'],
                             velocity=frame.fields['velocities'])
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.header.frame_id = 'base_link'
            self._pub.publish(msg)
        elif frame.type == proto.ACK and frame.fields['code'] != proto.OK:
            self._commands.record(f'controller refused command {frame.fields["acked"]} '
                                  f'(code {frame.fields["code"]})')
            self.get_logger().error(f'controller refused command {frame.fields["acked"]} '
                                    f'(code {frame.fields["code"]})')
        elif frame.type == proto.ERROR:
            said = (f'controller error {frame.fields["code"]}'
                    + ('' if conn.counts(frame) else ' (unauthenticated: before the session)')
                    + f': {frame.fields["text"]}')
            if self._linked is not conn:
                conn.refusal = said
            self.get_logger().error(said)

    def _hello(self, frame: proto.Frame, conn: Connection) -> None:
        """The controller's HELLO: check it; with a key, answer with AUTH (the decoder has
        refused any HELLO after the first)."""
        version = proto.VERSION if conn.auth is None else proto.AUTH_VERSION
        if frame.fields['version'] != version or frame.fields['names'] != list(JOINT_NAMES):
            self.get_logger().error(
                f'controller speaks version {frame.fields["version"]} with joints '
                f'{frame.fields["names"]}; need version {version} with {list(JOINT_NAMES)}')
            return
        if conn.hello:
            self.get_logger().error('second HELLO on one connection ignored')
            return
        conn.hello = True
        if conn.auth is None:
            self.get_logger().info('controller HELLO accepted: waiting for its joint states')
            return
        with self._lock:
            self._send(conn, proto.AUTH, **conn.auth.answer())
        self.get_logger().info('controller HELLO accepted, AUTH sent: waiting for its proof '
                               'of the site key')

    def destroy_node(self) -> None:
        self._running = False
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    run(BridgeNode, args)


if __name__ == '__main__':
    main()
