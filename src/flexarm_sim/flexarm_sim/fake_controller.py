"""A robot controller that speaks the flexarm wire protocol (PROTOCOL.md), for tests and demos.

The simulator (:class:`~flexarm_sim.sim_node.SimNode`) with its joint interface moved from ROS
topics to a TCP server: it serves JOINT_STATE frames and executes JOINT_COMMAND frames, so
``flexarm_bridge`` can stand between it and the graph; what the real world provides outside a
robot controller stays on ROS (``/clock``, the tip camera, the ground truth). One PC at a time,
on loopback unless a site key (``link_key_file``) is given; the frames are
:mod:`flexarm_bridge.controller_protocol`, the authentication :mod:`flexarm_bridge.link_auth`.

Explained in docs/nodes.md#the-fake-controller-flexarm_fake_controller.
"""
from __future__ import annotations

import socket
import threading
import time
from dataclasses import dataclass, field

from builtin_interfaces.msg import Time as TimeMsg

from flexarm_bridge import controller_protocol as proto
from flexarm_bridge.link_auth import CONTROLLER, OPEN_KEY, LinkAuth, site_key_for
from flexarm_core.health_report import OK, WARN, Status, status
from flexarm_core.kinematics import JOINT_NAMES
from flexarm_core.ros.node_main import run
from flexarm_core.ros.node_params import declare
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


@dataclass
class Peer:
    """The PC of one connection: its socket, authentication (with a site key), and frames."""
    conn: socket.socket
    auth: LinkAuth | None
    since: float = field(default_factory=time.monotonic)
    encoder: proto.Encoder = field(init=False)

    def __post_init__(self) -> None:
        self.encoder = proto.Encoder(self.auth)

    @property
    def authenticated(self) -> bool:
        """Whether the PC may command the arm: keyless (loopback), or its AUTH verified."""
        return self.auth is None or self.auth.established


def holds_slot(peer: Peer, now: float, timeout: float) -> bool:
    """Whether ``peer`` keeps a new connection out: authenticated, or still within the time
    it has to authenticate."""
    return peer.authenticated or now - peer.since < timeout


class FakeController(SimNode):

    def __init__(self) -> None:
        super().__init__('flexarm_fake_controller')

    def _setup_joint_io(self) -> None:
        host = declare(self, 'host', 'config/bridge.yaml')
        port = declare(self, 'port', 'config/bridge.yaml')
        self._heartbeat_timeout = declare(self, 'heartbeat_timeout', 'config/bridge.yaml')
        key_file = declare(self, 'link_key_file', 'config/bridge.yaml')
        try:
            self._site_key = site_key_for(host, key_file)
        except ValueError as exc:
            self.get_logger().fatal(f'refusing to listen: {exc}')
            raise SystemExit(1) from None
        self._hardware_id = f'{host}:{port}'
        self._peer: Peer | None = None        # the PC holding the link (or handshaking)
        self._send_lock = threading.RLock()   # guards _peer and every send
        self._server = socket.create_server((host, port), reuse_port=False)
        self._server.settimeout(0.2)
        self._running = True
        threading.Thread(target=self._serve, daemon=True).start()
        version = proto.VERSION if self._site_key is None else proto.AUTH_VERSION
        self.get_logger().info(f'controller protocol v{version} on {host}:{port}')

    def statuses(self) -> list[Status]:
        """The simulator's statuses and the link to the PC (docs/nodes.md)."""
        peer = self._peer
        return [*super().statuses(), link_status(
            self.get_name(), self._hardware_id, peer is not None, self._site_key is not None,
            peer is not None and peer.auth is not None and peer.auth.established)]

    def _serve(self) -> None:
        """Accept connections: one PC is served, any other refused while it holds the slot."""
        while self._running:
            try:
                conn, address = self._server.accept()
            except (TimeoutError, OSError):
                continue
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._send_lock:            # HELLO goes out before any JOINT_STATE
                old = self._peer
                if old is not None and holds_slot(old, time.monotonic(),
                                                  self._heartbeat_timeout):
                    self._refuse(conn, address)
                    continue
                if old is not None:
                    self.get_logger().warning(
                        f'PC dropped: not authenticated within {self._heartbeat_timeout:g} s')
                    _shut(old.conn)           # its thread ends and leaves the new peer alone
                self.get_logger().info(f'PC connected from {address}')
                auth = None if self._site_key is None else LinkAuth(self._site_key, CONTROLLER)
                peer = self._peer = Peer(conn, auth)
                if auth is None:
                    self._send(peer, proto.HELLO, version=proto.VERSION, names=list(JOINT_NAMES))
                else:
                    self._send(peer, proto.HELLO, version=proto.AUTH_VERSION,
                               names=list(JOINT_NAMES), nonce=auth.nonce)
            threading.Thread(target=self._serve_client, args=(peer,), daemon=True).start()

    def _refuse(self, conn: socket.socket, address: object) -> None:
        """Tell another PC that the slot is taken, and close its connection (the ERROR is
        unauthenticated with a site key: there is no session to tag it with)."""
        self.get_logger().warning(f'connection from {address} refused: another PC is connected')
        key = None if self._site_key is None else OPEN_KEY
        try:
            conn.sendall(proto.encode(proto.ERROR, 0, key, code=proto.E_BUSY,
                                      text='another PC is connected (one at a time)'))
        except OSError:
            pass
        conn.close()

    def _serve_client(self, peer: Peer) -> None:
        peer.conn.settimeout(0.1)
        reason = self._talk(peer)
        with self._send_lock:
            current = self._peer is peer
            if current:
                self._peer = None
        peer.conn.close()
        if current:
            self.hold()
            self.get_logger().warning(f'link to the PC lost ({reason}): arm held')

    def _talk(self, peer: Peer) -> str:
        """Serve one PC until the link fails; the reason it did. Without a key any valid frame
        is a sign of life; with one only authenticated session frames are, and the session must
        start within the heartbeat timeout of the connection (refused frames never count)."""
        decoder, heard = proto.Decoder(peer.auth), peer.since
        while self._running:
            if time.monotonic() - heard >= self._heartbeat_timeout:
                return (f'no frame for {self._heartbeat_timeout:g} s' if peer.authenticated
                        else f'not authenticated within {self._heartbeat_timeout:g} s')
            try:
                data = peer.conn.recv(4096)
            except TimeoutError:
                continue
            except OSError as exc:
                return str(exc)
            if not data:
                return 'closed by the PC'
            frames, errors = decoder.feed(data)
            for error in errors:
                self.get_logger().warning(f'from the PC: {error}')
                self._send(peer, proto.ERROR, code=proto.E_MALFORMED, text=error)
            for frame in frames:
                if peer.auth is None or frame.authenticated:
                    heard = time.monotonic()
                if frame.type == proto.AUTH:          # its proof verified by the decoder
                    with self._send_lock:
                        self._send(peer, proto.AUTH_OK, **peer.auth.answer())
                    heard = time.monotonic()          # the session starts
                    self.get_logger().info('PC authenticated')
                elif frame.type == proto.JOINT_COMMAND:
                    reason = self.apply_command(frame.fields['positions'])
                    self._send(peer, proto.ACK, acked=frame.seq,
                               code=proto.OK if reason is None else proto.E_LIMITS)
        return 'shutting down'

    def _send(self, peer: Peer | None, frame_type: int, **fields) -> None:
        """Send a frame to ``peer`` if it still holds the link; with a key nothing but
        handshake frames and ERROR before its session (:class:`~proto.Encoder`)."""
        with self._send_lock:
            if peer is None or peer is not self._peer:
                return
            data = peer.encoder.encode(frame_type, **fields)
            if data is None:
                return
            try:
                peer.conn.sendall(data)
            except OSError:
                pass      # the reader notices the broken link

    def _joints_wanted(self) -> bool:
        return self._peer is not None

    def _publish_joints(self, now: TimeMsg, state: ArmState) -> None:
        self._send(self._peer, proto.JOINT_STATE, time=now.sec + now.nanosec * 1e-9,
                   positions=state.joint_positions.tolist(),
                   velocities=state.joint_velocities.tolist(),
                   status=proto.STATUS_MOVING if state.is_moving else 0)

    def destroy_node(self) -> None:
        self._running = False
        self._server.close()
        super().destroy_node()


def _shut(conn: socket.socket) -> None:
    """End a connection that another thread reads (it sees the end and closes it)."""
    try:
        conn.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass          # already down


def main(args: list[str] | None = None) -> None:
    run(FakeController, args)


if __name__ == '__main__':
    main()
