"""``FaultProxy`` in process, in front of a recording controller, with real sockets."""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Callable, Iterator
from typing import TypeVar

import pytest

from rovlink.busy_tcp import RefusedClients
from rovlink.client.errors import ConnectionLostError
from rovlink.client.links import PortLink, open_link
from rovlink.client.url import parse_url
from rovlink.faults import FaultPort, FaultSettings
from rovlink.faults.proxy import BUSY_MESSAGE, FaultProxy

pytestmark = pytest.mark.integration

_TIMEOUT_S = 5.0
T = TypeVar("T")


class RecordingController:
    """A TCP 'controller' that keeps every byte it is sent, in order."""

    def __init__(self) -> None:
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.address: tuple[str, int] = self._listener.getsockname()[:2]
        self._received = bytearray()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        connection, _ = self._listener.accept()
        with connection:
            while data := connection.recv(4096):
                with self._lock:
                    self._received += data

    @property
    def received(self) -> bytes:
        with self._lock:
            return bytes(self._received)

    def wait_for(self, expected: bytes) -> bytes:
        """What it was sent, once that ends with ``expected`` (fails after a timeout)."""
        return _wait_until(lambda: self.received, lambda got: got.endswith(expected))

    def close(self) -> None:
        self._listener.close()


def _wait_until(get: Callable[[], T], done: Callable[[T], bool]) -> T:
    deadline = time.monotonic() + _TIMEOUT_S
    while not done(value := get()):
        assert time.monotonic() < deadline, f"timed out; so far {value!r}"
        time.sleep(0.01)
    return value


@pytest.fixture
def proxied() -> Iterator[tuple[RecordingController, tuple[str, int]]]:
    """A proxy with no faults in front of a recording controller; its address."""
    with _proxy(FaultSettings()) as served:
        yield served


@contextlib.contextmanager
def _proxy(settings: FaultSettings) -> Iterator[tuple[RecordingController, tuple[str, int]]]:
    """A proxy with ``settings`` in front of a recording controller; its address."""
    controller = RecordingController()
    host, port = controller.address
    fault_port = FaultPort(open_link(parse_url(f"socket://{host}:{port}")), settings)
    proxy = FaultProxy(fault_port, "127.0.0.1", 0)
    stop = threading.Event()
    serving = threading.Thread(target=proxy.serve, args=(stop.is_set,), daemon=True)
    serving.start()
    try:
        yield controller, proxy.address
    finally:
        stop.set()
        serving.join(timeout=_TIMEOUT_S)
        fault_port.close()
        controller.close()


def _read_to_end(connection: socket.socket) -> bytes:
    connection.settimeout(_TIMEOUT_S)
    received = b""
    while chunk := connection.recv(4096):  # (a timeout raises: the client was kept waiting)
        received += chunk
    return received


def test_a_second_client_is_told_it_is_busy_and_its_commands_never_reach_the_controller(
    proxied: tuple[RecordingController, tuple[str, int]],
) -> None:
    # Before: listen(1) queued the second client; once the first left, its stale #start! and
    # #th.0.100! ran right after the proxy's safety #stop!.
    controller, address = proxied
    with socket.create_connection(address) as first:
        first.sendall(b"#debug1!")
        controller.wait_for(b"#debug1!")
        with socket.create_connection(address) as second:
            second.sendall(b"#start!#th.0.100!")
            assert _read_to_end(second) == BUSY_MESSAGE
        first.sendall(b"#qd!")  # the first client is undisturbed
        controller.wait_for(b"#qd!")
    controller.wait_for(b"#stop!")
    # The next client, after the first has gone, is served: only its own bytes go through.
    with socket.create_connection(address) as third:
        third.sendall(b"#qr!")
        assert controller.wait_for(b"#qr!") == b"#debug1!#qd!#stop!#qr!"


def test_a_client_that_closes_and_connects_again_at_once_is_served(
    proxied: tuple[RecordingController, tuple[str, int]],
) -> None:
    # A test suite that opens the proxy per test case connects again as soon as it has closed:
    # the proxy had not yet read the hang-up, and told about a third of them it was busy.
    controller, address = proxied
    for number in range(30):
        with socket.create_connection(address, timeout=_TIMEOUT_S) as client:
            frame = f"#mgmp.{number}!".encode()
            client.sendall(frame)
            # (Its frame passed on by the proxy, or the busy line instead, whichever comes.)
            client.settimeout(0.01)
            answer = b""
            deadline = time.monotonic() + _TIMEOUT_S
            while frame not in controller.received:
                with contextlib.suppress(TimeoutError):
                    answer += client.recv(len(BUSY_MESSAGE))
                assert BUSY_MESSAGE not in answer, f"client {number} was told the proxy is busy"
                assert time.monotonic() < deadline, f"client {number}'s frame never came"
    # Each client's #stop! went before the next one's bytes.
    assert controller.wait_for(b"#mgmp.29!#stop!").count(b"!#stop!#mgmp.") == 29


def test_a_departed_clients_delayed_bytes_never_follow_its_stop() -> None:
    # Before, the #stop! went out at once while the client's delayed chunks were still queued:
    # they reached the controller after it, and its #start!#mvs.-50! dived again.
    with _proxy(FaultSettings(delay_ms=300)) as (controller, address):
        with socket.create_connection(address) as first:
            first.sendall(b"#start!#mvdirect.1!#mvs.-50!")
        controller.wait_for(b"#stop!")
        # The next client's bytes queue behind anything left (a serial line never reorders).
        with socket.create_connection(address) as second:
            second.sendall(b"#qr!")
            assert controller.wait_for(b"#qr!") == b"#stop!#qr!"


def test_a_flood_of_refused_clients_is_bounded_and_the_served_one_is_undisturbed(
    proxied: tuple[RecordingController, tuple[str, int]],
) -> None:
    controller, address = proxied
    with socket.create_connection(address) as first:
        first.sendall(b"#qd!")
        controller.wait_for(b"#qd!")
        others = [socket.create_connection(address) for _ in range(RefusedClients.MAX_KEPT + 4)]
        try:
            for other in others:
                other.sendall(b"#start!")
                other.settimeout(_TIMEOUT_S)
                assert other.recv(4096) == BUSY_MESSAGE
        finally:
            for other in others:
                other.close()
        first.sendall(b"#qr!")
        assert controller.wait_for(b"#qr!") == b"#qd!#qr!"


def test_serve_returns_with_nothing_left_reading_the_port() -> None:
    # Before, the thread moving the controller's bytes could still be reading when serve()
    # returned: it found the port closed by its caller, and `rovlink fault` ended by Ctrl-C
    # or SIGTERM then reported a lost link, with status 1, about one time in three.
    controller = RecordingController()
    host, port = controller.address
    fault_port = FaultPort(open_link(parse_url(f"socket://{host}:{port}")), FaultSettings())
    proxy = FaultProxy(fault_port, "127.0.0.1", 0)
    stop = threading.Event()
    before = set(threading.enumerate())
    serving = threading.Thread(target=proxy.serve, args=(stop.is_set,), daemon=True)
    serving.start()
    # Once serve() has its threads (its own and the pump, which then waits on the port):
    _wait_until(lambda: len(set(threading.enumerate()) - before), lambda started: started >= 2)
    stop.set()
    serving.join(timeout=_TIMEOUT_S)
    assert not serving.is_alive()
    assert set(threading.enumerate()) <= before  # every thread serve() started has ended
    fault_port.close()
    assert proxy.lost is None
    assert controller.wait_for(b"#stop!")
    controller.close()


def test_a_lost_link_is_named_once_in_the_proxys_error() -> None:
    # Before: "fault proxy to tcp 127.0.0.1:N: tcp 127.0.0.1:N: closed by the other end".
    with socket.create_server(("127.0.0.1", 0)) as listener:
        host, port = listener.getsockname()[:2]
        link = open_link(parse_url(f"socket://{host}:{port}"))
        connection, _ = listener.accept()
    fault_port = FaultPort(link, FaultSettings(), name=f"fault proxy to {link.description}")
    fault_port.timeout = 0.05
    try:
        connection.close()  # the controller goes
        said = _wait_until(lambda: _read_error(fault_port), lambda error: error is not None)
        assert said is not None
        assert said.startswith(f"fault proxy to {link.description}: ")
        assert said.count(link.description) == 1, said
    finally:
        fault_port.close()


def _read_error(port: FaultPort) -> str | None:
    """What reading ``port`` raises, if it does (it waits ``port.timeout`` at the most)."""
    try:
        port.read(1)
    except ConnectionLostError as error:
        return str(error)
    return None


def test_bytes_still_delayed_when_the_port_closes_are_sent_not_dropped() -> None:
    # A program writes its last #stop! and closes its link at once: the stop must still reach
    # the controller, as a serial line delivers what was written before it was closed.
    controller = RecordingController()
    host, port = controller.address
    fault_port = FaultPort(
        open_link(parse_url(f"socket://{host}:{port}")), FaultSettings(delay_ms=5000)
    )
    try:
        fault_port.write(b"#start!#th.0.20!")
        fault_port.write(b"#stop!")
        fault_port.close()
        assert controller.wait_for(b"#stop!") == b"#start!#th.0.20!#stop!"
    finally:
        fault_port.close()
        controller.close()


class _RecordingLink:
    """An inner link that keeps what is written to it; its reads wait their whole time, as on
    a port that cannot be woken."""

    description = "recording link"

    def __init__(self) -> None:
        self.written = bytearray()

    def read_available(self, timeout_s: float) -> bytes:
        time.sleep(timeout_s)  # (the reader thread's poll: nothing comes from the controller)
        return b""

    def write(self, data: bytes) -> None:
        self.written += data

    def wake(self) -> None:
        pass

    def close(self) -> None:
        pass


def test_the_last_stop_is_sent_before_the_drivers_close_returns() -> None:
    # The client closing a fault:// port first gives up the writes waiting for room
    # (abort_writes), which closes the port from a thread of its own, then closes the link.
    # When that thread came first, the close in the program's thread returned at once, before
    # the held-back #stop! was sent: the program exited, its daemon threads with it, and the
    # controller never got the stop (rovlink send 'fault://?…&delay_ms=20' start 'mvs -30'
    # left the robot diving, two runs in three).
    for _ in range(20):  # (which close comes first is up to the threads)
        inner = _RecordingLink()
        link = PortLink(FaultPort(inner, FaultSettings(delay_ms=5000)), "fault://")
        link.write(b"#start!#mvs.-30!")
        link.write(b"#stop!")
        link.abort_writes()
        link.close()
        assert bytes(inner.written) == b"#start!#mvs.-30!#stop!"
