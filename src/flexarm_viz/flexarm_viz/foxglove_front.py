"""A TCP front of the Foxglove SDK's WebSocket server that also admits clients offering only
``foxglove.websocket.v1``, the protocol's former name, which the SDK answers with HTTP 400.

The two names carry the same protocol; the SDK has no setting to accept the old one. So the
front rewrites the one header of the opening handshake that names it (the request's
``Sec-WebSocket-Protocol`` to ``foxglove.sdk.v1``, the answer's back to the old name) and then
copies bytes both ways untouched: frames, compression and backpressure stay the SDK's, and
a client offering ``foxglove.sdk.v1`` passes as it came. The copy costs ~2 % of a core at the
camera's 9 MB/s (30 frames of 300 kB per second: 2.5-3.3 % of a core directly, 4.4-6.0 % through
the front, the client included).
"""
from __future__ import annotations

import asyncio
import threading
from collections.abc import Iterable

SDK_SUBPROTOCOL = b'foxglove.sdk.v1'
LEGACY_SUBPROTOCOL = b'foxglove.websocket.v1'
_PROTOCOL_HEADER = b'sec-websocket-protocol'
_HEAD_END = b'\r\n\r\n'
_HEAD_LIMIT = 1 << 16           # bytes of an HTTP head
_HANDSHAKE_TIMEOUT = 10.0       # [s] for a head to arrive
_CHUNK = 1 << 18


def offered(head: bytes) -> list[bytes]:
    """The subprotocols an HTTP head names, in order."""
    return [name.strip() for line in _header_lines(head, _PROTOCOL_HEADER)
            for name in line.partition(b':')[2].split(b',') if name.strip()]


def _header_lines(head: bytes, name: bytes) -> Iterable[bytes]:
    return (line for line in head.split(b'\r\n')[1:]
            if line.partition(b':')[0].strip().lower() == name)


def renamed(head: bytes, subprotocol: bytes) -> bytes:
    """The head with its ``Sec-WebSocket-Protocol`` headers replaced by one naming only
    ``subprotocol``."""
    lines = head[:-len(_HEAD_END)].split(b'\r\n')
    kept = [lines[0], *(line for line in lines[1:]
                        if line.partition(b':')[0].strip().lower() != _PROTOCOL_HEADER)]
    return b'\r\n'.join([*kept, b'Sec-WebSocket-Protocol: ' + subprotocol]) + _HEAD_END


def _legacy_only(head: bytes) -> bool:
    names = offered(head)
    return LEGACY_SUBPROTOCOL in names and SDK_SUBPROTOCOL not in names


async def _pipe(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    """Copy until end of stream, then close the writer (the other side sees the end)."""
    try:
        while data := await reader.read(_CHUNK):
            writer.write(data)
            await writer.drain()    # a slow client slows the reads: the SDK drops for it
    except ConnectionError:
        pass
    finally:
        writer.close()


class SubprotocolFront:
    """Listens on ``host:port`` in a thread of its own and relays each connection to the
    WebSocket server on ``127.0.0.1:upstream_port``; OSError when it cannot listen. Made, it
    listens: the constructor returns once the socket is bound and listening (``port`` is its
    port), so a client may connect at once."""

    def __init__(self, host: str, port: int, upstream_port: int) -> None:
        self._upstream_port = upstream_port
        self._loop = asyncio.new_event_loop()
        self._clients: dict[asyncio.Task[None], asyncio.StreamWriter] = {}
        self._thread = threading.Thread(target=self._loop.run_forever, name='foxglove_front',
                                        daemon=True)
        self._thread.start()
        try:
            self._server = asyncio.run_coroutine_threadsafe(asyncio.start_server(
                self._relay, host, port, limit=_HEAD_LIMIT), self._loop).result()
        except OSError:
            self._halt()
            raise
        self.port: int = self._server.sockets[0].getsockname()[1]

    async def _relay(self, client_in: asyncio.StreamReader,
                     client_out: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        self._clients[task] = client_out
        server_out: asyncio.StreamWriter | None = None
        try:
            async with asyncio.timeout(_HANDSHAKE_TIMEOUT):
                request = await client_in.readuntil(_HEAD_END)
                server_in, server_out = await asyncio.open_connection(
                    '127.0.0.1', self._upstream_port, limit=_HEAD_LIMIT)
                if _legacy_only(request):
                    server_out.write(renamed(request, SDK_SUBPROTOCOL))
                    answer = await server_in.readuntil(_HEAD_END)
                    client_out.write(renamed(answer, LEGACY_SUBPROTOCOL)
                                     if offered(answer) else answer)
                else:
                    server_out.write(request)
            await asyncio.gather(_pipe(client_in, server_out), _pipe(server_in, client_out))
        except (OSError, TimeoutError, asyncio.IncompleteReadError, asyncio.LimitOverrunError):
            pass                    # a broken handshake: the client sees the connection close
        finally:
            client_out.close()
            if server_out is not None:
                server_out.close()
            del self._clients[task]

    def stop(self) -> None:
        """Stop listening and close every connection (each relay then ends at its end of
        stream: cancelled, it would make Python 3.11's stream callback raise)."""
        async def close() -> None:
            self._server.close()
            for client_out in self._clients.values():
                client_out.close()
            await asyncio.gather(*self._clients)

        asyncio.run_coroutine_threadsafe(close(), self._loop).result()
        self._halt()

    def _halt(self) -> None:
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join()
        self._loop.close()
