"""The controller's serial lines as the operating system gives them: a serial device, a
pseudo-terminal and TCP clients (one at a time, as a serial port has one host), watched by one
:mod:`selectors` loop.

Both servers of the controller stand on this: the simulator (``rovlink sim``) and a real board
(``rovlink controller``). Each line is a non-blocking file descriptor with the bytes the kernel
has not taken yet; output that nobody reads is bounded (the oldest is dropped, as a UART
overruns). What a server does with the bytes it reads is its own (``on_bytes``).

>>> parse_tcp_address("5760"), parse_tcp_address("0.0.0.0:5760")
(('127.0.0.1', 5760), ('0.0.0.0', 5760))
>>> is_loopback("127.0.0.1"), is_loopback("0.0.0.0")
(True, False)
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import selectors
import socket
import termios
import time
import tty
from collections.abc import Callable
from typing import Any

from rovlink.busy_tcp import RefusedClients
from rovlink.logs import get_logger
from rovlink.serial_latency import ask_for_low_latency

__all__ = [
    "ACCEPT_PAUSE_S",
    "SILENT_CLIENT_GIVES_WAY_S",
    "Line",
    "Lines",
    "PtyLine",
    "SerialDeviceLine",
    "TcpLine",
    "is_loopback",
    "parse_tcp_address",
]

logger = get_logger(__name__)

_READ_BYTES = 4096
#: Reads of the TCP client being served when another connects, to see whether it has gone: its
#: last bytes and its hang-up (what a client that ends sends last) take two.
_DRAIN_READS = 4
#: Output kept for a line that does not read it, bytes.
MAX_PENDING_BYTES = 1 << 16
#: Empty reads in a row, each after select(2) said the device was readable, that mean a serial
#: device has gone (a USB adapter unplugged, the other end of a pseudo-terminal closed): its
#: descriptor then stays readable for good, and the loop would spin on it.
_HANGUP_EMPTY_READS = 3
#: How often a serial device that went away is opened again, s.
SERIAL_REOPEN_S = 1.0
#: How long a TCP client must have sent nothing before a new one takes its place, s: a host
#: keeps its link alive (P17; rovlink's hosts every idle second), so one silent this long has
#: lost it (a dropped Wi-Fi, a pulled cable leave the connection open), and its motion was
#: stopped by then.
SILENT_CLIENT_GIVES_WAY_S = 3.0
#: How long the listener is not watched after accept(2) failed for want of a file descriptor
#: (EMFILE, ENFILE) or of kernel memory, s. The waiting connection stays readable, so watching
#: it would spin the loop at 100 % CPU; the lines already connected are served meanwhile.
ACCEPT_PAUSE_S = 0.5
_ACCEPT_OUT_OF_RESOURCES = frozenset({errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM})


def parse_tcp_address(text: str, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """``HOST:PORT``, ``:PORT`` or ``PORT`` (``[::1]:PORT`` for IPv6) as (host, port)."""
    host, _, port_text = text.rpartition(":")
    host = host.strip("[]") or default_host
    if not port_text.isdigit() or not 0 <= int(port_text) <= 65535:
        raise ValueError(f"{text!r} is not HOST:PORT with a port 0–65535")
    return host, int(port_text)


def is_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback address (only this computer can connect)."""
    import ipaddress  # noqa: PLC0415

    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class Line:
    """One end of a serial line: a file descriptor, and bytes the kernel has not taken yet."""

    def __init__(self, name: str, fd: int) -> None:
        self.name = name
        self.fd = fd
        self.unsent = bytearray()
        #: Whether the line is read (see :meth:`Lines.set_reading`).
        self.reading = True
        #: The selector events the line is watched for (0: not registered).
        self.watched_events = 0
        #: When the line last read bytes (or opened), :func:`time.monotonic` seconds.
        self.last_bytes_s = time.monotonic()
        #: Whether the peer has ended its stream and the line stays open only to finish its
        #: output (see ``finishes_after_hangup`` of :class:`Lines`).
        self.hung_up = False

    def read(self) -> bytes | None:
        """Bytes from the peer; b"" when it has gone; None when there is nothing after all."""
        try:
            return os.read(self.fd, _READ_BYTES) or b""
        except BlockingIOError:
            return None

    def write(self, data: bytes) -> int:
        """Write what the kernel takes without blocking; how many bytes it took."""
        try:
            return os.write(self.fd, data)
        except BlockingIOError:
            return 0

    def close(self) -> None:
        """Release the descriptor."""
        os.close(self.fd)


def _read_terminal(fd: int) -> bytes | None:
    """A terminal's bytes; never b"": programs open and close a terminal, it stays."""
    try:
        return os.read(fd, _READ_BYTES) or None
    except BlockingIOError:
        return None
    except OSError as error:
        if error.errno == errno.EIO:  # no program has the other side open: nothing to read
            return None
        raise


class SerialDeviceLine(Line):
    """A serial device (a board's UART, a USB adapter), opened exclusively (P22) at ``baud``."""

    def __init__(self, path: str, baud: int) -> None:
        import serial  # noqa: PLC0415 - pyserial, loaded when a serial device is used

        self.path = path
        self.baud = baud
        self._empty_reads = 0
        self._serial: Any = serial.Serial(
            path, baud, timeout=0, write_timeout=0, exclusive=True, rtscts=False, dsrdtr=False
        )
        ask_for_low_latency(self._serial, path)  # (a USB adapter hands on each frame at once)
        fd = self._serial.fileno()
        os.set_blocking(fd, False)
        # pyserial's lock keeps out programs that lock too; TIOCEXCL keeps out every other
        # opener but root (a forgotten terminal program), until the port is closed.
        with contextlib.suppress(OSError):
            fcntl.ioctl(fd, termios.TIOCEXCL)
        super().__init__(f"serial {path}", fd)

    def read(self) -> bytes | None:
        """Bytes from the line; b"" once the device has gone (hung up: it reads as empty, or
        fails with EIO, every time select(2) says it is readable)."""
        try:
            data = os.read(self.fd, _READ_BYTES)
        except BlockingIOError:
            return None
        except OSError as error:
            if error.errno in (errno.EIO, errno.ENXIO, errno.ENODEV):
                return b""
            raise
        if data:
            self._empty_reads = 0
            return data
        self._empty_reads += 1
        return b"" if self._empty_reads >= _HANGUP_EMPTY_READS else None

    def close(self) -> None:
        """Close the port (and release its lock)."""
        self._serial.close()


class PtyLine(Line):
    """A pseudo-terminal for a program on the same computer; :attr:`path` is what it opens."""

    def __init__(self) -> None:
        master_fd, slave_fd = os.openpty()
        # Raw mode on the terminal side: no echo, no line editing, no CR/LF translation, so the
        # program that opens it sees exactly the controller's bytes.
        tty.setraw(slave_fd)
        os.set_blocking(master_fd, False)
        super().__init__("pty", master_fd)
        # Kept open so the pseudo-terminal lives on while terminal programs come and go.
        self._slave_fd = slave_fd
        self.path = os.ttyname(slave_fd)

    def read(self) -> bytes | None:
        """Bytes from the terminal side; never b"" (programs come and go)."""
        return _read_terminal(self.fd)

    def close(self) -> None:
        """Close both sides."""
        os.close(self.fd)
        os.close(self._slave_fd)


class TcpLine(Line):
    """One TCP client, with Nagle's algorithm off (a frame leaves at once)."""

    def __init__(self, connection: socket.socket) -> None:
        connection.setblocking(False)
        connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        peer = connection.getpeername()
        super().__init__(f"tcp client {peer[0]}:{peer[1]}", connection.fileno())
        self.connection = connection
        #: Whether the connection failed (reset by the client, or its host unreachable) rather
        #: than ended in order.
        self.failed = False

    def read(self) -> bytes | None:
        """Bytes from the client; b"" when it has gone."""
        try:
            return self.connection.recv(_READ_BYTES)
        except BlockingIOError:
            return None
        except OSError:
            self.failed = True
            return b""

    def write(self, data: bytes) -> int:
        """Send what the socket takes."""
        try:
            return self.connection.send(data)
        except BlockingIOError:
            return 0

    def close(self) -> None:
        """Close the connection."""
        self.connection.close()


class Lines:
    """The lines a controller is served on, and the one selector that watches them.

    ``on_bytes(line, data)`` gets what each line reads; ``on_open`` and ``on_close`` see lines
    come (a TCP client connecting) and go. A second TCP client reads ``busy_message`` and is
    disconnected, unless the first has sent nothing for ``silent_client_gives_way_s`` (0:
    never): a client whose link died without closing (a dropped Wi-Fi, a pulled cable: no FIN
    ever comes) would otherwise keep every host out, the robot's own included, for good.

    A TCP client that ends its stream (a shutdown of its side: ``echo '#qd!' | socat - TCP:…``)
    is let go at once, unless ``finishes_after_hangup(line)`` says the server still has that
    line's bytes in hand (a paced line's, on their way to the controller or back): the line is
    then no longer read, and stays open until the server calls :meth:`finish`.
    """

    def __init__(
        self,
        on_bytes: Callable[[Line, bytes], None],
        *,
        busy_message: bytes,
        on_open: Callable[[Line], None] | None = None,
        on_close: Callable[[Line], None] | None = None,
        silent_client_gives_way_s: float = 0.0,
        finishes_after_hangup: Callable[[Line], bool] | None = None,
    ) -> None:
        self._on_bytes = on_bytes
        self._finishes_after_hangup = finishes_after_hangup
        self._silent_client_gives_way_s = silent_client_gives_way_s
        self._on_open = on_open
        self._on_close = on_close
        # select(2) takes microsecond timeouts where epoll and poll round up to whole
        # milliseconds: pacing at 115200 baud needs a wake-up every 87 µs. A handful of
        # descriptors is all a controller ever watches.
        self._selector = selectors.SelectSelector()
        #: The open lines, in the order they opened.
        self.lines: list[Line] = []
        self._listener: socket.socket | None = None
        self._tcp_line: TcpLine | None = None
        self._refused = RefusedClients(self._selector, busy_message, data=self._on_refused_readable)
        self.pty_path: str | None = None
        self.tcp_address: tuple[str, int] | None = None
        # Serial devices that went away, (path, baud), and when each is next opened again.
        self._gone_serial: dict[tuple[str, int], float] = {}
        # When the listener, paused after accept(2) ran out of descriptors, is watched again.
        self._accept_paused_until_s: float | None = None
        self._accept_failures = 0

    # -- endpoints ---------------------------------------------------------------------------

    def open_serial(self, path: str, baud: int) -> None:
        """Serve on a serial device (opened exclusively)."""
        self._add(SerialDeviceLine(path, baud))

    def open_pty(self) -> str:
        """Serve on a new pseudo-terminal; the path a program opens."""
        line = PtyLine()
        self._add(line)
        self.pty_path = line.path
        return line.path

    def listen_tcp(self, host: str = "127.0.0.1", port: int = 0) -> tuple[str, int]:
        """Listen on TCP, one client at a time; the bound (host, port) (port 0: a free one)."""
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

    # -- moving bytes ------------------------------------------------------------------------

    def wait(self, timeout_s: float) -> None:
        """Wait up to ``timeout_s`` for the lines, and handle what they have."""
        if self._gone_serial:
            timeout_s = min(timeout_s, max(0.0, min(self._gone_serial.values()) - time.monotonic()))
        if self._accept_paused_until_s is not None:
            timeout_s = min(timeout_s, max(0.0, self._accept_paused_until_s - time.monotonic()))
        for key, mask in self._selector.select(timeout_s):
            key.data(key, mask)
        if self._refused:
            self._refused.expire(time.monotonic())
        if self._gone_serial:
            self._reopen_serial(time.monotonic())
        if (
            self._accept_paused_until_s is not None
            and time.monotonic() >= self._accept_paused_until_s
            and self._listener is not None
        ):
            self._accept_paused_until_s = None
            self._selector.register(self._listener, selectors.EVENT_READ, self._on_connection)

    def send(self, line: Line, data: bytes) -> None:
        """Write ``data`` to ``line``: now, what the kernel takes; the rest when it can."""
        if line not in self.lines:
            return
        line.unsent += data
        overflow = len(line.unsent) - MAX_PENDING_BYTES
        if overflow > 0:  # nobody reads: drop the oldest, as a UART overruns
            del line.unsent[:overflow]
        self._flush(line)

    def set_reading(self, line: Line, reading: bool) -> None:
        """Read ``line`` or leave its bytes in the kernel: a server whose controller is behind
        (a slow line's rate) stops reading, and the writer at the other end waits for room, as
        it would on a serial line whose buffer is full."""
        if line.hung_up:  # (nothing more comes from it)
            reading = False
        if line.reading != reading and line in self.lines:
            line.reading = reading
            self._watch(line)

    def finish(self, line: Line) -> None:
        """Let a hung-up ``line`` go now that its server has finished its output (what the
        kernel has not taken by now is dropped)."""
        if line in self.lines:
            self._flush(line)
        if line in self.lines:  # (a failed write has let it go already)
            logger.info("%s disconnected", line.name)
            self._remove(line)

    def close(self) -> None:
        """Close every line and the listener."""
        self._gone_serial.clear()
        for line in list(self.lines):
            self._remove(line)
        self._refused.close()
        if self._listener is not None:
            if self._accept_paused_until_s is None:
                self._selector.unregister(self._listener)
            self._accept_paused_until_s = None
            self._listener.close()
            self._listener = None
        self._selector.close()

    # -- events ------------------------------------------------------------------------------

    def _flush(self, line: Line) -> None:
        try:
            written = line.write(bytes(line.unsent))
        except OSError as error:
            # An unplugged adapter may show on a write before a read: it comes back as well.
            self._gone(line, error)
            return
        del line.unsent[:written]
        self._watch(line)

    def _watch(self, line: Line) -> None:
        """Watch ``line`` for what it waits for: bytes to read (unless reading is paused), room
        to write what is unsent."""
        events = (selectors.EVENT_READ if line.reading else 0) | (
            selectors.EVENT_WRITE if line.unsent else 0
        )
        if events == line.watched_events:
            return
        if not events:  # (a selector watches nothing for no events)
            self._selector.unregister(line.fd)
        elif line.watched_events:
            self._selector.modify(line.fd, events, self._on_line_event(line))
        else:
            self._selector.register(line.fd, events, self._on_line_event(line))
        line.watched_events = events

    def _on_refused_readable(self, key: selectors.SelectorKey, mask: int) -> None:
        connection = key.fileobj
        assert isinstance(connection, socket.socket)
        self._refused.on_readable(connection)

    def _on_line_event(self, line: Line) -> Callable[[selectors.SelectorKey, int], None]:
        def handle(key: selectors.SelectorKey, mask: int) -> None:
            if mask & selectors.EVENT_READ and line in self.lines:  # (not drained and let go)
                self._on_readable(line)
            if mask & selectors.EVENT_WRITE and line in self.lines:
                self._flush(line)

        return handle

    def _drain(self, line: TcpLine) -> None:
        """Handle what ``line`` has sent by now, its hang-up included (a few reads at most)."""
        for _ in range(_DRAIN_READS):
            if line is not self._tcp_line or not line.reading or not self._on_readable(line):
                return

    def _on_readable(self, line: Line) -> bool:
        """Read ``line`` once; True if it gave bytes (it may have more)."""
        data = line.read()
        if data is None:
            return False
        if not data:
            finishes = self._finishes_after_hangup
            # Only a stream ended in order: a failed connection has nobody left to answer, and
            # what it commanded must stop now.
            if (
                isinstance(line, TcpLine)
                and not line.failed
                and finishes is not None
                and finishes(line)
            ):
                line.hung_up = True
                self.set_reading(line, False)
                return False
            self._gone(line)
            return False
        line.last_bytes_s = time.monotonic()
        self._on_bytes(line, data)
        return True

    def _gone(self, line: Line, write_error: OSError | None = None) -> None:
        """Let ``line`` go (it hung up, or a write to it failed); a serial device is opened
        again every ``SERIAL_REOPEN_S``."""
        if isinstance(line, SerialDeviceLine):
            why = f"write failed: {write_error}" if write_error else "unplugged or hung up"
            logger.warning(
                "%s went away (%s); opening it again every %g s", line.name, why, SERIAL_REOPEN_S
            )
            self._gone_serial[(line.path, line.baud)] = time.monotonic() + SERIAL_REOPEN_S
        elif write_error is not None:
            logger.info("%s: write failed (%s), disconnecting", line.name, write_error)
        else:
            logger.info("%s disconnected", line.name)
        self._remove(line)

    def _reopen_serial(self, now_s: float) -> None:
        """Open again each serial device that went away and is due another try."""
        import serial  # noqa: PLC0415 - only serial devices get here

        for (path, baud), due_s in list(self._gone_serial.items()):
            if now_s < due_s:
                continue
            try:
                line = SerialDeviceLine(path, baud)
            except (serial.SerialException, OSError, ValueError) as error:
                logger.debug("serial %s: not back yet (%s)", path, error)
                self._gone_serial[(path, baud)] = now_s + SERIAL_REOPEN_S
                continue
            del self._gone_serial[(path, baud)]
            self._add(line)
            logger.warning("%s is back", line.name)

    def _on_connection(self, key: selectors.SelectorKey, mask: int) -> None:
        assert self._listener is not None
        try:
            connection, address = self._listener.accept()
        except (BlockingIOError, ConnectionAbortedError):  # (gone before it was accepted)
            return
        except OSError as error:
            if error.errno not in _ACCEPT_OUT_OF_RESOURCES:
                raise
            self._pause_accepting(error)
            return
        if self._accept_failures:
            logger.warning(
                "TCP %s:%s: accepting connections again (%d failed accepts while out of file "
                "descriptors)",
                *self._listener.getsockname()[:2],
                self._accept_failures,
            )
            self._accept_failures = 0
        current = self._tcp_line
        if current is not None:
            # Its hang-up may be waiting in this same turn, behind its last bytes (a program
            # that closed and connected again at once: run twice in a row, or reconnecting).
            self._drain(current)
            current = self._tcp_line
        if current is not None:
            silent_s = time.monotonic() - current.last_bytes_s
            gives_way_s = self._silent_client_gives_way_s
            if not gives_way_s or silent_s < gives_way_s:
                logger.info("refused %s:%s: busy", address[0], address[1])
                self._refused.refuse(connection)
                return
        try:
            line = TcpLine(connection)
        except OSError as error:
            # Reset while it waited to be accepted (a port scan, a client killed as it
            # connected): nobody to serve, and no reason to push out the one served. Before,
            # this ended the server.
            logger.info("%s:%s left before it was served (%s)", address[0], address[1], error)
            connection.close()
            return
        if current is not None:
            logger.warning(
                "%s sent nothing for %.1f s: disconnected for %s",
                current.name,
                silent_s,
                line.name,
            )
            self._remove(current)
        self._tcp_line = line
        self._add(line)
        logger.info("%s connected", line.name)

    def _pause_accepting(self, error: OSError) -> None:
        """Stop watching the listener for ``ACCEPT_PAUSE_S`` after accept(2) failed for want of
        resources: the connection waiting stays in the kernel's queue, and would make select(2)
        return at once for ever. Logged once until an accept succeeds again."""
        assert self._listener is not None
        if not self._accept_failures:
            host, port = self._listener.getsockname()[:2]
            logger.error(
                "TCP %s:%s: cannot accept a connection: %s; the lines connected are still "
                "served; trying again every %g s (raise the open-files limit: ulimit -n, or "
                "LimitNOFILE= in the systemd unit)",
                host,
                port,
                error.strerror or error,
                ACCEPT_PAUSE_S,
            )
        self._accept_failures += 1
        self._selector.unregister(self._listener)
        self._accept_paused_until_s = time.monotonic() + ACCEPT_PAUSE_S

    def _add(self, line: Line) -> None:
        self.lines.append(line)
        self._watch(line)
        if self._on_open is not None:
            self._on_open(line)

    def _remove(self, line: Line) -> None:
        self.lines.remove(line)
        if line.watched_events:
            self._selector.unregister(line.fd)
            line.watched_events = 0
        line.close()
        if line is self._tcp_line:
            self._tcp_line = None
        if self._on_close is not None:
            self._on_close(line)
