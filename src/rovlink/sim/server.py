"""The simulated controller on a pseudo-terminal and/or a TCP port (``rovlink sim``).

One thread, one :mod:`selectors` loop: it steps the simulation on its wall-clock schedule, moves
bytes between the peers and the controller, and paces both directions at the line rate when a
baud rate is given. The TCP port takes one client at a time, as a serial port does.

Both links lead to the one controller, but each is its own wire: what the controller writes while
it handles bytes from a link (replies, and debug lines about those frames) goes back on that link
only. What it writes on its own (failsafe and leak lines, from its tick) goes to every link: the
TCP client if one is connected, and the PTY, which cannot tell whether a terminal program has it
open. Output that nobody reads is bounded (the oldest is dropped, as a UART overruns).
"""

from __future__ import annotations

import contextlib
import errno
import os
import selectors
import socket
import time
import tty
from collections.abc import Callable

from rovlink.logs import get_logger
from rovlink.sim.pacing import LinePacer, TickSchedule
from rovlink.sim.robot import SimConfig, SimulatedRobot

__all__ = ["BUSY_MESSAGE", "SimServer", "parse_tcp_address"]

logger = get_logger(__name__)

#: What a second TCP client reads before it is disconnected.
BUSY_MESSAGE = b"busy: the simulated controller already has a client\r\n"

_READ_BYTES = 4096
_MAX_PENDING_BYTES = 1 << 16
#: The longest the loop sleeps, so a stop request is seen promptly, s.
_MAX_WAIT_S = 0.05


def parse_tcp_address(text: str, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """``HOST:PORT``, ``:PORT`` or ``PORT`` (``[::1]:PORT`` for IPv6) as (host, port).

    >>> parse_tcp_address("5760")
    ('127.0.0.1', 5760)
    >>> parse_tcp_address("0.0.0.0:5760")
    ('0.0.0.0', 5760)
    """
    host, _, port_text = text.rpartition(":")
    host = host.strip("[]") or default_host
    if not port_text.isdigit() or not 0 <= int(port_text) <= 65535:
        raise ValueError(f"{text!r} is not HOST:PORT with a port 0–65535")
    return host, int(port_text)


class _Peer:
    """One end of the simulated serial line: a file descriptor and the line's two directions."""

    def __init__(self, name: str, fd: int, baud: int | None) -> None:
        self.name = name
        self.fd = fd
        self.to_controller = LinePacer(baud)
        self.from_controller = LinePacer(baud)
        self.unsent = bytearray()  # off the simulated line, not yet taken by the kernel

    def read(self) -> bytes | None:
        """Bytes from the peer; b"" when it has gone; None when there is nothing after all."""
        raise NotImplementedError

    def write(self, data: bytes) -> int:
        """Write what the kernel takes without blocking; return how many bytes it took."""
        raise NotImplementedError

    def close(self) -> None:
        """Release the descriptor(s)."""
        raise NotImplementedError


class _PtyPeer(_Peer):
    def __init__(self, baud: int | None) -> None:
        master_fd, slave_fd = os.openpty()
        # Raw mode on the terminal side: no echo, no line editing, no CR/LF translation, so the
        # program that opens it sees exactly the controller's bytes.
        tty.setraw(slave_fd)
        os.set_blocking(master_fd, False)
        super().__init__("pty", master_fd, baud)
        # Kept open so the pseudo-terminal lives on while terminal programs come and go.
        self._slave_fd = slave_fd
        self.path = os.ttyname(slave_fd)

    def read(self) -> bytes | None:
        try:
            return os.read(self.fd, _READ_BYTES) or None
        except BlockingIOError:
            return None
        except OSError as error:
            if error.errno == errno.EIO:  # no terminal side open: nothing to read
                return None
            raise

    def write(self, data: bytes) -> int:
        try:
            return os.write(self.fd, data)
        except BlockingIOError:
            return 0

    def close(self) -> None:
        os.close(self.fd)
        os.close(self._slave_fd)


class _TcpPeer(_Peer):
    def __init__(self, connection: socket.socket, baud: int | None) -> None:
        connection.setblocking(False)
        connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        peer = connection.getpeername()
        super().__init__(f"tcp client {peer[0]}:{peer[1]}", connection.fileno(), baud)
        self.connection = connection

    def read(self) -> bytes | None:
        try:
            return self.connection.recv(_READ_BYTES)
        except BlockingIOError:
            return None
        except OSError:
            return b""

    def write(self, data: bytes) -> int:
        try:
            return self.connection.send(data)
        except BlockingIOError:
            return 0

    def close(self) -> None:
        self.connection.close()


class SimServer:
    """One simulated robot served on a PTY and/or TCP, stepped in real time (or faster).

    ``baud`` paces both directions at that rate (8N1); ``None`` leaves the stream unpaced.
    ``speed`` is simulated seconds per wall second, 0 for as fast as the CPU allows.
    """

    def __init__(
        self,
        config: SimConfig | None = None,
        *,
        seed: int | None = None,
        baud: int | None = None,
        speed: float = 1.0,
    ) -> None:
        self.robot = SimulatedRobot(config, seed=seed, write=self._from_controller)
        self.baud = baud
        self.speed = speed
        # select(2) takes microsecond timeouts where epoll and poll round up to whole
        # milliseconds: pacing at 115200 baud needs a wake-up every 87 µs. A handful of
        # descriptors is all this loop ever watches.
        self._selector = selectors.SelectSelector()
        self._peers: list[_Peer] = []
        self._listener: socket.socket | None = None
        self._tcp_peer: _TcpPeer | None = None
        self.pty_path: str | None = None
        self.tcp_address: tuple[str, int] | None = None
        # The link whose bytes the controller is handling: its output goes back there only.
        self._replying_to: _Peer | None = None

    # -- endpoints ---------------------------------------------------------------------------

    def open_pty(self) -> str:
        """Open the pseudo-terminal; return the path a terminal program opens."""
        peer = _PtyPeer(self.baud)
        self._add_peer(peer)
        self.pty_path = peer.path
        return peer.path

    def listen_tcp(self, host: str = "127.0.0.1", port: int = 0) -> tuple[str, int]:
        """Listen on TCP; return the bound (host, port) (port 0 picks a free one)."""
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        listener = socket.socket(family, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            listener.bind((host, port))
            listener.listen(2)
        except OSError:
            listener.close()
            raise
        listener.setblocking(False)
        self._listener = listener
        self._selector.register(listener, selectors.EVENT_READ, self._on_connection)
        bound = listener.getsockname()
        self.tcp_address = (bound[0], bound[1])
        return self.tcp_address

    # -- the loop ----------------------------------------------------------------------------

    def serve(self, should_stop: Callable[[], bool]) -> None:
        """Run until ``should_stop()`` is true (checked at least every 50 ms)."""
        robot = self.robot
        schedule = TickSchedule(robot.tick_s, time.monotonic(), speed=self.speed)
        step = robot.step
        while not should_stop():
            now = time.monotonic()
            for _ in range(schedule.due(now)):
                step()
            self._pump()
            wait_s = min(schedule.seconds_until_next(time.monotonic()), self._next_byte_wait_s())
            for key, mask in self._selector.select(min(wait_s, _MAX_WAIT_S)):
                key.data(key, mask)

    def close(self) -> None:
        """Close every endpoint."""
        for peer in list(self._peers):
            self._remove_peer(peer)
        if self._listener is not None:
            self._selector.unregister(self._listener)
            self._listener.close()
            self._listener = None
        self._selector.close()

    # -- bytes -------------------------------------------------------------------------------

    def _from_controller(self, data: bytes) -> None:
        now = time.monotonic()
        source = self._replying_to
        if source is not None:
            source.from_controller.push(data, now)
            return
        for peer in self._peers:  # spontaneous output: a failsafe or leak line
            peer.from_controller.push(data, now)

    def _pump(self) -> None:
        """Move every byte whose time has come: to the controller, then to the peers."""
        now = time.monotonic()
        for peer in self._peers:
            data = peer.to_controller.release(now)
            if data:
                self._replying_to = peer
                try:
                    self.robot.receive(data)
                finally:
                    self._replying_to = None
        for peer in list(self._peers):
            data = peer.from_controller.release(now)
            if not data:
                continue  # anything still unsent waits for the selector to say it is writable
            peer.unsent += data
            overflow = len(peer.unsent) - _MAX_PENDING_BYTES
            if overflow > 0:  # nobody reads: drop the oldest, as a UART overruns
                del peer.unsent[:overflow]
            self._flush(peer)

    def _flush(self, peer: _Peer) -> None:
        try:
            written = peer.write(bytes(peer.unsent))
        except OSError as error:
            logger.info("%s: write failed (%s), disconnecting", peer.name, error)
            self._remove_peer(peer)
            return
        del peer.unsent[:written]
        events = selectors.EVENT_READ | (selectors.EVENT_WRITE if peer.unsent else 0)
        self._selector.modify(peer.fd, events, self._on_peer_event(peer))

    def _next_byte_wait_s(self) -> float:
        now = time.monotonic()
        wait_s = _MAX_WAIT_S
        for peer in self._peers:
            for pacer in (peer.to_controller, peer.from_controller):
                due = pacer.next_release_s()
                if due is not None:
                    wait_s = min(wait_s, max(due - now, 0.0))
        return wait_s

    # -- events ------------------------------------------------------------------------------

    def _on_peer_event(self, peer: _Peer) -> Callable[[selectors.SelectorKey, int], None]:
        def handle(key: selectors.SelectorKey, mask: int) -> None:
            if mask & selectors.EVENT_READ:
                self._on_readable(peer)
            if mask & selectors.EVENT_WRITE and peer in self._peers:
                self._flush(peer)

        return handle

    def _on_readable(self, peer: _Peer) -> None:
        data = peer.read()
        if data is None:
            return
        if not data:
            logger.info("%s disconnected", peer.name)
            self._remove_peer(peer)
            return
        peer.to_controller.push(data, time.monotonic())
        self._pump()  # unpaced, the reply leaves in this same turn of the loop

    def _on_connection(self, key: selectors.SelectorKey, mask: int) -> None:
        assert self._listener is not None
        try:
            connection, address = self._listener.accept()
        except BlockingIOError:
            return
        if self._tcp_peer is not None:
            logger.info("refused %s:%s: busy", address[0], address[1])
            with contextlib.suppress(OSError):
                connection.setblocking(False)
                connection.send(BUSY_MESSAGE)
            connection.close()
            return
        peer = _TcpPeer(connection, self.baud)
        self._tcp_peer = peer
        self._add_peer(peer)
        logger.info("%s connected", peer.name)

    def _add_peer(self, peer: _Peer) -> None:
        self._peers.append(peer)
        self._selector.register(peer.fd, selectors.EVENT_READ, self._on_peer_event(peer))

    def _remove_peer(self, peer: _Peer) -> None:
        self._peers.remove(peer)
        self._selector.unregister(peer.fd)
        peer.close()
        if peer is self._tcp_peer:
            self._tcp_peer = None
