"""The asyncio client's waits on the queries on the wire (a checksum switch, close) end when
the session's own queries — a keep-alive — are answered, however their reply arrives."""

from __future__ import annotations

import asyncio
import socket
from collections.abc import AsyncIterator

import pytest

from rovlink.aio.client import AsyncClient
from rovlink.client.errors import ConnectionLostError
from rovlink.client.events import ClientEvent
from rovlink.client.links import SocketLink
from rovlink.client.options import ClientOptions
from tests.client.conftest import CONDITION_TIMEOUT_S, wait_until_async

# Long enough that a wait which only ends at the keep-alive's deadline is told from one that
# ends at its reply (which comes within 0.05 s).
_TIMEOUT_S = 5.0


async def _controller(sock: socket.socket, split: bool, delay_s: float = 0.03) -> None:
    """Answers each ``#qd!`` after ``delay_s`` with ``$qd.1!``, in two writes 20 ms apart when
    ``split`` (as a serial port's reads cut a reply), else in one."""
    loop = asyncio.get_running_loop()
    received = b""
    while True:
        data = await loop.sock_recv(sock, 4096)
        if not data:
            return
        received += data
        while b"!" in received:
            frame, _, received = received.partition(b"!")
            if frame.endswith(b"#qd"):
                await asyncio.sleep(delay_s)
                if split:
                    await loop.sock_sendall(sock, b"$qd.")
                    await asyncio.sleep(0.02)
                    await loop.sock_sendall(sock, b"1!")
                else:
                    await loop.sock_sendall(sock, b"$qd.1!")


@pytest.fixture(params=["split reply", "events recorded"])
async def client_with_keepalive_on_the_wire(
    request: pytest.FixtureRequest,
) -> AsyncIterator[AsyncClient]:
    """A client whose keep-alive is on the wire; its reply goes through the session's general
    path: cut in two, or whole while the client records events."""
    host_end, controller_end = socket.socketpair()
    controller_end.setblocking(False)
    split = request.param == "split reply"
    controller = asyncio.create_task(_controller(controller_end, split))
    events: list[ClientEvent] = []
    options = ClientOptions(
        timeout_s=_TIMEOUT_S,
        keepalive_s=0.1,
        boot_timeout_s=None,
        on_event=None if split else events.append,
    )
    client = await AsyncClient(SocketLink(host_end, "socket pair"), options).open()
    assert await wait_until_async(lambda: bool(client._session.pending))
    yield client
    await client.close()
    controller.cancel()
    controller_end.close()


async def test_a_checksum_switch_ends_when_the_keepalive_is_answered(
    client_with_keepalive_on_the_wire: AsyncClient,
) -> None:
    """Before, the switch waited for ever: the keep-alive settled without waking it, and the
    switch held back every query that could have."""
    client = client_with_keepalive_on_the_wire
    loop = asyncio.get_running_loop()
    started = loop.time()
    await asyncio.wait_for(client.set_checksum(False), CONDITION_TIMEOUT_S)
    assert loop.time() - started < _TIMEOUT_S / 2
    assert client._session.counters.timeouts == 0


async def test_close_ends_when_the_keepalive_is_answered(
    client_with_keepalive_on_the_wire: AsyncClient,
) -> None:
    """Before, close waited out the keep-alive's whole timeout."""
    client = client_with_keepalive_on_the_wire
    loop = asyncio.get_running_loop()
    started = loop.time()
    await client.close()
    assert loop.time() - started < _TIMEOUT_S / 2
    assert client._session.counters.timeouts == 0


async def test_a_query_on_a_client_closing_during_a_checksum_switch_fails_at_once() -> None:
    """It does not wait for the switch (itself waiting for a slow reply) to end first."""
    host_end, controller_end = socket.socketpair()
    controller_end.setblocking(False)
    controller = asyncio.create_task(_controller(controller_end, split=False, delay_s=0.5))
    options = ClientOptions(timeout_s=_TIMEOUT_S, keepalive_s=None, boot_timeout_s=None)
    client = await AsyncClient(SocketLink(host_end, "socket pair"), options).open()
    try:
        query = asyncio.create_task(client.depth_cm())
        assert await wait_until_async(lambda: bool(client._session.pending))
        switch = asyncio.create_task(client.set_checksum(False))
        assert await wait_until_async(lambda: client._switching_mode)
        closing = asyncio.create_task(client.close())
        assert await wait_until_async(lambda: client._closed)
        with pytest.raises(ConnectionLostError, match="closed"):
            await client.heading_deg()
        assert client._switching_mode, "the query waited for the switch to end"
        await asyncio.gather(query, switch, closing, return_exceptions=True)
    finally:
        await client.close()
        controller.cancel()
        controller_end.close()
