"""Closing a client that moved the robot stops it: ``#stop!`` goes out first, in both clients,
whether the program calls ``close()`` or leaves its ``with`` block, over the in-process
simulator, a real pseudo-terminal and TCP. Before, ``close()`` let go of the port and the robot
drove on with the thrust last sent until the controller's link-loss watchdog (2 s) stopped it."""

from __future__ import annotations

import asyncio
import logging
import socket
from collections.abc import Callable

import pytest

import rovlink
import rovlink.aio
from rovlink.aio import AsyncClient, transport
from rovlink.client import Client, ClientOptions
from rovlink.client.links import SocketLink
from rovlink.controller import ControllerState
from rovlink.sim import SimulatedPort
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    REPLY_TIMEOUT_S,
    ThreadCall,
    client_options,
    fill_line,
    wait_until,
)
from tests.client.fake_controller import FakeController

pytestmark = pytest.mark.integration


def _state(rov: Client | AsyncClient) -> ControllerState:
    port = rov._link.port  # type: ignore[attr-defined]
    assert isinstance(port, SimulatedPort)
    with port.lock:
        return port.controller.state()


def _driving(state: ControllerState) -> tuple[bool, int, int]:
    return state.locked, state.power_percent, state.vertical_thrust_percent


_SIM = "sim://?seed=3"
#: How soon leaving a block on a line that takes nothing must end (well under a write timeout).
_LEAVING_BOUND_S = 1.5
_MOVING = (False, 40, -30)
_STOPPED = (True, 0, 0)


@pytest.mark.parametrize("how", ["close()", "leaving with"])
def test_closing_the_blocking_client_stops_the_robot_it_moved(how: str) -> None:
    rov = rovlink.connect(_SIM, keepalive=None, timeout=REPLY_TIMEOUT_S)
    with rov:
        rov.start()
        rov.move(90, 40)
        rov.set_direct_mode(True)
        rov.set_vertical_thrust(-30)
        assert rov.depth_cm() >= 0  # (everything before it has reached the controller)
        assert _driving(_state(rov)) == _MOVING
        if how == "close()":
            rov.close()
    assert _driving(_state(rov)) == _STOPPED


@pytest.mark.parametrize("how", ["close()", "leaving async with"])
async def test_closing_the_asyncio_client_stops_the_robot_it_moved(how: str) -> None:
    async with rovlink.aio.connect(_SIM, keepalive=None, timeout=REPLY_TIMEOUT_S) as rov:
        await rov.start()
        await rov.move(90, 40)
        await rov.set_direct_mode(True)
        await rov.set_vertical_thrust(-30)
        assert await rov.depth_cm() >= 0
        assert _driving(_state(rov)) == _MOVING
        if how == "close()":
            await rov.close()
    assert _driving(_state(rov)) == _STOPPED


def test_over_a_pseudo_terminal_both_clients_stop_on_close(
    pty_fake: tuple[FakeController, str],
) -> None:
    fake, path = pty_fake
    rov = rovlink.connect(path, keepalive=None, boot_timeout=None, timeout=REPLY_TIMEOUT_S)
    rov.start()
    rov.move(0, 50)
    rov.close()
    assert fake.wait_for(lambda f: len(f.frames()) == 4)
    assert fake.frames() == ["#crcoff!", "#start!", "#th.0.50!", "#stop!"]

    async def pilot() -> None:
        rov = await rovlink.aio.connect(
            path, keepalive=None, boot_timeout=None, timeout=REPLY_TIMEOUT_S
        )
        await rov.hold_depth(120)
        await rov.close()

    asyncio.run(pilot())
    assert fake.wait_for(lambda f: len(f.frames()) == 7)
    assert fake.frames()[4:] == ["#crcoff!", "#mvd.120!", "#stop!"]


def _frames_after_close(options: ClientOptions, program: list[str]) -> list[str]:
    """The frames a fake on a socket pair got from a blocking client that sent ``program``
    (commands as text) and closed, after its ``#crcoff!``."""
    fake, host_end = FakeController.on_socketpair()
    try:
        rov = Client(SocketLink(host_end, "socket pair"), options)
        for command in program:
            rov.send_raw(command)
        rov.depth_cm()  # (all before it has arrived)
        rov.close()
        fake._thread.join(CONDITION_TIMEOUT_S)  # (it ends at the end of the stream: all read)
        return fake.frames()[1:]
    finally:
        fake.close()


@pytest.mark.parametrize(
    ("program", "stop_on_close", "expected"),
    [
        (["#th.0.40!"], True, ["#th.0.40!", "#qd!", "#stop!"]),
        (["#start!"], True, ["#start!", "#qd!", "#stop!"]),  # unlocked: locked again
        (["#start!", "#th.0.40!", "#stop!"], True, ["#start!", "#th.0.40!", "#stop!", "#qd!"]),
        (["#mgmp.100!", "#q.l!"], True, ["#mgmp.100!", "#q.l!", "#qd!"]),  # nothing moved
        # (Motion while locked as last sent is dropped by the controller, P7: nothing moved.)
        (["#stop!", "#th.0.40!"], True, ["#stop!", "#th.0.40!", "#qd!"]),
        (["#stop!", "#start!"], True, ["#stop!", "#start!", "#qd!", "#stop!"]),
        (["#th.0.40!"], False, ["#th.0.40!", "#qd!"]),  # the program asked to leave it so
    ],
)
def test_a_stop_on_close_only_when_the_robot_was_moved_since_the_last_stop(
    program: list[str], stop_on_close: bool, expected: list[str]
) -> None:
    options = client_options(stop_on_close=stop_on_close)
    assert _frames_after_close(options, program) == expected


@pytest.mark.usefixtures("long_write_timeout")
def test_close_does_not_hang_on_a_line_that_takes_nothing(
    caplog: pytest.LogCaptureFixture,
) -> None:
    ours, theirs = socket.socketpair()  # nobody reads the far end
    link = SocketLink(ours, "socket pair")
    rov = Client(link, client_options())
    try:
        rov.move(0, 40)
        fill_line(link)  # the line takes nothing more
        with caplog.at_level(logging.WARNING, logger="rovlink.client"):
            closing = ThreadCall(rov.close)
            assert closing.done.wait(CONDITION_TIMEOUT_S), "close() waits for the write"
        assert closing.error is None
        assert "#stop! not written within 0.5 s" in caplog.text
        assert wait_until(lambda: rov.closed)
    finally:
        theirs.close()


def _failing_program(rov: Client, before_the_error: Callable[[], object]) -> None:
    with rov:
        before_the_error()
        raise KeyError("the robot program failed")


@pytest.mark.parametrize("transport", ["socket pair", "tcp"])
@pytest.mark.usefixtures("long_write_timeout")
def test_leaving_with_by_an_error_does_not_hang_on_a_line_that_takes_nothing(
    transport: str, caplog: pytest.LogCaptureFixture
) -> None:
    """Bounded as close() is: before, the error's own stop() waited for the write timeout."""
    if transport == "tcp":
        server = socket.create_server(("127.0.0.1", 0))
        ours = socket.create_connection(server.getsockname())
        theirs, _ = server.accept()  # nobody reads it
        server.close()
    else:
        ours, theirs = socket.socketpair()
    link = SocketLink(ours, transport)
    # (Nothing moved, and no stop on close asked for: an error stops the robot all the same.)
    rov = Client(link, client_options(stop_on_close=False))
    try:
        with caplog.at_level(logging.WARNING, logger="rovlink.client"):
            leaving = ThreadCall(lambda: _failing_program(rov, lambda: fill_line(link)))
            assert leaving.done.wait(CONDITION_TIMEOUT_S), "leaving waits for the write"
        assert isinstance(leaving.error, KeyError)  # the program's error, not masked
        assert f"{transport}: #stop! not written within 0.5 s" in caplog.text
        assert wait_until(lambda: rov.closed)
    finally:
        theirs.close()


def test_leaving_with_by_an_error_stops_even_a_robot_left_as_it_is_on_close() -> None:
    fake, host_end = FakeController.on_socketpair()
    try:
        rov = Client(SocketLink(host_end, "socket pair"), client_options(stop_on_close=False))
        with pytest.raises(KeyError):
            _failing_program(rov, lambda: rov.move(0, 40))
        assert rov.closed
        fake._thread.join(CONDITION_TIMEOUT_S)  # (it ends at the end of the stream: all read)
        assert fake.frames()[1:] == ["#th.0.40!", "#stop!"]
    finally:
        fake.close()


async def test_leaving_async_with_by_an_error_stops_even_a_robot_left_as_it_is_on_close() -> None:
    fake, host_end = FakeController.on_socketpair()
    try:
        rov = await AsyncClient(
            SocketLink(host_end, "socket pair"), client_options(stop_on_close=False)
        ).open()

        async def failing_program() -> None:
            async with rov:
                await rov.move(0, 40)
                raise KeyError("the robot program failed")

        with pytest.raises(KeyError):  # the program's error, not masked
            await failing_program()
        assert rov.closed
        await asyncio.to_thread(fake._thread.join, CONDITION_TIMEOUT_S)  # (all read)
        assert fake.frames()[1:] == ["#th.0.40!", "#stop!"]
    finally:
        fake.close()


async def test_leaving_async_with_by_an_error_is_bounded_as_close_is(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The asyncio client's stop on an error is queued for the port, as close()'s is: leaving
    waits for a line that takes nothing at most CLOSE_FLUSH_S (made short here), as close()."""
    monkeypatch.setattr(transport, "CLOSE_FLUSH_S", 0.1)
    ours, theirs = socket.socketpair()  # nobody reads the far end
    link = SocketLink(ours, "socket pair")
    try:
        rov = await AsyncClient(link, client_options(stop_on_close=False)).open()

        async def failing_program() -> None:
            async with rov:
                fill_line(link)
                raise KeyError("the robot program failed")

        with pytest.raises(KeyError):  # the program's error, not masked
            await asyncio.wait_for(failing_program(), _LEAVING_BOUND_S)
        assert rov.closed
    finally:
        theirs.close()
