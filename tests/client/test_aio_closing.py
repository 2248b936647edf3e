"""The asyncio client while another task closes it: a stop still goes out until the port is
closed, as the blocking client's does."""

from __future__ import annotations

import asyncio
import socket

import pytest

from rovlink.aio import AsyncClient, ConnectionLostError
from rovlink.client.links import SocketLink
from tests.client.conftest import CONDITION_TIMEOUT_S, client_options, wait_until_async
from tests.client.fake_controller import FakeController
from tests.client.test_aio import MakeAsyncClient


async def _client_draining_a_held_query(
    fake_pair: tuple[FakeController, socket.socket],
) -> tuple[AsyncClient, asyncio.Task[int], asyncio.Task[None]]:
    """A client whose close() (in a task of its own) waits for the reply to a query on the
    wire, which the controller holds back; its query and its close."""
    fake, sock = fake_pair
    client = await AsyncClient(SocketLink(sock, "socket pair"), client_options()).open()
    fake.then("hold")
    query = asyncio.ensure_future(client.depth_cm())
    assert await asyncio.to_thread(fake.wait_for, lambda f: "#qd!" in f.frames())
    closing = asyncio.ensure_future(client.close())
    assert await wait_until_async(lambda: client.closed)
    assert not closing.done()  # (still waiting for the held reply)
    return client, query, closing


async def test_a_stop_while_another_task_closes_goes_out(
    fake_pair: tuple[FakeController, socket.socket],
) -> None:
    """Before, it raised ConnectionLostError and was not sent, though the port was open for up
    to ``timeout`` more: a safety task's stop() as the program shut down was lost."""
    fake = fake_pair[0]
    client, query, closing = await _client_draining_a_held_query(fake_pair)
    with pytest.raises(ConnectionLostError, match="closed"):
        await client.move(90, 30)  # nothing but a stop is sent once close() began
    await client.stop()
    assert await asyncio.to_thread(fake.wait_for, lambda f: f.frames()[-1:] == ["#stop!"])
    assert "#th.90.30!" not in fake.frames()
    fake.release()
    await asyncio.wait_for(closing, CONDITION_TIMEOUT_S)
    assert await query == 123  # (the held reply, answered before the port closed)
    with pytest.raises(ConnectionLostError, match="closed"):
        await client.stop()  # the port is closed now


async def test_leaving_async_with_by_an_error_while_another_task_closes_stops_the_robot(
    fake_pair: tuple[FakeController, socket.socket],
) -> None:
    fake = fake_pair[0]
    client, _, closing = await _client_draining_a_held_query(fake_pair)

    async def failing_program() -> None:
        async with client:
            raise KeyError("bug")

    failing = asyncio.ensure_future(failing_program())
    assert await asyncio.to_thread(fake.wait_for, lambda f: f.frames()[-1:] == ["#stop!"])
    fake.release()
    await asyncio.wait_for(closing, CONDITION_TIMEOUT_S)
    with pytest.raises(KeyError):  # (its close() returns once the other one is done)
        await asyncio.wait_for(failing, CONDITION_TIMEOUT_S)


async def test_a_call_while_close_settles_the_wire_names_the_port(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    # (Before: "connection lost: closed", which of a program's clients not said.)
    rov = await make_async_client()
    fake.then("hold")
    held = asyncio.ensure_future(rov.depth_cm())
    assert await wait_until_async(lambda: "#qd!" in fake.frames())
    closing = asyncio.ensure_future(rov.close())
    assert await wait_until_async(lambda: rov.closed)
    with pytest.raises(ConnectionLostError, match=r"^connection lost: socket pair: closed$"):
        await rov.depth_cm()
    fake.release()
    await closing
    assert await held == 123
