"""A port whose close hangs (a USB serial adapter whose driver is stuck: the kernel's close waits
for output that never drains) never holds the program: both clients wait for it at most
``CLOSE_TIMEOUT_S``, say so in a warning naming the port, and leave it to end in the background;
the asyncio client's event loop runs on meanwhile, and a reconnection does not wait for the lost
port's close either. Before, ``close()`` waited for as long as the port's close did (the asyncio
client inside the event loop), and so did a reconnection before it opened anything."""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from collections.abc import Callable

import pytest

import rovlink
import rovlink.aio
from rovlink.aio import AsyncClient
from rovlink.client import Client, links, port_closing
from rovlink.client.events import ClientEvent, LinkState
from rovlink.client.url import parse_url
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    REPLY_TIMEOUT_S,
    ThreadCall,
    client_options,
    longest_loop_stall_s,
    wait_until,
    wait_until_async,
)
from tests.client.fake_controller import FakeController

pytestmark = pytest.mark.integration

_CLOSE_TIMEOUT_S = 0.2
#: How long the stuck close lasts unless the test lets it end first (a test of the code before
#: the fix would otherwise wait for it for ever).
_STUCK_FOR_S = 3.0


@pytest.fixture(autouse=True)
def short_close_timeout(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(port_closing, "CLOSE_TIMEOUT_S", _CLOSE_TIMEOUT_S)


def _make_close_hang(rov: Client | AsyncClient) -> threading.Event:
    """Make the pyserial port under ``rov`` hang in its close until the event is set."""
    port = rov._link._port  # type: ignore[attr-defined]
    real_close = port.close
    let_go = threading.Event()

    def stuck_close() -> None:
        let_go.wait(_STUCK_FOR_S)
        real_close()

    port.close = stuck_close
    return let_go


def test_the_blocking_client_does_not_wait_for_a_close_that_hangs(
    pty_fake: tuple[FakeController, str], caplog: pytest.LogCaptureFixture
) -> None:
    _, path = pty_fake
    rov = rovlink.connect(path, keepalive=None, boot_timeout=None, timeout=REPLY_TIMEOUT_S)
    assert rov.depth_cm() == 123
    let_go = _make_close_hang(rov)
    try:
        with caplog.at_level(logging.WARNING, logger="rovlink.client"):
            closing = ThreadCall(rov.close)
            assert closing.done.wait(_STUCK_FOR_S - 1.0), "close() waited for the stuck close"
        assert closing.error is None
        assert f"{path} at 115200 baud: the port did not close within 0.2 s" in caplog.text
        assert rov.closed
    finally:
        let_go.set()


@pytest.mark.realtime
async def test_the_asyncio_client_does_not_wait_for_a_close_that_hangs_nor_block_its_loop(
    pty_fake: tuple[FakeController, str], caplog: pytest.LogCaptureFixture
) -> None:
    _, path = pty_fake
    rov = await rovlink.aio.connect(
        path, keepalive=None, boot_timeout=None, timeout=REPLY_TIMEOUT_S
    )
    assert await rov.depth_cm() == 123
    let_go = _make_close_hang(rov)
    try:
        started = time.monotonic()
        with caplog.at_level(logging.WARNING, logger="rovlink.client"):
            stall_s = await longest_loop_stall_s(rov.close)
        assert time.monotonic() - started < _STUCK_FOR_S - 1.0, "close() waited for it"
        assert "the port did not close within 0.2 s" in caplog.text
        # (A loop that closed the port itself stood still for the whole stuck close.)
        assert stall_s < _STUCK_FOR_S / 3, "the event loop stood still while the port closed"
    finally:
        let_go.set()


def test_a_close_that_ends_in_time_is_waited_for_and_its_error_raised() -> None:
    class _FailingLink:
        description = "failing"

        def close(self) -> None:
            raise OSError("the port said no")

    with pytest.raises(OSError, match="the port said no"):
        port_closing.close_within(_FailingLink(), CONDITION_TIMEOUT_S)  # type: ignore[arg-type]


def _reconnected(events: list[ClientEvent]) -> bool:
    return any(isinstance(event, LinkState) and event.state == "reconnected" for event in events)


def test_the_blocking_client_reconnects_without_waiting_for_the_lost_port_to_close(
    pty_fake: tuple[FakeController, str], reopened: list[FakeController]
) -> None:
    # An adapter pulled out whose driver then hangs in close: the reconnection waited for that
    # close before it opened anything.
    fake, path = pty_fake
    events: list[ClientEvent] = []
    options = client_options(reconnect=True, on_event=events.append, timeout_s=REPLY_TIMEOUT_S)
    rov = Client(links.open_link(parse_url(path)), options, reopen=_reopen_to(reopened))
    let_go = _make_close_hang(rov)
    try:
        assert rov.depth_cm() == 123
        fake.close()  # pulled out
        assert wait_until(lambda: _reconnected(events), _STUCK_FOR_S - 1.0)
        assert rov.depth_cm() == 123  # on the reopened link
    finally:
        let_go.set()
        rov.close()


async def test_the_asyncio_client_reconnects_without_waiting_for_the_lost_port_to_close(
    pty_fake: tuple[FakeController, str], reopened: list[FakeController]
) -> None:
    fake, path = pty_fake
    events: list[ClientEvent] = []
    options = client_options(reconnect=True, on_event=events.append, timeout_s=REPLY_TIMEOUT_S)
    link = links.open_link(parse_url(path))
    rov = await AsyncClient(link, options, reopen=_reopen_to(reopened)).open()
    let_go = _make_close_hang(rov)
    try:
        assert await rov.depth_cm() == 123
        fake.close()
        assert await wait_until_async(lambda: _reconnected(events), _STUCK_FOR_S - 1.0)
        assert await rov.depth_cm() == 123
    finally:
        let_go.set()
        await rov.close()


def _reopen_to(reopened: list[FakeController]) -> Callable[[], links.Link]:
    """A ``reopen`` that plugs a fresh controller in, on a socket pair."""

    def reopen() -> links.Link:
        fake, ours = FakeController.on_socketpair()
        reopened.append(fake)
        return links.SocketLink(ours, "socket pair, reopened")

    return reopen


def test_closing_in_a_later_event_loop_stops_the_robot_and_does_not_wait_for_a_close_that_hangs(
    pty_fake: tuple[FakeController, str],
) -> None:
    # rov = asyncio.run(connect(url)), then asyncio.run(rov.close()): the port was closed as it
    # was, in the second loop's thread, for as long as its close hung, and the robot the first
    # loop moved was left moving.
    fake, path = pty_fake

    async def connect_and_move() -> AsyncClient:
        rov = await rovlink.aio.connect(
            path, keepalive=None, boot_timeout=None, timeout=REPLY_TIMEOUT_S
        )
        await rov.start()
        await rov.move(0, 40)
        assert await rov.depth_cm() == 123
        return rov

    rov = asyncio.run(connect_and_move())
    let_go = _make_close_hang(rov)
    try:
        started = time.monotonic()
        asyncio.run(rov.close())
        assert time.monotonic() - started < _STUCK_FOR_S - 1.0, "close() waited for it"
        assert fake.wait_for(lambda f: f.frames()[-1:] == ["#stop!"])
        assert rov.closed
    finally:
        let_go.set()


def test_the_warning_blames_a_serial_adapter_only_on_a_serial_link(
    caplog: pytest.LogCaptureFixture,
) -> None:
    # Before, every link's warning named "a serial adapter whose driver hangs", sim:// too.
    let_go = threading.Event()

    class _InProcessLink:
        description = "simulated controller"
        writes_may_wait = False

        def close(self) -> None:
            let_go.wait(_STUCK_FOR_S)

    try:
        with caplog.at_level(logging.WARNING, logger="rovlink.client"):
            closed = port_closing.close_within(_InProcessLink())  # type: ignore[arg-type]
        assert not closed
        assert "simulated controller: the port did not close within 0.2 s" in caplog.text
        assert "serial adapter" not in caplog.text
        assert "network port" not in caplog.text
    finally:
        let_go.set()
