"""A pseudo-terminal that is a process's controlling terminal is a person's terminal window, not
a controller's port: a reused ``/dev/pts/N`` (the simulator ended, a terminal window opened) or a
mistyped one is refused, on connecting and on reconnecting, and nothing is written into it."""

from __future__ import annotations

import logging
import os
import sys
import termios
import tty
from collections.abc import Iterator
from pathlib import Path

import pytest

import rovlink
import rovlink.aio
from rovlink.client.errors import ConnectError
from rovlink.client.events import ClientEvent, LinkState
from rovlink.client.links import open_link
from rovlink.client.terminal_owner import terminal_owner
from rovlink.client.url import parse_url
from tests.client.conftest import CONDITION_TIMEOUT_S, wait_until, wait_until_async
from tests.client.fake_controller import FakeController
from tests.terminals import TerminalWindow, refusal

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux's /proc"),
]


@pytest.fixture
def window() -> Iterator[TerminalWindow]:
    opened = TerminalWindow()
    yield opened
    opened.close()


def test_a_terminal_window_is_refused_on_connecting_and_left_as_it_was(
    window: TerminalWindow,
) -> None:
    with pytest.raises(ConnectError) as raised:
        rovlink.connect(window.path, boot_timeout=None)
    assert str(raised.value) == refusal(window)
    # Before, it was opened: set raw (the person's shell lost its line editing) and sent frames.
    assert window.shown() == b""
    assert termios.tcgetattr(window.master) == window.modes


def test_a_pseudo_terminal_without_a_session_opens_as_before() -> None:
    master, terminal = os.openpty()
    try:
        path = os.ttyname(terminal)
        assert terminal_owner(path) is None
        link = open_link(parse_url(path))
        link.write(b"#qd!")
        assert os.read(master, 4) == b"#qd!"
        link.close()
    finally:
        os.close(master)
        os.close(terminal)


def test_a_reused_pseudo_terminal_is_refused_on_reconnecting_until_a_controller_is_there(
    tmp_path: Path, window: TerminalWindow, caplog: pytest.LogCaptureFixture
) -> None:
    # A link (as socat's link=) names the controller's pseudo-terminal; when it is lost the
    # name leads to a terminal window, as a reused /dev/pts/N does.
    caplog.set_level(logging.DEBUG, logger="rovlink")
    port = tmp_path / "rov"
    master, terminal = os.openpty()
    tty.setraw(terminal)
    first = FakeController(master)
    port.symlink_to(os.ttyname(terminal))
    events: list[ClientEvent] = []
    rov = rovlink.connect(str(port), reconnect=True, timeout=1.0, on_event=events.append)
    second: FakeController | None = None
    try:
        assert rov.depth_cm() >= 0
        port.unlink()
        port.symlink_to(window.path)
        first.close()
        os.close(terminal)

        def refusals() -> list[logging.LogRecord]:
            return [r for r in caplog.records if refusal(window, str(port)) in r.getMessage()]

        assert wait_until(lambda: len(refusals()) >= 3)  # it keeps trying
        said = [record for record in refusals() if record.levelno == logging.WARNING]
        assert len(said) == 1, caplog.text  # said once, the rest to the debug log
        assert window.shown() == b""
        assert termios.tcgetattr(window.master) == window.modes

        # A controller there again: reopened.
        master, terminal = os.openpty()
        tty.setraw(terminal)
        second = FakeController(master)
        port.unlink()
        port.symlink_to(os.ttyname(terminal))
        assert wait_until(
            lambda: any(isinstance(e, LinkState) and e.state == "reconnected" for e in events),
            CONDITION_TIMEOUT_S * 2,
        )
        assert rov.depth_cm() >= 0
    finally:
        rov.close()
        if second is not None:
            second.close()
            os.close(terminal)
    assert window.shown() == b""


async def test_the_asyncio_client_refuses_a_reused_pseudo_terminal_on_reconnecting(
    tmp_path: Path, window: TerminalWindow, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG, logger="rovlink")
    port = tmp_path / "rov"
    master, terminal = os.openpty()
    tty.setraw(terminal)
    first = FakeController(master)
    port.symlink_to(os.ttyname(terminal))
    events: list[ClientEvent] = []
    rov = await rovlink.aio.connect(str(port), reconnect=True, timeout=1.0, on_event=events.append)
    try:
        assert await rov.depth_cm() >= 0
        port.unlink()
        port.symlink_to(window.path)
        first.close()
        os.close(terminal)

        def refusals() -> list[logging.LogRecord]:
            return [r for r in caplog.records if refusal(window, str(port)) in r.getMessage()]

        assert await wait_until_async(lambda: len(refusals()) >= 3)  # it keeps trying
        said = [record for record in refusals() if record.levelno == logging.WARNING]
        assert len(said) == 1, caplog.text
        assert not any(isinstance(e, LinkState) and e.state == "reconnected" for e in events)
    finally:
        await rov.close()
    assert window.shown() == b""
    assert termios.tcgetattr(window.master) == window.modes
