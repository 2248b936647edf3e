"""The tap over a controller link that is lost and comes back (:mod:`rovlink.recorder.reopening`):
its program stays connected, nothing it sent during the gap is queued, and a ``#stop!`` goes
first on the reopened link when the program's commands may have left the robot moving."""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import cast

import pytest

from rovlink.client import parse_url
from rovlink.client.errors import ConnectionLostError
from rovlink.client.events import LinkState
from rovlink.client.links import Link, open_link
from rovlink.recorder import Recorder, read_entries
from rovlink.recorder.entries import FrameEntry
from rovlink.recorder.reopening import ReopeningLink
from rovlink.recorder.tap import STOP_FRAME, TcpEndpoint, forward
from tests.client.conftest import wait_until

pytestmark = pytest.mark.integration

_TIMEOUT_S = 20.0


class DroppingController:
    """A TCP 'controller' that keeps what each connection sent it, answers ``#qd!`` with
    ``$qd.0!``, and can drop its connection (a USB-serial adapter's dropout); ``hello`` is sent
    to each connection as it comes (a controller's own output, for a recorder that only
    listens)."""

    def __init__(self, hello: bytes = b"") -> None:
        self._hello = hello
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.url = f"socket://127.0.0.1:{self._listener.getsockname()[1]}"
        #: What each connection sent, in order of the connections.
        self.received: list[bytearray] = []
        self._current: socket.socket | None = None
        self._false_starts = 0  # connections to close at once, as a dying process's port does
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while True:
            try:
                connection, _ = self._listener.accept()
            except OSError:
                return
            self._current = connection
            connection.sendall(self._hello)
            got = bytearray()
            self.received.append(got)
            if self._false_starts:
                self._false_starts -= 1
                connection.settimeout(_TIMEOUT_S)
                with contextlib.suppress(OSError):
                    got += connection.recv(4096)  # (what came before the close)
                connection.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                connection.close()  # a reset
                continue
            try:
                while data := connection.recv(4096):
                    got += data
                    if got.endswith(b"#qd!"):
                        connection.sendall(b"$qd.0!")
            except OSError:
                pass
            connection.close()

    def drop(self) -> None:
        """Drop the current connection, refusing others until :meth:`come_back`."""
        connection = self._current
        assert connection is not None
        self._listener.close()
        connection.shutdown(socket.SHUT_RDWR)

    def come_back(self, false_starts: int = 0) -> None:
        """Listen again on the same port, closing the first ``false_starts`` connections at
        once (after their first bytes)."""
        self._false_starts = false_starts
        port = int(self.url.rsplit(":", 1)[1])
        self._listener = socket.create_server(("127.0.0.1", port))
        self._thread.join(_TIMEOUT_S)
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._listener.close()
        if self._current is not None:
            self._current.close()


@pytest.fixture
def controller() -> Iterator[DroppingController]:
    controller = DroppingController()
    yield controller
    controller.close()


def _tap_over(
    controller: DroppingController, stopping: threading.Event, states: list[str]
) -> tuple[threading.Thread, TcpEndpoint, list[tuple[str, bytes, bool]]]:
    endpoint = TcpEndpoint("127.0.0.1", 0)
    recorded: list[tuple[str, bytes, bool]] = []

    def record(direction: str, data: bytes, *, by_session: bool = False) -> None:
        recorded.append((direction, data, by_session))

    endpoint_url = parse_url(controller.url)
    link = ReopeningLink(
        open_link(endpoint_url),
        lambda: open_link(endpoint_url),
        stopping=stopping,
        on_change=lambda state, _: states.append(state),
        may_reopen=lambda: True,
    )
    thread = threading.Thread(target=forward, args=(endpoint, link, record, stopping), daemon=True)
    thread.start()
    return thread, endpoint, recorded


def _ask(program: socket.socket) -> bytes:
    program.sendall(b"#qd!")
    return program.recv(64)


@pytest.mark.parametrize("moved", [True, False])
def test_a_reopened_link_gets_stop_first_only_if_the_program_may_have_moved_the_robot(
    controller: DroppingController, moved: bool
) -> None:
    stopping = threading.Event()
    states: list[str] = []
    thread, endpoint, recorded = _tap_over(controller, stopping, states)
    host, port = endpoint.path.removeprefix("socket://").rsplit(":", 1)
    program = socket.create_connection((host, int(port)), timeout=_TIMEOUT_S)
    try:
        if moved:
            program.sendall(b"#start!#th.90.50!")
        assert _ask(program) == b"$qd.0!"
        controller.drop()
        assert wait_until(lambda: states == ["lost"], _TIMEOUT_S)
        program.sendall(b"#th.90.80!")  # during the gap: never to run after the return
        controller.come_back()
        assert wait_until(lambda: states == ["lost", "reconnected"], _TIMEOUT_S)
        # The program was never disconnected, and is served again.
        assert _ask(program) == b"$qd.0!"
        assert bytes(controller.received[1]) == (STOP_FRAME if moved else b"") + b"#qd!"
        stops = [chunk for chunk in recorded if chunk == ("out", STOP_FRAME, True)]
        assert len(stops) == (1 if moved else 0)
        assert not any(b"#th.90.80!" in data for _, data, _ in recorded)
    finally:
        program.close()
        stopping.set()
        thread.join(_TIMEOUT_S)
        endpoint.close()


def test_a_program_that_leaves_during_the_gap_is_followed_by_stop_on_the_return(
    controller: DroppingController,
) -> None:
    stopping = threading.Event()
    states: list[str] = []
    thread, endpoint, _ = _tap_over(controller, stopping, states)
    host, port = endpoint.path.removeprefix("socket://").rsplit(":", 1)
    try:
        with socket.create_connection((host, int(port)), timeout=_TIMEOUT_S) as program:
            program.sendall(b"#start!#th.90.50!")
            assert _ask(program) == b"$qd.0!"
            controller.drop()
            assert wait_until(lambda: states == ["lost"], _TIMEOUT_S)
        assert wait_until(lambda: not endpoint.serving, _TIMEOUT_S)  # (its #stop! could not go)
        controller.come_back()
        assert wait_until(lambda: len(controller.received) == 2, _TIMEOUT_S)
        assert wait_until(lambda: bytes(controller.received[1]) == STOP_FRAME, _TIMEOUT_S)
    finally:
        stopping.set()
        thread.join(_TIMEOUT_S)
        endpoint.close()


def test_a_stop_is_sent_again_on_each_reopened_link_until_the_controller_is_heard(
    controller: DroppingController,
) -> None:
    # The first attempt after a loss may reach a port that takes it as its process dies: a
    # #stop! written there never reached the controller, and the next link got none.
    stopping = threading.Event()
    states: list[str] = []
    thread, endpoint, _ = _tap_over(controller, stopping, states)
    host, port = endpoint.path.removeprefix("socket://").rsplit(":", 1)
    program = socket.create_connection((host, int(port)), timeout=_TIMEOUT_S)
    try:
        program.sendall(b"#start!#th.90.50!")
        assert _ask(program) == b"$qd.0!"
        controller.drop()
        assert wait_until(lambda: states == ["lost"], _TIMEOUT_S)
        controller.come_back(false_starts=1)
        assert wait_until(lambda: states[-1:] == ["reconnected"] and len(states) >= 4, _TIMEOUT_S)
        assert _ask(program) == b"$qd.0!"
        assert bytes(controller.received[1]) == STOP_FRAME
        assert bytes(controller.received[2]) == STOP_FRAME + b"#qd!"
    finally:
        program.close()
        stopping.set()
        thread.join(_TIMEOUT_S)
        endpoint.close()


class _BusyLink:
    """A controller's port that says it is busy and closes (:class:`~rovlink.client.links.Link`'s
    calls that :class:`ReopeningLink` makes)."""

    description = "busy"

    def __init__(self) -> None:
        self._said = False

    def read_available(self, timeout_s: float) -> bytes:
        if self._said:
            raise ConnectionLostError("busy: closed by the other end")
        self._said = True
        return b"busy: the controller already has a client\r\n"

    def write(self, data: bytes) -> None:
        pass

    def close(self) -> None:
        pass


class _NoWaiting(threading.Event):
    """``stopping`` that records each wait instead of waiting, and is set after ``waits``."""

    def __init__(self, waits: int) -> None:
        super().__init__()
        self.waited_s: list[float] = []
        self._waits = waits

    def wait(self, timeout: float | None = None) -> bool:
        assert timeout is not None
        self.waited_s.append(timeout)
        if len(self.waited_s) >= self._waits:
            self.set()
        return self.is_set()


def test_links_that_close_before_a_frame_comes_are_reopened_with_backoff_not_at_once() -> None:
    # A controller busy with another client takes each connection, says so and closes it: each
    # reopening started the backoff again at 0.1 s, a new connection (and a lost and a
    # reconnected event) ten times a second for as long as it stayed busy.
    stopping = _NoWaiting(waits=6)
    states: list[str] = []
    first = cast(Link, _BusyLink())
    first.read_available(0)  # (what it said first)
    link = ReopeningLink(
        first,
        lambda: cast(Link, _BusyLink()),
        stopping=stopping,
        on_change=lambda state, _: states.append(state),
        may_reopen=lambda: True,
    )
    for _ in range(100):  # (reads, each a loss and a reopening)
        if stopping.is_set():
            break
        link.read_available(0)
    assert stopping.waited_s == [0.1, 0.2, 0.4, 0.8, 1.6, 2.0]
    assert states[:2] == ["lost", "reconnected"]


def test_a_reply_after_the_gap_is_not_matched_to_a_query_the_gap_left_unanswered(
    tmp_path: Path,
) -> None:
    # A tap's query in flight as the link dropped stayed awaited: every later reply of its
    # name was matched to the query before its own, its round trip seconds too long.
    path = tmp_path / "gap.jsonl"
    with Recorder(str(path), url="socket://127.0.0.1:1") as recorder:
        recorder.on_bytes("out", b"#qd!", at_s=1.0)
        recorder.on_event(LinkState(1.1, "lost", "closed by the other end; reconnecting"))
        recorder.on_event(LinkState(3.0, "reconnected", "after 3 attempts"))
        recorder.on_bytes("out", b"#qd!", at_s=4.0)
        recorder.on_bytes("in", b"$qd.7!", at_s=4.05)
    replies = [
        e for e in read_entries(str(path)) if isinstance(e, FrameEntry) and e.kind == "response"
    ]
    assert [(e.query, e.round_trip_ms) for e in replies] == [("qd", 50.0)]


def test_the_program_s_bytes_on_a_reopened_link_are_recorded_after_the_stop_that_precedes_them(
    controller: DroppingController,
) -> None:
    # A program's bytes that came as the link came back went on the wire after the tap's
    # #stop!, but were recorded before it: the file showed the robot stopped after the
    # program's "#start!#th.90.60!" while it was moving.
    stopping = threading.Event()
    states: list[str] = []
    endpoint = TcpEndpoint("127.0.0.1", 0)
    recorded: list[tuple[str, bytes, bool]] = []
    host, port = endpoint.path.removeprefix("socket://").rsplit(":", 1)
    program = socket.create_connection((host, int(port)), timeout=_TIMEOUT_S)
    after_gap = b"#start!#th.90.60!"

    def record(direction: str, data: bytes, *, by_session: bool = False) -> None:
        recorded.append((direction, data, by_session))

    def on_change(state: str, _detail: str) -> None:
        states.append(state)
        if state == "reconnected":  # (the link is back; its #stop! is about to be written)
            program.sendall(after_gap)
            wait_until(lambda: any(after_gap in data for _, data, _ in recorded), 1.0)

    url = parse_url(controller.url)
    link = ReopeningLink(
        open_link(url),
        lambda: open_link(url),
        stopping=stopping,
        on_change=on_change,
        may_reopen=lambda: True,
    )
    thread = threading.Thread(target=forward, args=(endpoint, link, record, stopping), daemon=True)
    thread.start()
    try:
        program.sendall(b"#start!#th.90.50!")
        assert _ask(program) == b"$qd.0!"
        controller.drop()
        assert wait_until(lambda: states == ["lost"], _TIMEOUT_S)
        gap_ends = len(recorded)
        controller.come_back()
        assert wait_until(lambda: bytes(controller.received[-1]).endswith(after_gap), _TIMEOUT_S)
        assert bytes(controller.received[1]) == STOP_FRAME + after_gap  # the wire's order
        sent = b"".join(data for direction, data, _ in recorded[gap_ends:] if direction == "out")
        assert sent == STOP_FRAME + after_gap  # the recording's order: the same
    finally:
        program.close()
        stopping.set()
        thread.join(_TIMEOUT_S)
        endpoint.close()
