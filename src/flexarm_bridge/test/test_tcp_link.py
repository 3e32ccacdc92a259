"""The controller's TCP connection is never one that met itself."""
import socket

import pytest

from flexarm_bridge import tcp_link


def test_a_connection_that_met_itself_is_refused(monkeypatch):
    """What the kernel makes of a connect to a free port it also picked as the client's own
    (a TCP simultaneous open): a socket whose own address is its peer's."""
    met = socket.socket()
    met.bind(('127.0.0.1', 0))
    met.connect(met.getsockname())
    assert met.getsockname() == met.getpeername()
    monkeypatch.setattr(socket, 'create_connection', lambda *args, **kwargs: met)
    port = met.getsockname()[1]
    with pytest.raises(ConnectionRefusedError, match='met itself'):
        tcp_link.connect('127.0.0.1', port, timeout=1.0)
    assert met.fileno() == -1                      # closed
    # ... and reset, not left in TIME_WAIT: a plain close kept the controller from listening
    # on its port for a minute ("Address already in use")
    socket.create_server(('127.0.0.1', port)).close()


def test_a_listening_controller_is_connected():
    with socket.create_server(('127.0.0.1', 0)) as server:
        with tcp_link.connect('127.0.0.1', server.getsockname()[1], timeout=1.0) as conn:
            assert conn.getpeername() == server.getsockname()
