"""Every way a link can die, mid-query and mid-keep-alive, on both clients over real transports:
a pseudo-terminal whose far end goes away (an adapter unplugged), a TCP connection closed or
reset by the far end, and a far end that hangs (reads and answers nothing). Each leaves the
client in a clear state: a lost link fails the waiting call and every later one with
ConnectionLostError naming the port and why, the client says it is closed and closes at once;
a hung far end times the query out and the client stays open, and its close stops the robot
it moved and does not hang."""

from __future__ import annotations

import asyncio
import os
import socket
import struct
import time
import tty
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import pytest

import rovlink
import rovlink.aio
from rovlink.client import ConnectionLostError, QueryTimeoutError
from tests.client.conftest import CONDITION_TIMEOUT_S, ThreadCall, wait_until, wait_until_async
from tests.client.fake_controller import FakeController, FakeControllerServer

pytestmark = pytest.mark.integration

_TIMEOUT_S = 0.3
#: How soon close() must return on a dead or hung link (well under the timeouts it could wait).
_CLOSE_BOUND_S = 1.5


@dataclass
class Far:
    """The far end of a link: its controller, the URL to it and the port's name in errors."""

    fake: Callable[[], FakeController]
    url: str
    name: str


@contextmanager
def _far_end(transport: str) -> Iterator[Far]:
    if transport == "pty":
        master, slave = os.openpty()
        tty.setraw(slave)
        fake = FakeController(master)
        path = os.ttyname(slave)
        try:
            yield Far(lambda: fake, path, f"{path} at 115200 baud")
        finally:
            fake.close()
            os.close(slave)
        return
    server = FakeControllerServer()

    def accepted() -> FakeController:
        assert wait_until(lambda: bool(server.fakes))
        return server.fakes[0]

    try:
        yield Far(accepted, server.url, f"tcp {server.url.removeprefix('socket://')}")
    finally:
        server.close()


@pytest.fixture(params=["pty", "tcp"])
def far(request: pytest.FixtureRequest) -> Iterator[Far]:
    """A far end that stays, on a pseudo-terminal or TCP."""
    with _far_end(request.param) as end:
        yield end


def _unplug(fake: FakeController) -> None:
    """The far end goes away: a pseudo-terminal's master side closed, a TCP connection closed."""
    fake.close()


def _reset(fake: FakeController) -> None:
    """The far end resets the TCP connection (an RST)."""
    sock = socket.socket(fileno=os.dup(fake._fd))
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    sock.close()  # (the option stays with the connection, which the fake then closes)
    fake.close()


#: How a link dies: the transport, and what its far end does.
DEATHS: dict[str, tuple[str, Callable[[FakeController], None]]] = {
    "pty unplugged": ("pty", _unplug),
    "tcp closed": ("tcp", _unplug),
    "tcp reset": ("tcp", _reset),
}


@pytest.fixture(params=DEATHS)
def dying(request: pytest.FixtureRequest) -> Iterator[tuple[Far, Callable[[], None]]]:
    """A far end, and how to make its link die."""
    transport, death = DEATHS[request.param]
    with _far_end(transport) as end:
        yield end, lambda: death(end.fake())


def _settings(**options: object) -> dict[str, object]:
    """The tests' connection settings, with ``options``."""
    return {"keepalive": None, "boot_timeout": None, "timeout": _TIMEOUT_S, "retries": 0, **options}


def _connect(far: Far, **options: object) -> rovlink.Client:
    return rovlink.connect(far.url, **_settings(**options))  # type: ignore[arg-type]


def _assert_closed_clearly(rov: rovlink.Client, far: Far) -> None:
    assert wait_until(lambda: rov.closed)
    with pytest.raises(ConnectionLostError, match=far.name):
        rov.depth_cm()
    with pytest.raises(ConnectionLostError, match=far.name):
        rov.stop()
    started = time.monotonic()
    rov.close()
    assert time.monotonic() - started < _CLOSE_BOUND_S


def test_blocking_a_link_dying_mid_query(dying: tuple[Far, Callable[[], None]]) -> None:
    far, die = dying
    rov = _connect(far, timeout=CONDITION_TIMEOUT_S)
    far.fake().then("hold")  # the reply is held back: the link dies while the query waits
    asker = ThreadCall(rov.depth_cm)
    assert far.fake().wait_for(lambda f: "#qd!" in f.frames())
    die()
    assert asker.done.wait(CONDITION_TIMEOUT_S)
    assert isinstance(asker.error, ConnectionLostError)
    assert far.name in str(asker.error)
    _assert_closed_clearly(rov, far)


def test_blocking_a_link_dying_mid_keepalive(dying: tuple[Far, Callable[[], None]]) -> None:
    far, die = dying
    rov = _connect(far, keepalive=0.05)
    assert far.fake().wait_for(lambda f: f.frames().count("#qd!") >= 2)  # the keep-alive runs
    die()
    _assert_closed_clearly(rov, far)


def test_blocking_a_far_end_that_hangs(far: Far) -> None:
    rov = _connect(far)
    rov.start()
    rov.move(0, 40)
    far.fake().then("hold")  # answers nothing from now on
    with pytest.raises(QueryTimeoutError, match="timeout"):
        rov.depth_cm()
    assert not rov.closed  # a slow controller is no lost link
    started = time.monotonic()
    rov.close()
    assert time.monotonic() - started < _CLOSE_BOUND_S
    assert far.fake().wait_for(lambda f: f.frames()[-1:] == ["#stop!"])


async def _aconnect(far: Far, **options: object) -> rovlink.aio.AsyncClient:
    return await rovlink.aio.connect(far.url, **_settings(**options))  # type: ignore[arg-type]


async def _assert_closed_clearly_async(rov: rovlink.aio.AsyncClient, far: Far) -> None:
    assert await wait_until_async(lambda: rov.closed)
    with pytest.raises(ConnectionLostError, match=far.name):
        await rov.depth_cm()
    with pytest.raises(ConnectionLostError, match=far.name):
        await rov.stop()
    started = time.monotonic()
    await rov.close()
    assert time.monotonic() - started < _CLOSE_BOUND_S


async def test_asyncio_a_link_dying_mid_query(dying: tuple[Far, Callable[[], None]]) -> None:
    far, die = dying
    rov = await _aconnect(far, timeout=CONDITION_TIMEOUT_S)
    far.fake().then("hold")
    asker = asyncio.ensure_future(rov.depth_cm())
    assert await asyncio.to_thread(far.fake().wait_for, lambda f: "#qd!" in f.frames())
    die()
    with pytest.raises(ConnectionLostError, match=far.name):
        await asyncio.wait_for(asker, CONDITION_TIMEOUT_S)
    await _assert_closed_clearly_async(rov, far)


async def test_asyncio_a_link_dying_mid_keepalive(dying: tuple[Far, Callable[[], None]]) -> None:
    far, die = dying
    rov = await _aconnect(far, keepalive=0.05)
    assert await asyncio.to_thread(far.fake().wait_for, lambda f: f.frames().count("#qd!") >= 2)
    die()
    await _assert_closed_clearly_async(rov, far)


async def test_asyncio_a_far_end_that_hangs(far: Far) -> None:
    rov = await _aconnect(far)
    await rov.start()
    await rov.move(0, 40)
    far.fake().then("hold")
    with pytest.raises(QueryTimeoutError, match="timeout"):
        await rov.depth_cm()
    assert not rov.closed
    started = time.monotonic()
    await rov.close()
    assert time.monotonic() - started < _CLOSE_BOUND_S
    assert await asyncio.to_thread(far.fake().wait_for, lambda f: f.frames()[-1:] == ["#stop!"])
