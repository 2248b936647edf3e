"""The asyncio client used from an event loop other than the one it was opened in: refused with
an error that says so, before anything is written; ``stop()`` still stops the robot."""

from __future__ import annotations

import asyncio
import socket
from collections.abc import Callable, Coroutine
from typing import Any

import pytest

from rovlink.aio import AsyncClient, ConnectionLostError
from rovlink.client.links import SocketLink
from tests.client.conftest import CONDITION_TIMEOUT_S, client_options
from tests.client.fake_controller import FakeController

WRONG_LOOP = "belongs to the event loop it was opened in"

Call = Callable[[AsyncClient], Coroutine[Any, Any, object]]


async def _first_reading(client: AsyncClient) -> object:
    async for reading in client.telemetry(10):
        return reading
    return None


CALLS: dict[str, Call] = {
    "depth_cm": lambda client: client.depth_cm(),
    "sensors": lambda client: client.sensors(),
    "move": lambda client: client.move(90, 30),
    "start": lambda client: client.start(),
    "send_raw": lambda client: client.send_raw("#qd!"),
    "set_checksum": lambda client: client.set_checksum(True),
    "telemetry": _first_reading,
    "close": lambda client: client.close(),
}


async def _client(fake: FakeController, sock: socket.socket) -> AsyncClient:
    """A client, once the fake has read its checksum mode frame."""
    client = await AsyncClient(SocketLink(sock, "socket pair"), client_options()).open()
    assert await asyncio.to_thread(fake.wait_for, lambda f: f.frames() == ["#crcoff!"])
    return client


def _in_another_thread(call: Call, client: AsyncClient) -> Coroutine[Any, Any, object]:
    """Run ``call(client)`` in an event loop of its own, in a thread of its own."""

    async def bounded() -> object:
        return await asyncio.wait_for(call(client), CONDITION_TIMEOUT_S)

    return asyncio.to_thread(asyncio.run, bounded())


@pytest.mark.parametrize("method", CALLS)
async def test_a_call_from_another_threads_loop_is_refused_before_anything_is_sent(
    fake_pair: tuple[FakeController, socket.socket], method: str
) -> None:
    """Before, a query was written from the other thread, then failed with asyncio's 'got
    Future attached to a different loop' and gave its max_in_flight slot back while it was on
    the wire; a set command was written from the other thread, racing the client's own."""
    fake, sock = fake_pair
    client = await _client(fake, sock)
    frames_before = len(fake.frames())
    with pytest.raises(RuntimeError, match=WRONG_LOOP):
        await _in_another_thread(CALLS[method], client)
    # Still the client's own, whole: the next query is answered, and it was the only one sent.
    assert await asyncio.wait_for(client.depth_cm(), CONDITION_TIMEOUT_S) == 123
    assert fake.frames()[frames_before:] == ["#qd!"]
    assert client._in_flight.free == 8
    await client.close()


async def test_a_stop_from_another_threads_loop_stops_the_robot(
    fake_pair: tuple[FakeController, socket.socket],
) -> None:
    fake, sock = fake_pair
    client = await _client(fake, sock)
    await client.move(90, 30)
    await _in_another_thread(lambda client: client.stop(), client)
    assert await asyncio.to_thread(fake.wait_for, lambda f: f.frames()[-1:] == ["#stop!"])
    await client.close()
    with pytest.raises(ConnectionLostError, match="closed"):
        await _in_another_thread(lambda client: client.stop(), client)


def test_a_client_connected_in_an_earlier_asyncio_run_says_so(
    fake_pair: tuple[FakeController, socket.socket],
) -> None:
    """``rov = asyncio.run(connect(url))`` then ``asyncio.run(program(rov))``: the loop the
    client was opened in is closed, nothing would ever read its replies."""
    fake, sock = fake_pair
    client = asyncio.run(_client(fake, sock))
    with pytest.raises(RuntimeError, match=f"{WRONG_LOOP}.*a later asyncio.run"):
        asyncio.run(client.depth_cm())
    asyncio.run(client.stop())  # the robot is stopped all the same
    assert fake.wait_for(lambda f: f.frames()[-1:] == ["#stop!"])
    assert "#qd!" not in fake.frames()[1:]
    asyncio.run(client.close())  # and the port can be released: nothing else would
    assert sock.fileno() == -1
    assert client.closed
    with pytest.raises(ConnectionLostError, match="closed"):
        asyncio.run(client.depth_cm())
