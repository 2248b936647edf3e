"""reconnect=True: a reconnection that fails with an error no retry can mend (a bug in a
``reopen`` callable, a link scheme's opener or its link) ends the connection for good, visibly."""

from __future__ import annotations

import logging
import time

import pytest

from rovlink.aio import AsyncClient
from rovlink.client import Client
from rovlink.client.errors import ConnectionLostError
from rovlink.client.events import ClientEvent, LinkState
from rovlink.client.links import Link, SocketLink
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    client_options,
    wait_until,
    wait_until_async,
)
from tests.client.fake_controller import FakeController

#: Long, so that a call that waited for the link (the defect) is told from one that failed at once.
_TIMEOUT_S = 20.0


class _BrokenOpenerError(RuntimeError):
    """What a buggy opener raises: neither the port's error (OSError) nor the URL's (ValueError)."""


class _BrokenLink(SocketLink):
    """A reopened link whose writes fail with a bug of its own (not a lost port)."""

    was_closed = False

    def send_some(self, data: bytes | bytearray | memoryview) -> int:
        raise _BrokenOpenerError("the link scheme's write is broken")

    def write(self, data: bytes) -> None:
        raise _BrokenOpenerError("the link scheme's write is broken")

    def close(self) -> None:
        self.was_closed = True
        super().close()


class _Reopener:
    """A ``reopen`` that fails with a bug (``opens_link``: after opening a link it then fails)."""

    def __init__(self, *, opens_link: bool) -> None:
        self.opens_link = opens_link
        self.calls = 0
        self.fakes: list[FakeController] = []
        self.links: list[_BrokenLink] = []

    def __call__(self) -> Link:
        self.calls += 1
        if not self.opens_link:
            raise _BrokenOpenerError("the opener is broken")
        fake, host_end = FakeController.on_socketpair()
        self.fakes.append(fake)
        link = _BrokenLink(host_end, "socket pair, broken")
        self.links.append(link)
        return link


def _lost(events: list[ClientEvent]) -> bool:
    return any(isinstance(event, LinkState) and event.state == "lost" for event in events)


def _check_the_error(error: ConnectionLostError, elapsed_s: float) -> None:
    assert elapsed_s < _TIMEOUT_S / 4  # at once, not after waiting for a link that never comes
    assert "reconnecting failed: _BrokenOpenerError: the " in str(error)
    assert "is broken" in str(error)


def _check_logged(caplog: pytest.LogCaptureFixture) -> None:
    errors = [record for record in caplog.records if record.levelno >= logging.ERROR]
    assert len(errors) == 1, caplog.text
    assert "reconnecting socket pair failed: _BrokenOpenerError" in errors[0].getMessage()
    assert errors[0].exc_info is not None  # with its traceback
    assert errors[0].exc_info[0] is _BrokenOpenerError


@pytest.mark.parametrize("opens_link", [False, True], ids=["opener fails", "its link fails"])
def test_a_broken_reopen_ends_the_blocking_clients_connection_at_once(
    caplog: pytest.LogCaptureFixture, opens_link: bool
) -> None:
    # Before, the reconnecting thread died silently: every call waited `timeout` and failed
    # with "not reopened within …" until close(), and nothing said why.
    caplog.set_level(logging.ERROR, logger="rovlink")
    first, host_end = FakeController.on_socketpair()
    reopen = _Reopener(opens_link=opens_link)
    events: list[ClientEvent] = []
    options = client_options(reconnect=True, timeout_s=_TIMEOUT_S, on_event=events.append)
    rov = Client(SocketLink(host_end, "socket pair"), options, reopen=reopen)
    try:
        rov.start()
        rov.move(90, 50)
        first.close()
        assert wait_until(lambda: rov.closed)  # lost for good, as without reconnect
        for call in (rov.depth_cm, lambda: rov.move(0, 0), rov.stop):
            started = time.monotonic()
            with pytest.raises(ConnectionLostError) as raised:
                call()
            _check_the_error(raised.value, time.monotonic() - started)
        assert reopen.calls == 1  # no retry of what no retry can mend
        assert all(link.was_closed for link in reopen.links)  # a link it opened is not kept
    finally:
        rov.close()
        first.close()
        for fake in reopen.fakes:
            fake.close()
    _check_logged(caplog)
    assert _lost(events)


@pytest.mark.parametrize("opens_link", [False, True], ids=["opener fails", "its link fails"])
async def test_a_broken_reopen_ends_the_asyncio_clients_connection_at_once(
    caplog: pytest.LogCaptureFixture, opens_link: bool
) -> None:
    caplog.set_level(logging.ERROR, logger="rovlink")
    first, host_end = FakeController.on_socketpair()
    reopen = _Reopener(opens_link=opens_link)
    events: list[ClientEvent] = []
    options = client_options(reconnect=True, timeout_s=_TIMEOUT_S, on_event=events.append)
    rov = await AsyncClient(SocketLink(host_end, "socket pair"), options, reopen=reopen).open()
    try:
        await rov.start()
        await rov.move(90, 50)
        first.close()
        assert await wait_until_async(lambda: rov.closed, CONDITION_TIMEOUT_S)
        for call in (rov.depth_cm, lambda: rov.move(0, 0), rov.stop):
            started = time.monotonic()
            with pytest.raises(ConnectionLostError) as raised:
                await call()
            _check_the_error(raised.value, time.monotonic() - started)
        assert reopen.calls == 1
        assert all(link.was_closed for link in reopen.links)
    finally:
        await rov.close()
        first.close()
        for fake in reopen.fakes:
            fake.close()
    _check_logged(caplog)
    assert _lost(events)
