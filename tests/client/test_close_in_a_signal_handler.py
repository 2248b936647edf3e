"""``close()`` from a signal handler, in the thread whose call it interrupted (``signal.signal(
SIGTERM, lambda *_: rov.close())``, a common way to end a program): the ``#stop!`` it owes a
robot it moved goes out. The handler runs between two steps of the interrupted call, which may
hold the client's wire lock or state lock there. Before, the ``#stop!`` was written by a thread
of its own that waited for those locks: it gave up after 0.5 s, with a warning that the line
took nothing, and the robot drove on until the controller's link-loss failsafe stopped it; and
the interrupted call, whose locks close() had given back, ended with a ``RuntimeError`` or a
``KeyError`` rather than ``ConnectionLostError``.

A tracing function plays the signal: it calls ``close()`` at the first step of the client's own
code where the interrupted call holds the lock a test names.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Iterator
from types import FrameType
from typing import Any

import pytest

import rovlink.client.blocking
from rovlink.client import Client, ConnectionLostError
from rovlink.client.blocking import _owns
from rovlink.client.links import SocketLink
from tests.client.conftest import client_options, wait_until
from tests.client.fake_controller import FakeController

pytestmark = pytest.mark.integration

_CLIENT_SOURCE = rovlink.client.blocking.__file__


class _CloseWhenHeld:
    """Call ``client.close()`` at the first line of the client's code that this thread runs
    while it holds ``lock`` and not ``free`` (as a signal handler would run there)."""

    def __init__(self, client: Client, lock: threading.RLock, free: threading.RLock) -> None:
        self._client = client
        self._lock = lock
        self._free = free
        self.fired = False

    def _on_call(self, frame: FrameType, event: str, arg: Any) -> Any:
        if self.fired or frame.f_code.co_filename != _CLIENT_SOURCE:
            return None
        return self._on_line

    def _on_line(self, frame: FrameType, event: str, arg: Any) -> Any:
        if self.fired or event != "line":
            return None if self.fired else self._on_line
        if _owns(self._lock) and not _owns(self._free):
            self.fired = True
            self._client.close()
            return None
        return self._on_line

    def __enter__(self) -> _CloseWhenHeld:
        sys.settrace(self._on_call)  # (this thread only: the client's own threads run untraced)
        return self

    def __exit__(self, *exc_info: object) -> None:
        sys.settrace(None)


@pytest.fixture
def fake_and_client() -> Iterator[tuple[FakeController, Client]]:
    fake, sock = FakeController.on_socketpair()
    client = Client(SocketLink(sock, "socket pair"), client_options())
    try:
        yield fake, client
    finally:
        client.close()
        fake.close()


@pytest.mark.parametrize(
    ("lock", "free"), [("_wire_lock", "_state_lock"), ("_state_lock", "_wire_lock")]
)
def test_close_in_a_handler_that_interrupted_a_query_sends_the_stop_it_owes(
    fake_and_client: tuple[FakeController, Client], lock: str, free: str
) -> None:
    fake, rov = fake_and_client
    rov.start()
    rov.move(90, 40)
    assert wait_until(lambda: fake.frames()[-1:] == ["#th.90.40!"])
    # The interrupted call ends as every call of a closed client does (it ended with a
    # RuntimeError or a KeyError: close() gave back the locks and the query it held).
    with (
        pytest.raises(ConnectionLostError, match="closed"),
        _CloseWhenHeld(rov, getattr(rov, lock), getattr(rov, free)) as at,
    ):
        rov.depth_cm()
    assert at.fired
    assert wait_until(lambda: "#stop!" in fake.frames())
    frames = fake.frames()
    assert frames.index("#stop!") > frames.index("#th.90.40!")
