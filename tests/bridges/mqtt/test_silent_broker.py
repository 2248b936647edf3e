"""The MQTT bridge on a broker that accepts connections and answers nothing (as mosquitto
stopped with SIGSTOP), then answers late: what the bridge gave up must not come back to it."""

from __future__ import annotations

import asyncio
import contextlib
import gc
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from typing import Any

import pytest

from tests.bridges.mqtt.rig import bridged_robot, until

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
