"""Both clients over real transports: a pseudo-terminal, TCP, and pyserial's own socket handler."""

from __future__ import annotations

import asyncio
import socket
import threading
from collections.abc import Iterator

import pytest

import rovlink
import rovlink.aio
from rovlink.client import ConnectError, ConnectionLostError, Sensors
from rovlink.client.links import PortLink, SerialFdLink, SocketLink
from tests.client.conftest import REPLY_TIMEOUT_S, wait_until
from tests.client.fake_controller import FakeController

pytestmark = pytest.mark.integration

EXPECTED_SENSORS = Sensors(123, 530, False, -1, 15, 275)


class _TcpFake:
    """A fake controller behind a listening socket on the loopback interface."""

    def __init__(self) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.fake: FakeController | None = None
        self.accepted = threading.Event()
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        connection, _ = self.server.accept()
        self.fake = FakeController(connection.detach())
        self.accepted.set()

    def connected(self) -> FakeController:
        """The fake serving the accepted connection. It may answer before this thread has
        stored it, so wait for that rather than take a reply as proof."""
        assert self.accepted.wait(5.0)
        assert self.fake is not None
        return self.fake

    def close(self) -> None:
        self.server.close()
        if self.fake is not None:
            self.fake.close()


@pytest.fixture
def tcp_fake() -> Iterator[_TcpFake]:
    server = _TcpFake()
    yield server
    server.close()


def test_blocking_client_over_a_pty(pty_fake: tuple[FakeController, str]) -> None:
    fake, path = pty_fake
    with rovlink.connect(path, keepalive=None, checksum=True, timeout=REPLY_TIMEOUT_S) as rov:
        assert isinstance(rov._link, SerialFdLink)
        assert rov.sensors() == EXPECTED_SENSORS
        rov.move(270, 25)
        assert rov.depth_cm() == 123
    # The readiness probe (P21), then the checksum mode, confirmed by a query; the robot moved,
    # so closing stops it.
    assert fake.wait_for(lambda f: f.frames()[-1:] == ["#stop!"])
    assert fake.frames()[:2] == ["#crcoff!", "#qd!"]
    assert fake.frames()[-6:] == ["#crcon!", "#qd!", "#qsa!", "#th.270.25!", "#qd!", "#stop!"]
    assert bytes(fake.raw).endswith(b"#crcon!#qd8C!#qsaB1!#th.270.25CA!#qd8C!#stop!")


def test_pty_disconnect_is_a_lost_connection(pty_fake: tuple[FakeController, str]) -> None:
    fake, path = pty_fake
    rov = rovlink.connect(path, keepalive=None, timeout=REPLY_TIMEOUT_S)
    fake.then("close")
    with pytest.raises(ConnectionLostError):
        rov.depth_cm()
    with pytest.raises(ConnectionLostError):
        rov.stop()
    rov.close()


def test_blocking_client_over_tcp(tcp_fake: _TcpFake) -> None:
    with rovlink.connect(
        f"socket://127.0.0.1:{tcp_fake.port}", keepalive=None, timeout=REPLY_TIMEOUT_S
    ) as rov:
        assert isinstance(rov._link, SocketLink)
        assert rov.heading_deg() == 275
        assert rov.leak_detected() is False
        tcp_fake.connected().close()
        assert wait_until(lambda: rov.closed)
        with pytest.raises(ConnectionLostError, match="closed by the other end"):
            rov.pitch_deg()


def test_blocking_client_through_pyserials_own_handler(tcp_fake: _TcpFake) -> None:
    url = f"socket://127.0.0.1:{tcp_fake.port}?logging=warning"
    with rovlink.connect(url, keepalive=None, timeout=REPLY_TIMEOUT_S) as rov:
        assert isinstance(rov._link, PortLink)
        assert rov.sensors() == EXPECTED_SENSORS


def test_connecting_to_nothing_is_a_connect_error() -> None:
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    server.close()
    with pytest.raises(ConnectionError, match="cannot open socket://"):
        rovlink.connect(f"socket://127.0.0.1:{port}")
    with pytest.raises(ConnectionError, match="No such file or directory"):
        rovlink.connect("/dev/nonexistent-rovlink-port")


#: A port written as another program writes it, and how the error says to write it (before:
#: "cannot open 127.0.0.1:5760: No such file or directory", and no word of socket://).
MISWRITTEN_PORTS = [
    ("127.0.0.1:5760", "No such file or directory (a TCP address is socket://127.0.0.1:5760)"),
    ("localhost:5760", "No such file or directory (a TCP address is socket://localhost:5760)"),
    (
        "/dev/nonexistent-rovlink-port:115200",
        "No such file or directory (a speed is /dev/nonexistent-rovlink-port?baudrate=115200)",
    ),
    ("/dev/nonexistent-rovlink-port", "No such file or directory"),
]


@pytest.mark.parametrize(("url", "reason"), MISWRITTEN_PORTS)
def test_a_miswritten_port_is_named_with_how_to_write_it(url: str, reason: str) -> None:
    with pytest.raises(ConnectError) as raised:
        rovlink.connect(url)
    assert str(raised.value) == f"cannot open {url}: {reason}"


def test_a_tcp_url_is_refused_with_how_to_write_it() -> None:
    # (An unknown scheme is refused before anything is opened: before, pyserial said "invalid
    # URL, protocol 'tcp' not known" as it failed to open it.)
    with pytest.raises(ValueError, match="unknown URL scheme tcp://") as raised:
        rovlink.connect("tcp://127.0.0.1:5760")
    assert str(raised.value).endswith(" (a TCP address is socket://127.0.0.1:5760)")


@pytest.mark.parametrize(("url", "reason"), MISWRITTEN_PORTS[:1])
async def test_the_asyncio_client_names_a_miswritten_port_alike(url: str, reason: str) -> None:
    with pytest.raises(ConnectError) as raised:
        await rovlink.aio.connect(url)
    assert str(raised.value) == f"cannot open {url}: {reason}"


async def test_async_client_over_a_pty(pty_fake: tuple[FakeController, str]) -> None:
    fake, path = pty_fake
    async with rovlink.aio.connect(path, keepalive=None, timeout=REPLY_TIMEOUT_S) as rov:
        results = await asyncio.gather(*(rov.sensors() for _ in range(50)))
        assert results == [EXPECTED_SENSORS] * 50
        await rov.claw_open()
    assert fake.wait_for(lambda f: f.frames()[-2:] == ["#h+!", "#stop!"])  # (stopped on close)


async def test_async_client_over_tcp_and_disconnect(tcp_fake: _TcpFake) -> None:
    rov = await rovlink.aio.connect(
        f"socket://127.0.0.1:{tcp_fake.port}", keepalive=None, timeout=REPLY_TIMEOUT_S
    )
    assert await rov.depth_cm() == 123
    tcp_fake.connected().then("close")
    with pytest.raises(ConnectionLostError):
        await rov.depth_cm()
    await rov.close()


async def test_async_client_through_pyserials_own_handler(tcp_fake: _TcpFake) -> None:
    url = f"socket://127.0.0.1:{tcp_fake.port}?logging=warning"
    async with rovlink.aio.connect(url, keepalive=None, timeout=REPLY_TIMEOUT_S) as rov:
        assert await rov.heading_deg() == 275
        assert await rov.roll_deg() == -1


class _TimedPort:
    """A pyserial-like port that notes the timeout each read is made with (none comes)."""

    def __init__(self, *, timeout_is_free: bool) -> None:
        if timeout_is_free:
            self.timeout_is_free = True
        self.timeout: float | None = None
        self.is_open = True
        self.in_waiting = 0
        self.read_timeouts: list[float | None] = []

    def read(self, size: int = 1) -> bytes:
        self.read_timeouts.append(self.timeout)
        return b""

    def write(self, data: bytes) -> int:
        return len(data)

    def close(self) -> None:
        self.is_open = False


def test_a_port_whose_timeout_is_free_is_read_for_the_time_asked_up_to_the_poll() -> None:
    # The simulator's port: before, every read waited the full 50 ms poll, so a 20 ms wait of
    # `rovlink check` took 50 ms and a run on the simulator 5 s longer than on a PTY.
    free = _TimedPort(timeout_is_free=True)
    link = PortLink(free, "free")
    for asked_s in (0.02, 5.0, 0.0, -1.0):
        assert link.read_available(asked_s) == b""
    assert free.read_timeouts == [0.02, 0.05, 0.001, 0.001]
    # A real port is reconfigured by a new timeout: read at the fixed poll, whatever is asked.
    fixed = _TimedPort(timeout_is_free=False)
    link = PortLink(fixed, "fixed")
    link.read_available(0.02)
    assert fixed.read_timeouts == [0.05]


def test_the_simulators_port_says_its_timeout_is_free() -> None:
    from rovlink.sim.port import SimulatedPort

    assert SimulatedPort.timeout_is_free is True
