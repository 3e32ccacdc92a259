"""A robot controller that speaks the flexarm wire protocol (PROTOCOL.md), for tests and demos.

The simulator (:class:`~flexarm_sim.sim_node.SimNode`) with its joint interface moved from ROS
topics to a TCP server: it serves JOINT_STATE frames at the joint-state rate and executes
JOINT_COMMAND frames, so ``flexarm_bridge`` can stand between it and the graph. What the real
world provides outside a robot controller stays on ROS: ``/clock``, the tip camera and the
ground truth. Listens on loopback unless ``host`` says otherwise, and refuses to listen
anywhere else without ``link_key_file`` (PROTOCOL.md, Authentication); with a key it speaks
only the authenticated protocol and executes nothing before the PC's AUTH. One PC at a time: a
second connection gets an ERROR frame (code 5, busy) and is closed at once, never queued. On
link loss (peer closed, or no frame for ``heartbeat_timeout``, which also ends a connection
that does not authenticate) it holds the arm, as PROTOCOL.md requires of a controller.

Health on ``/diagnostics``: the simulator's statuses, with the listening ``host:port`` as the
controller's hardware id, and :func:`link_status`.
"""
from __future__ import annotations

import socket
import threading
import time

from builtin_interfaces.msg import Time as TimeMsg

from flexarm_bridge import controller_protocol as proto
from flexarm_bridge.link_auth import CONTROLLER, LinkAuth, site_key_for
from flexarm_control.health_report import OK, WARN, Status, status
from flexarm_control.kinematics import JOINT_NAMES
from flexarm_control.node_main import run
from flexarm_control.node_params import declare
from flexarm_sim.dynamics import ArmState
from flexarm_sim.sim_node import SimNode


def link_status(node: str, hardware_id: str, connected: bool, keyed: bool,
                authenticated: bool) -> Status:
    """``<node>: link`` to the PC: WARN without a PC (the arm is held, no command can come)
    or while a keyed link waits for the PC's AUTH; OK when a PC is connected (and, with a
    site key, authenticated)."""
    values = {'PC connected': connected, 'authenticated link': keyed,
              'authenticated': authenticated if keyed else 'n/a'}
    if not connected:
        return status(node, 'link', WARN, 'no PC connected: arm held', values, hardware_id)
    if keyed and not authenticated:
        return status(node, 'link', WARN, 'PC connected, waiting for its AUTH', values,
                      hardware_id)
    return status(node, 'link', OK, 'PC connected' + (', authenticated' if keyed else ''),
                  values, hardware_id)


class FakeController(SimNode):

    def __init__(self) -> None:
        super().__init__('flexarm_fake_controller')

    def _setup_joint_io(self) -> None:
        host = declare(self, 'host', '127.0.0.1', 'address to listen on')
        port = declare(self, 'port', 47800, 'TCP port to listen on')
        self._heartbeat_timeout = declare(self, 'heartbeat_timeout', 1.0,
                                          '[s, wall] silence after which the link is lost')
        key_file = declare(self, 'link_key_file', '',
                           'site key file; required to listen on a non-loopback address')
        try:
            self._site_key = site_key_for(host, key_file)
        except ValueError as exc:
            self.get_logger().fatal(f'refusing to listen: {exc}')
            raise SystemExit(1) from None
        self._hardware_id = f'{host}:{port}'
        self._client: socket.socket | None = None
        self._auth: LinkAuth | None = None        # of the current client, with a site key
        self._send_lock = threading.RLock()
        self._seq = 0
        self._server = socket.create_server((host, port), reuse_port=False)
        self._server.settimeout(0.2)
        self._running = True
        threading.Thread(target=self._serve, daemon=True).start()
        version = proto.VERSION if self._site_key is None else proto.AUTH_VERSION
        self.get_logger().info(f'controller protocol v{version} on {host}:{port}')

    def statuses(self) -> list[Status]:
        """The simulator's statuses and the link to the PC (module docstring)."""
        auth = self._auth
        return [*super().statuses(), link_status(
            self.get_name(), self._hardware_id, self._client is not None,
            self._site_key is not None, auth is not None and auth.established)]

    def _serve(self) -> None:
        """Accept connections: the first one is served, any other refused while it lasts."""
        while self._running:
            try:
                conn, peer = self._server.accept()
            except (TimeoutError, OSError):
                continue
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._send_lock:            # HELLO goes out before any JOINT_STATE
                if self._client is not None:
                    self._refuse(conn, peer)
                    continue
                self.get_logger().info(f'PC connected from {peer}')
                self._client = conn
                if self._site_key is None:
                    self._send(proto.HELLO, version=proto.VERSION, names=list(JOINT_NAMES))
                else:
                    self._auth = LinkAuth(self._site_key, CONTROLLER)
                    self._send(proto.HELLO, version=proto.AUTH_VERSION, names=list(JOINT_NAMES),
                               nonce=self._auth.nonce)
            threading.Thread(target=self._serve_client, args=(conn,), daemon=True).start()

    def _refuse(self, conn: socket.socket, peer: object) -> None:
        """Tell a second PC that another one is connected, and close its connection."""
        self.get_logger().warning(f'connection from {peer} refused: another PC is connected')
        try:
            conn.sendall(proto.encode(proto.ERROR, 0, code=proto.E_BUSY,
                                      text='another PC is connected (one at a time)'))
        except OSError:
            pass
        conn.close()

    def _serve_client(self, conn: socket.socket) -> None:
        conn.settimeout(0.1)
        self._talk(conn)
        with self._send_lock:
            self._client, self._auth = None, None
        conn.close()
        self.hold()
        self.get_logger().warning('link to the PC lost: arm held')

    def _talk(self, conn: socket.socket) -> None:
        decoder, heard = proto.Decoder(self._auth), time.monotonic()
        while self._running and time.monotonic() - heard < self._heartbeat_timeout:
            try:
                data = conn.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                return
            if not data:
                return
            frames, errors = decoder.feed(data)
            for error in errors:
                self.get_logger().warning(f'from the PC: {error}')
                self._send(proto.ERROR, code=proto.E_MALFORMED, text=error)
            for frame in frames:
                heard = time.monotonic()
                if frame.type == proto.AUTH:
                    self._authenticate(frame.fields['nonce'])
                elif frame.type == proto.JOINT_COMMAND:
                    reason = self.apply_command(frame.fields['positions'])
                    self._send(proto.ACK, acked=frame.seq,
                               code=proto.OK if reason is None else proto.E_LIMITS)

    def _authenticate(self, pc_nonce: bytes) -> None:
        """The PC's AUTH: start the session (joint states flow, commands are accepted)."""
        with self._send_lock:
            if self._auth is None or self._auth.established:
                self.get_logger().warning('AUTH ignored: the session is already established')
                return
            self._auth.start_session(pc_nonce)
        self.get_logger().info('PC authenticated')

    def _send(self, frame_type: int, **fields) -> None:
        """Send a frame to the current PC; nothing but HELLO before its AUTH, if keyed."""
        with self._send_lock:
            if self._client is None:
                return
            key = None
            if self._auth is not None:
                key = self._auth.sending_key(frame_type in proto.HANDSHAKE)
                if key is None:
                    return
            self._seq += 1
            try:
                self._client.sendall(proto.encode(frame_type, self._seq, key, **fields))
            except OSError:
                pass      # the reader notices the broken link

    def _publish_joints(self, now: TimeMsg, state: ArmState) -> None:
        self._send(proto.JOINT_STATE, time=now.sec + now.nanosec * 1e-9,
                   positions=state.joint_positions.tolist(),
                   velocities=state.joint_velocities.tolist(),
                   status=proto.STATUS_MOVING if state.is_moving else 0)

    def destroy_node(self) -> None:
        self._running = False
        self._server.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    run(FakeController, args)


if __name__ == '__main__':
    main()
