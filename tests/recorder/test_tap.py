"""The recording tap (``rovlink record URL --tap socket://…`` or ``--tap pty``) over real TCP
sockets and pseudo-terminals: one program at a time, and the robot stopped when a program that
may have moved it leaves."""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field

import pytest
import serial

from rovlink.client import parse_url
from rovlink.client.links import Link, open_link
from rovlink.protocol import Command, encode
from rovlink.recorder.reopening import ReopeningLink
from rovlink.recorder.tap import BUSY_MESSAGE, STOP_FRAME, PtyEndpoint, TcpEndpoint, forward
from tests.client.conftest import wait_until
from tests.faults.test_fault_proxy import RecordingController

pytestmark = pytest.mark.integration

_TIMEOUT_S = 10.0


@dataclass
class _Chunks:
    """What the tap handed to the recorder, in order."""

    chunks: list[tuple[str, bytes, bool]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def __call__(self, direction: str, data: bytes, *, by_session: bool = False) -> None:
        with self.lock:
            self.chunks.append((direction, data, by_session))


@dataclass
class _Tap:
    controller: RecordingController
    address: tuple[str, int]
    recorded: _Chunks
    endpoint: TcpEndpoint

    def program_gone(self) -> None:
        """Wait until the tap has seen its program leave (the next is then served)."""
        assert wait_until(lambda: not self.endpoint.serving, _TIMEOUT_S)


def _held(link: Link, stopping: threading.Event) -> ReopeningLink:
    """``link`` as ``rovlink record --exit-on-loss`` holds it: lost, it is not reopened."""

    def reopen() -> Link:
        raise AssertionError("not reopened")

    return ReopeningLink(
        link, reopen, stopping=stopping, on_change=lambda *_: None, may_reopen=lambda: False
    )


@contextlib.contextmanager
def _forwarding(
    endpoint: TcpEndpoint | PtyEndpoint,
) -> Iterator[tuple[RecordingController, _Chunks]]:
    """The tap forwarding between ``endpoint`` and a controller that keeps every byte it is
    sent; what it recorded."""
    controller = RecordingController()
    host, port = controller.address
    link = open_link(parse_url(f"socket://{host}:{port}"))
    recorded = _Chunks()
    stopping = threading.Event()
    forwarding = threading.Thread(
        target=forward, args=(endpoint, _held(link, stopping), recorded, stopping), daemon=True
    )
    forwarding.start()
    try:
        yield controller, recorded
    finally:
        stopping.set()
        forwarding.join(_TIMEOUT_S)
        endpoint.close()
        link.close()
        controller.close()


@pytest.fixture
def tap() -> Iterator[_Tap]:
    """A tap on a free TCP port in front of a controller that keeps every byte it is sent."""
    endpoint = TcpEndpoint("127.0.0.1", 0)
    with _forwarding(endpoint) as (controller, recorded):
        tcp_host, tcp_port = endpoint.path.removeprefix("socket://").rsplit(":", 1)
        yield _Tap(controller, (tcp_host, int(tcp_port)), recorded, endpoint)


def _program(address: tuple[str, int]) -> socket.socket:
    connection = socket.create_connection(address, timeout=_TIMEOUT_S)
    connection.settimeout(_TIMEOUT_S)
    return connection


def _read_to_end(connection: socket.socket) -> bytes:
    data = b""
    while chunk := connection.recv(4096):
        data += chunk
    return data


def test_a_second_program_is_told_busy_and_nothing_it_sends_reaches_the_controller(
    tap: _Tap,
) -> None:
    first = _program(tap.address)
    first.sendall(b"#qd!")
    assert tap.controller.wait_for(b"#qd!") == b"#qd!"
    second = _program(tap.address)
    second.sendall(b"#start!#th.0.100!")
    # At once, while the first is still connected: one line, then the end of the connection.
    assert _read_to_end(second) == BUSY_MESSAGE
    second.close()
    first.close()
    tap.program_gone()
    # The next program after the first has gone is served; the refused one's bytes never came.
    third = _program(tap.address)
    third.sendall(b"#qr!")
    assert tap.controller.wait_for(b"#qr!") == b"#qd!#qr!"
    third.close()


def test_a_program_that_leaves_the_robot_moving_is_followed_by_stop(tap: _Tap) -> None:
    mover = _program(tap.address)
    mover.sendall(b"#start!#th.90.50!")
    tap.controller.wait_for(b"#th.90.50!")
    mover.close()
    assert tap.controller.wait_for(STOP_FRAME) == b"#start!#th.90.50!" + STOP_FRAME
    assert wait_until(lambda: ("out", STOP_FRAME, True) in tap.recorded.chunks, _TIMEOUT_S)


def test_a_program_that_stopped_the_robot_or_only_asked_is_not_followed_by_stop(
    tap: _Tap,
) -> None:
    stopped = _program(tap.address)
    stopped.sendall(b"#start!#th.90.50!#stop!")
    tap.controller.wait_for(b"#stop!")
    stopped.close()
    tap.program_gone()
    asker = _program(tap.address)  # (served once the one before has gone)
    asker.sendall(b"#qd!")
    tap.controller.wait_for(b"#qd!")
    asker.close()
    tap.program_gone()
    last = _program(tap.address)
    last.sendall(b"#qr!")
    assert tap.controller.wait_for(b"#qr!") == b"#start!#th.90.50!#stop!#qd!#qr!"
    last.close()


def test_a_program_in_the_checksum_mode_an_earlier_one_left_is_still_stopped(tap: _Tap) -> None:
    # The controller keeps the mode a program left it in (P3), and so must the tap's reading of
    # the next program's frames: read plain, its checksummed #start! was noise, and no #stop!.
    switcher = _program(tap.address)
    switcher.sendall(b"#crcon!")
    tap.controller.wait_for(b"#crcon!")
    switcher.close()
    tap.program_gone()
    mover = _program(tap.address)
    moving = encode(Command("start"), "crc8") + encode(Command("th", (90, 40)), "crc8")
    mover.sendall(moving)
    tap.controller.wait_for(moving)
    mover.close()
    assert tap.controller.wait_for(STOP_FRAME).endswith(moving + STOP_FRAME)


def test_a_program_that_resets_its_connection_at_once_leaves_the_tap_free(tap: _Tap) -> None:
    # Accepted, then reset before the tap took it up: the tap stayed busy for good (its peer's
    # address could no longer be read), and every later program was told so.
    resetting = _program(tap.address)
    resetting.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    resetting.close()
    deadline = time.monotonic() + _TIMEOUT_S
    while True:  # (a program that came while the reset one was served is told busy: again)
        program = _program(tap.address)
        program.sendall(b"#qd!")
        program.settimeout(0.05)
        refused = False
        while not tap.controller.received.endswith(b"#qd!"):
            with contextlib.suppress(TimeoutError):
                refused = program.recv(len(BUSY_MESSAGE)) == BUSY_MESSAGE
            if refused:
                break
            assert time.monotonic() < deadline, "the program's frame never reached the controller"
        program.close()
        if not refused:
            break
        assert time.monotonic() < deadline, "every program was told the tap is busy"
        tap.program_gone()


def test_a_program_that_closes_and_connects_again_at_once_is_served(tap: _Tap) -> None:
    # A script that opens the tap per task, run in one process, connects again as soon as it
    # has closed: the tap had not yet read the hang-up, and told the program it was busy.
    for number in range(30):
        program = _program(tap.address)
        frame = f"#mgmp.{number}!".encode()
        program.sendall(frame)
        # (Its frame read by the tap, or the busy line instead, whichever comes first.)
        program.settimeout(0.01)
        answer = b""
        deadline = time.monotonic() + _TIMEOUT_S
        while not tap.controller.received.endswith(frame):
            with contextlib.suppress(TimeoutError):
                answer += program.recv(len(BUSY_MESSAGE))
            assert BUSY_MESSAGE not in answer, f"program {number} was told the tap is busy"
            assert time.monotonic() < deadline, f"program {number}'s frame never came"
        program.close()


@dataclass
class _PtyTap:
    controller: RecordingController
    recorded: _Chunks
    endpoint: PtyEndpoint


@pytest.fixture
def pty_tap() -> Iterator[_PtyTap]:
    """A tap on a pseudo-terminal in front of a controller that keeps every byte it is sent."""
    endpoint = PtyEndpoint()
    with _forwarding(endpoint) as (controller, recorded):
        yield _PtyTap(controller, recorded, endpoint)


def test_a_program_that_closes_the_terminal_leaving_the_robot_moving_is_followed_by_stop(
    pty_tap: _PtyTap,
) -> None:
    # A pseudo-terminal has no connection to end: before, the #stop! came only when the tap
    # stopped, however long after the program had gone.
    with serial.Serial(pty_tap.endpoint.path, timeout=_TIMEOUT_S) as program:
        program.write(b"#start!#th.90.50!")
        program.flush()
    assert pty_tap.controller.wait_for(STOP_FRAME) == b"#start!#th.90.50!" + STOP_FRAME
    assert wait_until(lambda: ("out", STOP_FRAME, True) in pty_tap.recorded.chunks, _TIMEOUT_S)


def test_a_program_that_stopped_the_robot_before_closing_the_terminal_is_not_followed_by_stop(
    pty_tap: _PtyTap,
) -> None:
    with serial.Serial(pty_tap.endpoint.path, timeout=_TIMEOUT_S) as program:
        program.write(b"#start!#th.90.50!#stop!")
        program.flush()
        pty_tap.controller.wait_for(b"#stop!")
    with serial.Serial(pty_tap.endpoint.path, timeout=_TIMEOUT_S) as mover:
        mover.write(b"#start!#mvs.+10!")
        mover.flush()
    # The next program is served as the first was, and followed by a #stop! of its own.
    assert pty_tap.controller.wait_for(b"#mvs.+10!" + STOP_FRAME) == (
        b"#start!#th.90.50!#stop!#start!#mvs.+10!" + STOP_FRAME
    )


class _HangingUpController:
    """A TCP 'controller' that keeps what it is sent until told to hang up."""

    def __init__(self) -> None:
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.url = f"socket://127.0.0.1:{self._listener.getsockname()[1]}"
        self.received = bytearray()
        self._hang_up = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        connection, _ = self._listener.accept()
        with connection:
            connection.settimeout(0.01)
            while not self._hang_up.is_set():
                with contextlib.suppress(TimeoutError):
                    self.received += connection.recv(4096)

    def hang_up(self) -> None:
        self._hang_up.set()
        self._thread.join(_TIMEOUT_S)
        self._listener.close()


def test_no_stop_is_recorded_as_sent_on_a_controller_link_that_is_lost() -> None:
    # The tap wrote #stop! to a controller that had hung up (the write "succeeded": a closed TCP
    # peer takes bytes until its reset comes back) and recorded it as sent: the recording said
    # the robot was stopped and locked when nothing reached it.
    controller = _HangingUpController()
    link = open_link(parse_url(controller.url))
    endpoint = TcpEndpoint("127.0.0.1", 0)
    recorded = _Chunks()
    lost: list[BaseException] = []

    def forwarding() -> None:
        try:
            stopping = threading.Event()
            forward(endpoint, _held(link, stopping), recorded, stopping)
        except BaseException as error:  # (kept for the assertion)
            lost.append(error)

    thread = threading.Thread(target=forwarding, daemon=True)
    thread.start()
    host, port = endpoint.path.removeprefix("socket://").rsplit(":", 1)
    mover = _program((host, int(port)))
    try:
        mover.sendall(b"#start!#th.90.50!")
        assert wait_until(lambda: controller.received.endswith(b"#th.90.50!"), _TIMEOUT_S)
        controller.hang_up()
        thread.join(_TIMEOUT_S)
        assert [type(error).__name__ for error in lost] == ["ConnectionLostError"]
        assert ("out", STOP_FRAME, True) not in recorded.chunks
    finally:
        mover.close()
        endpoint.close()
        link.close()
