"""The MQTT bridge on a broker that accepts connections and answers nothing (as mosquitto
stopped with SIGSTOP), then answers late: what the bridge gave up must not come back to it."""

from __future__ import annotations

import asyncio
import contextlib
import gc
import socket
from collections.abc import AsyncIterator, Iterator
from dataclasses import dataclass, field
from typing import Any

import pytest

from tests.bridges.mqtt.rig import CONDITION_TIMEOUT_S, bridged_robot, until

pytestmark = pytest.mark.integration

#: MQTT 5 CONNACK: session not present, success, no properties.
_CONNACK = b"\x20\x03\x00\x00\x00"
#: Short, so that a connection attempt is given up at once.
_REPLY_TIMEOUT_S = 0.2
#: The bridge closes what it gives up at once; paho would after its keep-alive, 10 s.
_CLOSED_TIMEOUT_S = 3.0


@dataclass
class _Connection:
    writer: asyncio.StreamWriter
    received: bytearray = field(default_factory=bytearray)
    #: The client closed its side (end of stream).
    closed: bool = False


class SilentBroker:
    """Accepts every connection, reads what comes and sends nothing until :meth:`answer_late`."""

    def __init__(self) -> None:
        self.connections: list[_Connection] = []
        self.port = 0

    async def serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        connection = _Connection(writer)
        self.connections.append(connection)
        with contextlib.suppress(ConnectionError):
            while data := await reader.read(4096):
                connection.received += data
        connection.closed = True

    async def answer_late(self) -> None:
        """The broker resumes: a CONNACK on every connection, then it is dropped (the broker
        ends, or another connection takes the session over)."""
        for connection in self.connections:
            with contextlib.suppress(ConnectionError):
                connection.writer.write(_CONNACK)
                await connection.writer.drain()
            connection.writer.close()


@contextlib.asynccontextmanager
async def silent_broker() -> AsyncIterator[SilentBroker]:
    broker = SilentBroker()
    server = await asyncio.start_server(broker.serve, "127.0.0.1", 0)
    broker.port = server.sockets[0].getsockname()[1]
    try:
        yield broker
    finally:
        for connection in broker.connections:
            connection.writer.close()
        server.close()


async def _callbacks_done(loop: asyncio.AbstractEventLoop) -> None:
    """Back once what the event loop had ready to run (reader callbacks, tasks cancelled by
    them) has run: a future resolved from here runs its callbacks after them."""
    for _ in range(3):
        done = loop.create_future()
        loop.call_soon(done.set_result, None)
        await done


async def test_connections_given_up_on_a_silent_broker_are_closed_and_say_nothing_later():
    # A connection whose CONNACK did not come in time, or whose attempt was cancelled as the
    # bridge ended, kept its socket open: the broker's late CONNACK and close then landed on a
    # client nobody awaited, and exiting logged "Future exception was never retrieved" (and a
    # CancelledError raised in the event loop's reader callback).
    loop = asyncio.get_running_loop()
    errors: list[dict[str, Any]] = []
    loop.set_exception_handler(lambda _loop, context: errors.append(context))
    try:
        async with silent_broker() as broker:
            async with bridged_robot(
                broker, "s1", reply_timeout_s=_REPLY_TIMEOUT_S, wait_connected=False
            ):
                # The first attempt given up; a second one sent its CONNECT and waits for the
                # CONNACK (cancelled as the bridge ends).
                await until(lambda: len(broker.connections) >= 2)
                await until(lambda: bool(broker.connections[1].received))
            # Nothing is left open for the broker to answer (paho itself gives up a connection
            # without a CONNACK only after the 10 s keep-alive).
            await until(lambda: all(c.closed for c in broker.connections), _CLOSED_TIMEOUT_S)
            await broker.answer_late()
            await until(lambda: all(c.closed for c in broker.connections))
        await _callbacks_done(loop)
        gc.collect()  # (a future's unretrieved exception is said when it is collected)
        assert [context["message"] for context in errors] == []
    finally:
        loop.set_exception_handler(None)


#: /proc/net/tcp's state of a socket that sent its SYN and has no answer yet.
_SYN_SENT = "02"


def _connecting_ports(port: int) -> set[int]:
    """The local ports of this machine's TCP sockets waiting for a SYN-ACK from ``port``."""
    ports = set()
    with open("/proc/net/tcp", encoding="ascii") as table:
        for line in table.readlines()[1:]:
            local, remote, state = line.split()[1:4]
            if state == _SYN_SENT and int(remote.split(":")[1], 16) == port:
                ports.add(int(local.split(":")[1], 16))
    return ports


@contextlib.contextmanager
def _full_listener() -> Iterator[tuple[socket.socket, set[int]]]:
    """A listening socket whose queue of connections not yet accepted is full (as a stopped
    broker's fills): a new connection's SYN is dropped, and its handshake waits for a
    retransmission after the queue has room. With the local ports of the connections that
    filled it."""
    listener = socket.create_server(("127.0.0.1", 0), backlog=0)
    port = listener.getsockname()[1]
    fillers = [socket.create_connection(("127.0.0.1", port))]  # (the one it has room for)
    try:
        yield listener, {filler.getsockname()[1] for filler in fillers}
    finally:
        for filler in fillers:
            filler.close()
        listener.close()


async def test_a_connection_cancelled_in_its_tcp_handshake_is_closed_when_it_completes():
    # aiomqtt makes the TCP connection (and writes CONNECT) in an executor thread, which a
    # cancellation does not stop: a bridge ended during the handshake left the connection to
    # complete later, open, its CONNECT (client id and last will) sent to a broker that resumed.
    with _full_listener() as (listener, fillers):
        port = listener.getsockname()[1]
        broker = _Port(port)
        async with bridged_robot(broker, "s2", wait_connected=False):
            await until(lambda: bool(_connecting_ports(port) - fillers))
        # The broker resumes: it accepts what waited, and the late handshake completes.
        listener.setblocking(False)
        loop = asyncio.get_running_loop()
        late: list[socket.socket] = []
        deadline = loop.time() + CONDITION_TIMEOUT_S
        try:
            while not late:
                assert loop.time() < deadline, "the cancelled connection never came"
                with contextlib.suppress(BlockingIOError):
                    accepted, (_, client_port) = listener.accept()
                    if client_port not in fillers:
                        accepted.setblocking(False)  # (for the event loop's sock_recv)
                        late.append(accepted)
                    else:
                        accepted.close()
                await asyncio.sleep(0.01)
            (connection,) = late
            # The connection given up is closed (its CONNECT perhaps written first): its end of
            # stream comes.
            try:
                received = await asyncio.wait_for(_read_to_end(loop, connection), _CLOSED_TIMEOUT_S)
            except (TimeoutError, asyncio.TimeoutError):
                raise AssertionError(
                    "the connection given up in its handshake was left open"
                ) from None
            assert received[:1] in (b"", b"\x10")  # nothing, or CONNECT: no more
        finally:
            for accepted in late:
                accepted.close()


@dataclass
class _Port:
    port: int


async def _read_to_end(loop: asyncio.AbstractEventLoop, connection: socket.socket) -> bytes:
    """What comes on ``connection`` before its end of stream (not CONNACK: none is sent)."""
    received = b""
    while data := await loop.sock_recv(connection, 4096):
        received += data
    return received
