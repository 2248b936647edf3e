"""Links: the byte pipe under a client, opened from an :class:`~rovlink.client.url.Endpoint`.

Two kinds, one interface. Ports with a file descriptor — a POSIX serial device or pseudo-terminal
opened by pyserial, a TCP socket — are read with ``select`` and one ``read`` of whatever is
waiting: pyserial's own ``read``/``read_until`` loop costs a system call per requested byte count
and dominates a query's round trip. Everything else pyserial-like (``loop://``, ``rfc2217://``,
the in-process simulated port) goes through its ``read``/``in_waiting``/``write``.

Errors of the underlying port become :class:`~rovlink.client.errors.ConnectionLostError`.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import re
import select
import socket
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from rovlink.client.errors import ConnectError, ConnectionLostError
from rovlink.client.schemes import load_handler
from rovlink.client.terminal_owner import PSEUDO_TERMINAL_MAJORS, terminal_owner
from rovlink.client.url import Endpoint, Scheme
from rovlink.protocol.frames import BITS_PER_BYTE_8N1
from rovlink.serial_latency import ask_for_low_latency

__all__ = [
    "MAX_QUEUED_LINE_S",
    "POLL_INTERVAL_S",
    "Link",
    "PortLink",
    "SerialFdLink",
    "SocketLink",
    "abort_writes",
    "open_link",
    "queued_line_s",
]

#: How long a read of a port without a file descriptor blocks before it looks around again.
POLL_INTERVAL_S = 0.05
#: The most line time a client lets queue ahead of a frame it sends other than ``#stop!``, s:
#: what a ``#stop!`` may wait behind (see :meth:`SerialFdLink.queued_s`).
MAX_QUEUED_LINE_S = 0.02
#: The shortest wait of a read on a port whose timeout is free to set, s (no busy loop).
_MIN_READ_S = 0.001
#: A write that cannot make progress for this long means the link is dead.
WRITE_TIMEOUT_S = 2.0
CONNECT_TIMEOUT_S = 5.0
_READ_BYTES = 65536

if sys.platform != "win32":
    import fcntl
    import termios

logger = logging.getLogger(__name__)


class Link(Protocol):
    """A bidirectional byte pipe to the controller.

    Example::

        link = open_link(parse_url("socket://localhost:5760"))
        client = Client(link)   # the client owns the link from here on
    """

    description: str

    def read_available(self, timeout_s: float) -> bytes:
        """Wait up to about ``timeout_s`` for bytes; return all that are waiting (maybe none).

        Example::

            data = link.read_available(0.1)   # b"" if nothing came
        """
        ...

    def write(self, data: bytes) -> None:
        """Write all of ``data``.

        Example::

            link.write(b"#qd!")
        """
        ...

    def wake(self) -> None:
        """Make a ``read_available`` blocked in another thread return soon.

        Example::

            threading.Thread(target=link.read_available, args=(5.0,)).start()
            link.wake()   # that read returns now rather than in 5 s
        """
        ...

    def close(self) -> None:
        """Release the port (idempotent).

        Example::

            link.close()
        """
        ...


class FdLink:
    """Base of links over a file descriptor: ``poll`` plus non-blocking reads and writes.

    The asyncio client uses :meth:`fileno`, :meth:`recv_some` and :meth:`send_some` directly.
    A socket pair (which ``select`` accepts everywhere) wakes a blocked reader.
    """

    description = "fd"

    def __init__(self, fd: int) -> None:
        self._fd = fd
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._wake_fd = self._wake_r.fileno()
        # A write waiting for room is woken apart from readers (see abort_writes).
        self._abort_r, self._abort_w = socket.socketpair()
        self._abort_r.setblocking(False)
        self._abort_w.setblocking(False)
        self._writes_aborted = False
        # A registered poll object costs half of building select's lists on every read.
        self._poll: select.poll | None = None
        if hasattr(select, "poll"):
            self._poll = select.poll()
            self._poll.register(fd, select.POLLIN)
            self._poll.register(self._wake_fd, select.POLLIN)
        self._closed = False

    def fileno(self) -> int:
        """The descriptor to watch for readability.

        Example::

            loop.add_reader(link.fileno(), on_readable)
        """
        return self._fd

    # Subclasses read and write without blocking; b"" / 0 mean "nothing now".
    def recv_some(self) -> bytes:
        """Whatever is waiting now, b"" if nothing; raise ConnectionLostError at end of stream.

        Example::

            data = link.recv_some()   # never blocks
        """
        raise NotImplementedError

    def send_some(self, data: bytes | bytearray | memoryview) -> int:
        """Write what fits now; the number of bytes written (0 if none fit).

        Example::

            unsent = data[link.send_some(data):]
        """
        raise NotImplementedError

    def read_available(self, timeout_s: float) -> bytes:
        """Wait up to ``timeout_s`` for bytes; return all that are waiting (maybe none).

        Example::

            data = link.read_available(0.1)   # b"" if nothing came
        """
        if self._closed:
            raise ConnectionLostError(f"{self.description}: closed")
        fd = self._fd
        try:
            if self._poll is not None:
                events = self._poll.poll(max(timeout_s, 0.0) * 1000.0)
                if len(events) == 1 and events[0][0] == fd:  # the usual case: only the port
                    # Read in place, not through recv_some: after a sleep in poll every call
                    # layer costs cache misses. A descriptor read serves devices and sockets.
                    try:
                        data = os.read(fd, _READ_BYTES)
                    except BlockingIOError:
                        return b""
                    except OSError as error:  # as recv_some reports it
                        raise ConnectionLostError(
                            f"{self.description}: {error.strerror or error}"
                        ) from error
                    return data or self.recv_some()  # the end: the subclass says of what
                ready = [ready_fd for ready_fd, _ in events]
            else:
                ready, _, _ = select.select([fd, self._wake_fd], [], [], max(timeout_s, 0.0))
        except ConnectionLostError:
            raise
        except (OSError, ValueError) as error:
            raise ConnectionLostError(f"{self.description}: {error}") from error
        if self._wake_fd in ready:
            with contextlib.suppress(OSError):
                self._wake_r.recv(4096)
        if fd not in ready:
            return b""
        return self.recv_some()

    def write(self, data: bytes) -> None:
        """Write all of ``data``, waiting for room at most :data:`WRITE_TIMEOUT_S` at a time,
        unless :meth:`abort_writes` gives the write up first.

        Example::

            link.write(b"#qd!")
        """
        if self._writes_aborted:
            raise _write_abandoned(self.description)
        written = self.send_some(data)
        if written == len(data):  # nearly always: a frame fits in the kernel's buffer
            return
        view = memoryview(data)[written:]
        while view:
            written = self.send_some(view)
            view = view[written:]
            if view and not written:
                try:
                    _, ready, _ = select.select([self._abort_r], [self._fd], [], WRITE_TIMEOUT_S)
                except (OSError, ValueError) as error:
                    raise ConnectionLostError(f"{self.description}: {error}") from error
                if self._writes_aborted:
                    raise _write_abandoned(self.description)
                if not ready:
                    raise ConnectionLostError(
                        f"{self.description}: write blocked for {WRITE_TIMEOUT_S:g} s"
                    )

    def abort_writes(self) -> None:
        """Give up every write waiting for room, now and from now on: the link is lost.

        A serial device whose far end stopped reading keeps a writer waiting until the write
        times out, and closing the descriptor does not wake it (a socket's shutdown does): the
        writer holds the client's wire lock meanwhile, and a ``#stop!`` would wait behind it.
        Safe from any thread; the descriptor stays open until :meth:`close`.

        Example::

            link.abort_writes()   # a write waiting in another thread raises ConnectionLostError
        """
        self._writes_aborted = True
        with contextlib.suppress(OSError):  # a wake-up already pending, or closed
            self._abort_w.send(b"x")

    def wake(self) -> None:
        """Make a ``read_available`` blocked in another thread return now.

        Example::

            threading.Thread(target=link.read_available, args=(5.0,)).start()
            link.wake()   # that read returns now rather than in 5 s
        """
        with contextlib.suppress(OSError):  # a wake-up already pending, or closed
            self._wake_w.send(b"x")

    def close(self) -> None:
        """Close the port and the wake-up pipe (idempotent).

        Example::

            link.close()
        """
        if self._closed:
            return
        self._closed = True
        self.abort_writes()  # (a writer waiting for room must not write on a reused number)
        if self._poll is not None:
            with contextlib.suppress(KeyError, ValueError):
                self._poll.unregister(self._fd)
        self._close_port()
        self._wake_r.close()
        self._wake_w.close()
        self._abort_r.close()
        self._abort_w.close()

    def _close_port(self) -> None:
        raise NotImplementedError


class SerialFdLink(FdLink):
    """A POSIX serial device or pseudo-terminal opened (and configured) by pyserial.

    Example::

        port = serial.Serial("/dev/ttyUSB0", 115200, timeout=0)
        link = SerialFdLink(port, "/dev/ttyUSB0 at 115200 baud")
    """

    def __init__(self, port: Any, description: str, *, exclusive: bool = False) -> None:
        super().__init__(port.fileno())
        self._port = port
        self.description = description
        os.set_blocking(self._fd, False)  # pyserial opens it so; make sure
        #: Whether the terminal's own exclusive mode was set (see :func:`_set_exclusive_mode`).
        self.exclusive_mode = exclusive and _set_exclusive_mode(self._fd)
        # The kernel takes a few KB at once (4 KB: a UART's or a USB adapter's buffer), which a
        # line takes seconds to send at a low rate; what is written is timed at the port's rate.
        baudrate = getattr(port, "baudrate", None)
        self._byte_s = BITS_PER_BYTE_8N1 / baudrate if isinstance(baudrate, int) else 0.0
        self._line_free_at_s = 0.0  # when the last byte written has left the line (estimated)

    def queued_s(self) -> float:
        """Seconds the line still needs for the bytes written to it, estimated at its baud rate.

        Example::

            link.write(b"#th.90.50!")
            link.queued_s()   # 0.0104 at 9600 baud, falling to 0 as the frame leaves
        """
        return max(self._line_free_at_s - time.monotonic(), 0.0)

    def recv_some(self) -> bytes:
        """Whatever is waiting now; raise ConnectionLostError if the device went away.

        Example::

            data = link.recv_some()   # b"" when nothing is waiting
        """
        try:
            data = os.read(self._fd, _READ_BYTES)
        except BlockingIOError:
            return b""
        except OSError as error:  # EIO: the other side of a pseudo-terminal closed
            raise ConnectionLostError(f"{self.description}: {error.strerror or error}") from error
        if not data:
            # A device that is readable but yields nothing has been unplugged.
            raise ConnectionLostError(f"{self.description}: device disconnected")
        return data

    def send_some(self, data: bytes | bytearray | memoryview) -> int:
        """Write what fits now; the number of bytes written (0 if none fit).

        Example::

            unsent = data[link.send_some(data):]
        """
        try:
            written = os.write(self._fd, data)
        except BlockingIOError:
            return 0
        except OSError as error:
            raise ConnectionLostError(f"{self.description}: {error.strerror or error}") from error
        if self._byte_s:
            now_s = time.monotonic()
            start_s = self._line_free_at_s if self._line_free_at_s > now_s else now_s
            self._line_free_at_s = start_s + written * self._byte_s
        return written

    def _close_port(self) -> None:
        if self.exclusive_mode:
            # Cleared before closing: the mode belongs to the terminal, not to this descriptor,
            # and outlives it while anything else (a root process) still has the port open.
            with contextlib.suppress(OSError):
                fcntl.ioctl(self._fd, termios.TIOCNXCL)
        with contextlib.suppress(OSError):
            self._port.close()


def _is_pseudo_terminal(fd: int) -> bool:
    """Whether ``fd`` is the terminal side of a Unix98 pseudo-terminal (``/dev/pts/N``)."""
    try:
        return os.major(os.fstat(fd).st_rdev) in PSEUDO_TERMINAL_MAJORS
    except OSError:
        return False


def _set_exclusive_mode(fd: int) -> bool:
    """Set the terminal's exclusive mode (``TIOCEXCL``); whether it was set.

    pyserial's ``exclusive`` lock (``flock``) keeps out programs that take the same lock;
    exclusive mode makes the kernel refuse every other opener but root (a forgotten ``screen``
    or ``cat``) with "Device or resource busy", until the mode is cleared or the port's last
    descriptor closes. A pseudo-terminal is left out: the program serving it (``rovlink sim``)
    keeps its terminal side open, so the mode would outlive a host that crashed and lock out
    every later one but root's until the simulator restarts.
    """
    if _is_pseudo_terminal(fd):
        return False
    try:
        fcntl.ioctl(fd, termios.TIOCEXCL)
    except OSError as error:  # (not a terminal after all: the flock still holds)
        logger.debug("exclusive mode not set on descriptor %d: %s", fd, error)
        return False
    return True


class SocketLink(FdLink):
    """A TCP connection (``socket://host:port``) with Nagle's algorithm off.

    Example::

        sock = socket.create_connection(("localhost", 5760))
        link = SocketLink(sock, "tcp localhost:5760")
    """

    def __init__(self, sock: socket.socket, description: str) -> None:
        super().__init__(sock.fileno())
        self._socket = sock
        self.description = description
        if sock.family in (socket.AF_INET, socket.AF_INET6):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        # Non-blocking: a caller waiting for its reply polls with an absolute deadline (see
        # FdLink.read_available). A read asleep in ``recv`` with the kernel's receive timeout
        # (SO_RCVTIMEO) restarted with the whole timeout each time the process was stopped and
        # continued (SIGSTOP/SIGCONT, a profiler's ptrace), so a query could wait for ever.
        sock.setblocking(False)

    def recv_some(self) -> bytes:
        """Whatever is waiting now; raise ConnectionLostError when the peer closed.

        Example::

            data = link.recv_some()   # b"" when nothing is waiting
        """
        try:
            data = self._socket.recv(_READ_BYTES)
        except BlockingIOError:
            return b""
        except OSError as error:
            raise ConnectionLostError(f"{self.description}: {error.strerror or error}") from error
        if not data:
            raise ConnectionLostError(f"{self.description}: closed by the other end")
        return data

    def send_some(self, data: bytes | bytearray | memoryview) -> int:
        """Write what fits now; the number of bytes written (0 if none fit).

        Example::

            unsent = data[link.send_some(data):]
        """
        try:
            return self._socket.send(data)
        except BlockingIOError:
            return 0
        except OSError as error:
            raise ConnectionLostError(f"{self.description}: {error.strerror or error}") from error

    def _close_port(self) -> None:
        with contextlib.suppress(OSError):  # wakes a read asleep in poll in another thread
            self._socket.shutdown(socket.SHUT_RDWR)
        self._socket.close()


class PortLink:
    """Any pyserial-like port: ``read``, ``in_waiting``, ``write``, ``close``, ``timeout``.

    Example::

        link = PortLink(serial.serial_for_url("loop://"), "loopback")
    """

    def __init__(self, port: Any, description: str) -> None:
        self._port = port
        self.description = description
        #: Whether a write may wait for the port (a line with no room, a stalled network): the
        #: asyncio client then writes from a thread of its own. A port whose writes never wait
        #: (an in-process one, such as the simulator's) says so with ``writes_may_wait = False``.
        self.writes_may_wait: bool = getattr(port, "writes_may_wait", True)
        #: Whether setting the port's ``timeout`` costs nothing (no device to reconfigure, as
        #: with the simulator's port, which says so with ``timeout_is_free = True``): each read
        #: then waits its own time, up to :data:`POLL_INTERVAL_S`, not always that interval.
        self._timeout_per_read: bool = getattr(port, "timeout_is_free", False)
        port.timeout = POLL_INTERVAL_S
        self._closed = False
        self._writes_aborted = False

    @property
    def port(self) -> Any:
        """The wrapped port object.

        Example::

            print(link.port.name)
        """
        return self._port

    def read_available(self, timeout_s: float) -> bytes:
        """Wait up to :data:`POLL_INTERVAL_S` for bytes (up to ``timeout_s``, if shorter, on a
        port whose timeout is free to set); return all waiting.

        Example::

            data = link.read_available(0.1)   # b"" if nothing came
        """
        # (changing a pyserial timeout reconfigures the port: others poll at a fixed rate)
        if self._timeout_per_read:
            self._port.timeout = min(max(timeout_s, _MIN_READ_S), POLL_INTERVAL_S)
        if self._closed:
            raise ConnectionLostError(f"{self.description}: closed")
        try:
            first = self._port.read(1)
            if not first:
                if not self._port.is_open:
                    raise ConnectionLostError(f"{self.description}: port closed")
                return b""
            waiting: int = self._port.in_waiting
            rest: bytes = self._port.read(waiting) if waiting else b""
            return bytes(first) + rest
        except ConnectionLostError:
            raise
        except Exception as error:  # pyserial and stand-ins raise their own OSError kinds
            raise ConnectionLostError(f"{self.description}: {error}") from error

    def write(self, data: bytes) -> None:
        """Write all of ``data``.

        Example::

            link.write(b"#qd!")
        """
        if self._closed:
            raise ConnectionLostError(f"{self.description}: closed")
        if self._writes_aborted:
            raise _write_abandoned(self.description)
        try:
            self._port.write(data)
        except Exception as error:
            raise ConnectionLostError(f"{self.description}: {error}") from error
        # (pyserial's write returns, as if it had written, when cancel_write gives it up.)
        if self._writes_aborted:
            raise _write_abandoned(self.description)

    def abort_writes(self) -> None:
        """Give up every write waiting for room, now and from now on: the link is lost.

        Where the port can (pyserial's ports on POSIX, and wrappers of them such as
        ``spy://``, through ``cancel_write``), a write waiting in another thread returns at
        once. A port that cannot cancel a write (``rfc2217://``, whose write waits up to its
        socket's timeout, 5 s) is closed instead, in a thread of its own (its close may wait),
        which ends the write as well. Either way it raises :class:`ConnectionLostError` rather
        than report the data written.

        Example::

            link.abort_writes()   # a write waiting in another thread raises ConnectionLostError
        """
        first = not self._writes_aborted
        self._writes_aborted = True
        cancel = getattr(self._port, "cancel_write", None)
        if cancel is not None:
            with contextlib.suppress(Exception):  # (a port closed meanwhile)
                cancel()
        elif first and self.writes_may_wait and not self._closed:
            threading.Thread(
                target=self._close_port_quietly,
                name=f"rovlink abort writes ({self.description})",
                daemon=True,
            ).start()

    def _close_port_quietly(self) -> None:
        with contextlib.suppress(Exception):  # (close() closes it again, and says so)
            self._port.close()

    def wake(self) -> None:
        """Interrupt a blocked read where the port supports it; otherwise it returns on its own.

        Example::

            link.wake()   # a read in another thread returns within POLL_INTERVAL_S
        """
        cancel = getattr(self._port, "cancel_read", None)
        if cancel is not None:
            with contextlib.suppress(Exception):
                cancel()

    def close(self) -> None:
        """Close the port (idempotent).

        Example::

            link.close()
        """
        if not self._closed:
            self._closed = True
            self.abort_writes()  # (a writer waiting for room must not outlive the port)
            self._port.close()


def abort_writes(link: Link | None) -> None:
    """Give up the writes waiting for room on ``link``, where it can (the links of this module:
    ``FdLink.abort_writes``, ``PortLink.abort_writes``); others' writes end at their timeout.

    Example::

        abort_writes(link)   # the link is lost: a writer waiting in another thread gives up
    """
    abort = getattr(link, "abort_writes", None)
    if abort is not None:
        abort()


def queued_line_s(link: Link) -> Callable[[], float] | None:
    """How to read the seconds ``link``'s line still needs for what was written to it (see
    :meth:`SerialFdLink.queued_s`); None for a link that does not know (TCP, ``loop://``).

    Example::

        queued_s = queued_line_s(link)
        if queued_s is not None and queued_s() > 0.1:
            print("the line is behind")
    """
    queued_s: Callable[[], float] | None = getattr(link, "queued_s", None)
    return queued_s


def _write_abandoned(description: str) -> ConnectionLostError:
    """What a write given up by ``abort_writes`` raises."""
    return ConnectionLostError(f"{description}: write abandoned, the link is lost")


def _open_serial(endpoint: Endpoint) -> Link:
    import serial  # noqa: PLC0415 - pyserial is only needed when a serial port is opened
    from serial import serialposix  # noqa: PLC0415

    # A device is opened exclusively (P22): a second program on the same port would share its
    # byte stream and steal replies. pyserial's URL handlers have no such notion.
    options: dict[str, Any] = (
        {"exclusive": True} if endpoint.is_device and os.name == "posix" else {}
    )
    if endpoint.is_device:  # (before opening: opening sets the terminal's modes)
        _refuse_a_terminal_in_use(endpoint.target)
    # pyserial's rfc2217:// refuses a write timeout (NotImplementedError); its writes wait at
    # most its socket's timeout, 5 s.
    if not endpoint.target.lower().startswith("rfc2217://"):
        options["write_timeout"] = WRITE_TIMEOUT_S
    try:
        port = serial.serial_for_url(
            endpoint.target, baudrate=endpoint.baudrate, timeout=POLL_INTERVAL_S, **options
        )
    except (OSError, ValueError) as error:
        raise ConnectError(_open_error(endpoint, error)) from error
    description = f"{endpoint.target} at {endpoint.baudrate} baud"
    # Only pyserial's own POSIX class is read through its descriptor: wrappers such as spy://
    # log in read() and write(), which reading the descriptor would bypass.
    if type(port) is serialposix.Serial:
        ask_for_low_latency(port, endpoint.target)  # (a USB adapter's replies come at once)
        return SerialFdLink(port, description, exclusive="exclusive" in options)
    return PortLink(port, description)


def _refuse_a_terminal_in_use(path: str) -> None:
    """Raise ConnectError if pseudo-terminal ``path`` is a process's controlling terminal: a
    person's terminal window (a reused or mistyped ``/dev/pts/N``), never a controller's."""
    owner = terminal_owner(path)
    if owner is not None:
        raise ConnectError(
            f"{path} is the terminal of process {owner.pid} ({owner.name}), not a controller's "
            "port (a pseudo-terminal's number is reused once its program ends)"
        )


def _open_error(endpoint: Endpoint, error: BaseException) -> str:
    """One line naming the port and what went wrong, in a user's words."""
    name = endpoint.target
    text = str(error)
    errno_value = getattr(error, "errno", None)
    if "exclusively lock" in text or errno_value == errno.EBUSY:
        if _locked_by_this_process(name):
            return (
                f"{name} is already open in this program: a client that was not closed? (close "
                "it first, or connect in a `with` block; a port has one host at a time)"
            )
        return f"{name} is already open in another program (a port has one host at a time)"
    if errno_value == errno.ENOTTY or "Inappropriate ioctl" in text:
        return f"{name}: not a serial port"
    if errno_value == errno.EACCES or "Permission denied" in text:
        return f"{name}: permission denied (is the user in the dialout group?)"
    if "waiting for option 'control'" in text:  # (pyserial's rfc2217://, after 3 s)
        return (
            f"cannot open {name}: the server does not acknowledge modem control (ser2net on a"
            " port without modem lines does not): add ?ign_set_control to the URL"
        )
    reason = getattr(error, "strerror", None) or text
    if errno_value == errno.ENOENT or "No such file" in text:
        reason = os.strerror(errno.ENOENT) + _address_hint(name)
    return f"cannot open {name}: {reason}"


def _locked_by_this_process(path: str) -> bool:
    """Whether this process holds the exclusive lock on device ``path`` (Linux's
    ``/proc/locks``; False where it cannot tell): a client that a program, a notebook or a
    shell session never closed, not another program.

    >>> _locked_by_this_process("/dev/no-such-port")
    False
    """
    try:
        status = os.stat(path)
        with open("/proc/locks", encoding="ascii", errors="replace") as locks:
            table = locks.read()
    except OSError:
        return False
    device = f"{os.major(status.st_dev):02x}:{os.minor(status.st_dev):02x}:{status.st_ino}"
    pid = str(os.getpid())
    # "1: FLOCK  ADVISORY  WRITE 1234 00:1a:7 0 EOF": kind, ..., pid, device:inode, range.
    return any(
        fields[1] == "FLOCK" and fields[4] == pid and fields[5] == device
        for fields in (line.split() for line in table.splitlines())
        if len(fields) > 5
    )


#: A name that is no device but ends in ``:NUMBER``: a TCP address or a speed written as a
#: network tool or another program writes it (``127.0.0.1:5760``, ``/dev/ttyUSB0:115200``).
_ENDS_IN_A_NUMBER = re.compile(r"(?P<before>[^:?]+):(?P<number>\d+)")


def _address_hint(name: str) -> str:
    """How to write what a missing device's name was probably meant to be, or nothing.

    >>> _address_hint("127.0.0.1:5760")
    ' (a TCP address is socket://127.0.0.1:5760)'
    >>> _address_hint("/dev/ttyUSB0:115200")
    ' (a speed is /dev/ttyUSB0?baudrate=115200)'
    >>> _address_hint("/dev/ttyUSB9")
    ''
    """
    match = _ENDS_IN_A_NUMBER.fullmatch(name)
    if match is None:
        return ""
    if match["before"].startswith("/"):
        return f" (a speed is {match['before']}?baudrate={match['number']})"
    return f" (a TCP address is socket://{name})"


def _open_tcp(endpoint: Endpoint) -> Link:
    try:
        sock = socket.create_connection((endpoint.host, endpoint.port), CONNECT_TIMEOUT_S)
    except OSError as error:
        reason = error.strerror or str(error)
        raise ConnectError(f"cannot open {endpoint.url}: {reason}") from error
    return SocketLink(sock, f"tcp {endpoint.target}")


def _open_registered(endpoint: Endpoint) -> Link:
    try:
        handler = load_handler(endpoint.handler)
    except ImportError as error:
        raise ConnectError(f"{endpoint.url}: {error}") from error
    try:
        port = handler.open_url(endpoint.target)
    except (OSError, ValueError) as error:
        raise ConnectError(f"cannot open {endpoint.url}: {error}") from error
    return PortLink(port, getattr(handler, "DESCRIPTION", endpoint.url))


def open_link(endpoint: Endpoint) -> Link:
    """Open the port an endpoint names.

    >>> from rovlink.client.url import parse_url
    >>> link = open_link(parse_url("loop://"))
    >>> link.write(b"#qd!"); link.read_available(0.5)
    b'#qd!'
    >>> link.close()
    """
    if endpoint.scheme is Scheme.TCP:
        return _open_tcp(endpoint)
    if endpoint.scheme is Scheme.REGISTERED:
        return _open_registered(endpoint)
    return _open_serial(endpoint)
