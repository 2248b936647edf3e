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

import logging
import sys
import threading
import time
from collections.abc import Iterator
from types import FrameType
from typing import Any

import pytest

import rovlink
import rovlink.client.blocking
import rovlink.sim.port
from rovlink.client import Client, ConnectionLostError
from rovlink.client.blocking import _owns
from rovlink.client.links import SocketLink
from tests.client.conftest import REPLY_TIMEOUT_S, client_options, wait_until
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


class _CloseInSimRead:
    """Call ``client.close()`` at the first line of the simulated port's ``read`` that this
    thread runs holding the port's lock (a signal handler run while a query reads ``sim://``)."""

    def __init__(self, client: Client) -> None:
        self._client = client
        self._lock = client._link.port.lock  # type: ignore[attr-defined]
        self.fired = False
        self.close_took_s: float | None = None

    def _on_call(self, frame: FrameType, event: str, arg: Any) -> Any:
        if self.fired or frame.f_code.co_filename != rovlink.sim.port.__file__:
            return None
        return self._on_line if frame.f_code.co_name == "read" else None

    def _on_line(self, frame: FrameType, event: str, arg: Any) -> Any:
        if self.fired or event != "line":
            return None if self.fired else self._on_line
        if _owns(self._lock):
            self.fired = True
            started = time.monotonic()
            self._client.close()
            self.close_took_s = time.monotonic() - started
            return None
        return self._on_line

    def __enter__(self) -> _CloseInSimRead:
        sys.settrace(self._on_call)
        return self

    def __exit__(self, *exc_info: object) -> None:
        sys.settrace(None)


def _query_until_fired(rov: Client, at: _CloseInSimRead) -> None:
    # (A query's reply may be read by the background reader: a later one is read here.)
    for _ in range(1000):
        rov.depth_cm()
        if at.fired:
            return


@pytest.mark.realtime
def test_close_in_a_handler_that_interrupted_a_sim_read_is_prompt_and_stops_first(
    caplog: pytest.LogCaptureFixture,
) -> None:
    # The interrupted read holds the simulated port's lock until the handler returns. Before,
    # the #stop! (written by a thread of its own) and the port's close both waited for it: the
    # #stop! was given up after 0.5 s, close() took 4.5 s, and a warning blamed a serial adapter.
    rov = rovlink.connect("sim://", keepalive=None, timeout=REPLY_TIMEOUT_S)
    port = rov._link.port  # type: ignore[attr-defined]
    written: list[tuple[bytes, bool]] = []
    real_write = port.write

    def recording_write(data: bytes) -> int:
        written.append((bytes(data), port.is_open))
        return int(real_write(data))

    port.write = recording_write
    rov.start()
    rov.move(90, 40)
    at = _CloseInSimRead(rov)
    with caplog.at_level(logging.WARNING), at, pytest.raises(ConnectionLostError, match="closed"):
        _query_until_fired(rov, at)
    assert at.fired
    assert at.close_took_s is not None
    assert at.close_took_s < 1.0
    assert (b"#stop!", True) in written
    assert "not written within" not in caplog.text
    assert "serial adapter" not in caplog.text
    assert not port.is_open
