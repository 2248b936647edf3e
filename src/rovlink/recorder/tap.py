"""A recording tap: a program talks to the controller through us, and both directions are
recorded (``rovlink record URL --tap socket://127.0.0.1:5761`` or ``--tap pty``).

The program connects to the tap's TCP port, or opens its pseudo-terminal, as if it were the
controller's port; the tap forwards every byte unchanged to the controller at ``URL`` and every
reply back, handing each chunk to the recorder on the way. One program at a time, as on a serial
port: a second one that connects to the TCP port meanwhile reads :data:`BUSY_MESSAGE` and is
disconnected at once, and nothing it sent reaches the controller (queued, its commands would run
after the first program left, with nobody connected). When a program whose commands may have
moved the robot (``start``, a motion command, with no ``stop`` after them) disconnects (closes
the pseudo-terminal), or the tap ends while it is connected, the tap sends ``#stop!`` to the
controller, as ``rovlink fault`` does; then the next program may connect. Without ``--tap``,
``rovlink record URL`` listens only (a sniffer on a line that another program drives, through a
Y-cable or a port mirror).
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import logging
import os
import selectors
import socket
import struct
import termios
import threading
import time
import tty
from typing import Protocol

from rovlink.busy_tcp import HUNG_UP_GRACE_S, RefusedClients, has_hung_up
from rovlink.client.errors import ConnectionLostError
from rovlink.client.links import FdLink, Link, SocketLink
from rovlink.protocol import Command, Decoder, Frame, Setting
from rovlink.recorder.reopening import ReopeningLink

__all__ = ["BUSY_MESSAGE", "STOP_FRAME", "PtyEndpoint", "TcpEndpoint", "forward", "parse_tap"]

logger = logging.getLogger(__name__)

_POLL_S = 0.1
#: How long a program's last bytes may take through a pseudo-terminal once it has closed it.
_PTY_DRAIN_S = 0.05
#: What a second program reads on the tap's TCP port (a text line, as the simulator's).
BUSY_MESSAGE = b"busy: the recording tap already has a program\r\n"
#: Sent when a program that may have set the robot moving leaves: a bare #stop! is honoured in
#: either checksum mode (P3).
STOP_FRAME = b"#stop!"
_BACKLOG = 8


class Record(Protocol):
    """Where the tap hands each chunk: ``direction`` (``out``: to the controller), the bytes,
    and whether the tap wrote them itself (its ``#stop!``)."""

    def __call__(self, direction: str, data: bytes, *, by_session: bool = False) -> None: ...


class _MayMove:
    """Whether a program's commands may have left the robot moving: a motion command or
    ``start`` since its last ``stop`` (the command table's motion flag and lock setting)."""

    def __init__(self, *, checksum: bool, algorithm: str) -> None:
        # The program's own frames set the mode its later frames are read in (P3).
        self._decoder = Decoder(checksum_enabled=checksum, algorithm=algorithm)
        self.moved = False

    def next_program(self) -> None:
        """A new program connected: nothing it moved yet. The checksum mode stays as the last
        program left it, as the controller's does (P3): reset, the next program's checksummed
        frames were read as noise, and a program that left the robot moving got no ``#stop!``."""
        self._decoder.reset()
        self.moved = False

    def feed(self, data: bytes) -> None:
        for event in self._decoder.feed(data):
            if not isinstance(event, Frame) or not isinstance(event.message, Command):
                continue  # (a frame the controller drops moves nothing)
            command = event.message
            setting = command.setting
            if setting is not None and setting[0] is Setting.LOCKED:
                self.moved = not setting[1]
            elif command.spec.motion:
                self.moved = True


class _PtyMasterLink(FdLink):
    """The master side of a pseudo-terminal, as a link."""

    description = "pseudo-terminal"

    def recv_some(self) -> bytes:
        try:
            return os.read(self._fd, 65536)
        except BlockingIOError:
            return b""
        except OSError as error:
            if error.errno == errno.EIO:  # no program has the terminal open: nothing to read
                return b""
            raise ConnectionLostError(f"pseudo-terminal: {error.strerror}") from None

    def send_some(self, data: bytes | bytearray | memoryview) -> int:
        try:
            return os.write(self._fd, data)
        except BlockingIOError:
            return 0

    def _close_port(self) -> None:
        os.close(self._fd)


class _TerminalOpeners:
    """Who has the pseudo-terminal at ``path`` open, from the kernel's notice of each open and
    each last close of it (inotify, Linux): a pseudo-terminal has no connection to end, and the
    tap's own handle keeps it from hanging up. Where inotify is missing, nothing is seen.
    """

    _IN_CLOSE_WRITE = 0x08
    _IN_CLOSE_NOWRITE = 0x10
    _IN_OPEN = 0x20
    _EVENT = struct.Struct("iIII")  # wd, mask, cookie, len (then len bytes of name)

    def __init__(self, path: str) -> None:
        #: How many times the terminal is open, but for the tap's own handle.
        self.open_count = 0
        #: Whether a program has opened it since :attr:`opened` was last cleared.
        self.opened = False
        #: Whether every program that had it open closed it, since this was last cleared (even
        #: if another has opened it since: the one that left may have left the robot moving).
        self.all_closed = False
        self._fd = -1
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            fd = libc.inotify_init1(os.O_NONBLOCK | os.O_CLOEXEC)
        except (OSError, AttributeError):  # (not Linux)
            logger.info("tap: no inotify here: a program leaving %s goes unseen", path)
            return
        mask = self._IN_OPEN | self._IN_CLOSE_WRITE | self._IN_CLOSE_NOWRITE
        if fd < 0 or libc.inotify_add_watch(fd, os.fsencode(path), mask) < 0:
            logger.info("tap: cannot watch %s: %s", path, os.strerror(ctypes.get_errno()))
            if fd >= 0:
                os.close(fd)
            return
        self._fd = fd

    @property
    def watching(self) -> bool:
        """Whether opens and closes are seen here."""
        return self._fd >= 0

    def read_notices(self) -> None:
        """Take in the notices that came since the last call."""
        if self._fd < 0:
            return
        try:
            data = os.read(self._fd, 4096)
        except BlockingIOError:
            return
        offset = 0
        while offset < len(data):
            _, mask, _, name_length = self._EVENT.unpack_from(data, offset)
            offset += self._EVENT.size + name_length
            if mask & self._IN_OPEN:
                self.open_count += 1
                self.opened = True
            elif mask & (self._IN_CLOSE_WRITE | self._IN_CLOSE_NOWRITE):
                self.open_count = max(self.open_count - 1, 0)
                self.all_closed |= self.open_count == 0

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


class PtyEndpoint:
    """A pseudo-terminal for the program: :attr:`path` is what it opens."""

    def __init__(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)  # bytes pass unchanged: no echo, no line editing, no CR/LF mapping
        os.set_blocking(master, False)
        # The tap keeps its own handle on the terminal so that a program closing it is no
        # hang-up: the next program can open it again.
        self._slave = slave
        self.path = os.ttyname(slave)
        self.link: Link = _PtyMasterLink(master)
        self._openers = _TerminalOpeners(self.path)

    def accept(self, stopping: threading.Event) -> Link | None:
        """The program's side, once a program has the terminal open (at once where opens
        are not seen); ``None`` once ``stopping`` is set."""
        openers = self._openers
        while openers.watching and not stopping.is_set():
            openers.read_notices()
            if openers.opened or openers.open_count:  # (it may have closed it already)
                openers.opened = False
                break
            stopping.wait(_POLL_S)
        return None if stopping.is_set() else self.link

    def program_left(self) -> bool:
        """Whether the program has closed the terminal since the last call (every handle on it
        but the tap's own). What the controller sent it meanwhile is dropped, so that the next
        program does not read replies to queries it never sent."""
        openers = self._openers
        openers.read_notices()
        if not openers.all_closed:
            return False
        openers.all_closed = False
        termios.tcflush(self._slave, termios.TCIFLUSH)
        return True

    def close(self) -> None:
        self._openers.close()
        self.link.close()
        os.close(self._slave)


class TcpEndpoint:
    """A TCP port for the program, one connection at a time.

    A thread of its own accepts every connection as it comes: the first waits for
    :meth:`accept`, and any other while that program is served (until :meth:`release`) reads
    :data:`BUSY_MESSAGE` and is disconnected, what it sent read and dropped. A program that
    closed and connected again at once (a script that opens the tap per task) is served: a
    connection that comes after the served program hung up waits for the tap to finish with it.
    """

    def __init__(self, host: str, port: int) -> None:
        self._server = socket.create_server((host, port), backlog=_BACKLOG)
        self._server.setblocking(False)
        host, port = self._server.getsockname()[:2]
        self.path = f"socket://{host}:{port}"
        #: Programs turned away because another was served.
        self.refused = 0
        self._selector = selectors.DefaultSelector()
        self._selector.register(self._server, selectors.EVENT_READ, None)
        self._refused = RefusedClients(self._selector, BUSY_MESSAGE)
        self._ready = threading.Condition()
        # Accepted, with its peer's address, not yet taken by accept().
        self._waiting: tuple[socket.socket, tuple[str, int]] | None = None
        self._busy = False  # a program is waiting or served
        self._served: socket.socket | None = None  # the program taken by accept()
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._listen, name="rovlink-tap-listen", daemon=True)
        self._thread.start()

    def accept(self, stopping: threading.Event) -> Link | None:
        """Wait for the next program (``None`` once ``stopping`` is set)."""
        with self._ready:
            while self._waiting is None:
                if stopping.is_set() or self._closing.is_set():
                    return None
                self._ready.wait(_POLL_S)
            (connection, peer), self._waiting = self._waiting, None
            self._served = connection
        logger.info("tap: %s:%s connected", *peer[:2])
        return SocketLink(connection, f"tcp {peer[0]}:{peer[1]}")

    @property
    def serving(self) -> bool:
        """Whether a program has connected and not yet been released (others are refused)."""
        with self._ready:
            return self._busy

    def release(self) -> None:
        """The program served has gone (and its ``#stop!`` is sent): the next may connect."""
        with self._ready:
            self._busy = False
            self._served = None
            self._ready.notify_all()

    def close(self) -> None:
        self._closing.set()
        self._thread.join()
        with self._ready:
            if self._waiting is not None:
                self._waiting[0].close()
                self._waiting = None
        self._refused.close()
        self._selector.close()
        self._server.close()

    def _listen(self) -> None:
        while not self._closing.is_set():
            for key, _ in self._selector.select(_POLL_S):
                if key.fileobj is self._server:
                    self._on_connection()
                else:
                    assert isinstance(key.fileobj, socket.socket)
                    self._refused.on_readable(key.fileobj)
            self._refused.expire(time.monotonic())

    def _on_connection(self) -> None:
        try:
            connection, peer = self._server.accept()
        except (BlockingIOError, InterruptedError):
            return
        except OSError as error:
            logger.debug("tap server: %s", error)
            return
        with self._ready:
            if self._busy and self._served is not None and has_hung_up(self._served):
                self._ready.wait_for(lambda: not self._busy, HUNG_UP_GRACE_S)
            if not self._busy:
                self._busy = True
                connection.setblocking(True)
                # (The peer as accept() gave it: getpeername() fails once the program has reset
                # the connection, and the tap stayed busy for good.)
                self._waiting = (connection, peer)
                self._ready.notify()
                return
        logger.info("tap: refused %s:%s: busy", *peer[:2])
        self.refused += 1
        self._refused.refuse(connection)


def parse_tap(text: str) -> PtyEndpoint | TcpEndpoint:
    """The tap's endpoint from ``--tap``: ``pty`` or ``socket://HOST:PORT``.

    ValueError says what is wrong.
    """
    if text == "pty":
        return PtyEndpoint()
    if not text.startswith("socket://"):
        raise ValueError(f"--tap {text!r}: use pty or socket://HOST:PORT")
    host, _, port = text[len("socket://") :].rpartition(":")
    if not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"--tap {text!r}: the port must be a number from 0 to 65535")
    return TcpEndpoint(host or "127.0.0.1", int(port))


def forward(
    endpoint: PtyEndpoint | TcpEndpoint,
    controller: ReopeningLink,
    record: Record,
    stopping: threading.Event,
    *,
    checksum: bool = False,
    algorithm: str = "crc8",
) -> None:
    """Forward bytes both ways until ``stopping`` is set or the controller's link is lost for
    good, calling ``record(direction, data)`` for each chunk before passing it on. ``checksum``
    and ``algorithm``: the mode the link starts in, to read the program's frames.

    While the controller's link is down (being reopened) the program stays connected: what it
    sends is dropped and it gets no replies. When the link comes back, a ``#stop!`` goes first
    if the program's commands may have left the robot moving (as when a program leaves): the
    tap never lets a robot resume what it was doing before the gap unseen by its program."""
    program: list[Link | None] = [None]
    motion = _MayMove(checksum=checksum, algorithm=algorithm)
    # A #stop! that could not go (a program left during the gap), or that went on a reopened
    # link that no frame has come back on yet (it may have died at once: a port that took the
    # connection as its process died): sent on the return.
    stop_owed = [False]

    def stop_robot() -> None:
        # (A link found lost takes nothing: a TCP peer that closed may take bytes until its
        # reset comes back, and a #stop! recorded as sent there would be a lie.)
        if not controller.write(STOP_FRAME):
            stop_owed[0] = True
            logger.warning("tap: could not send #stop!: the controller's link is lost")
            return
        record("out", STOP_FRAME, by_session=True)
        logger.info("tap: #stop! sent (the program may have left the robot moving)")

    def stop_on_return(link: Link) -> None:
        if motion.moved or stop_owed[0]:
            link.write(STOP_FRAME)
            record("out", STOP_FRAME, by_session=True)
            motion.moved = False
            stop_owed[0] = True  # (until the controller is heard on this link)
            logger.info("tap: #stop! sent first on the reopened link")

    controller.on_return = stop_on_return

    def pass_on(data: bytes) -> None:
        # (Recorded as it goes, with the link's lock held: after a #stop! the return wrote
        # first, and never for a link that is down.)
        if controller.write(data, before=lambda: record("out", data)):
            motion.feed(data)
        else:
            logger.debug("tap: dropped %d bytes of the program's: the link is down", len(data))

    def to_controller() -> None:
        while not stopping.is_set():
            side = program[0] = endpoint.accept(stopping)
            if side is None:
                return
            motion.next_program()
            try:
                while not stopping.is_set():
                    data = side.read_available(_POLL_S)
                    if data:
                        pass_on(data)
                    elif isinstance(endpoint, PtyEndpoint) and endpoint.program_left():
                        # Its last bytes may still be on their way through the terminal.
                        while data := side.read_available(_PTY_DRAIN_S):
                            pass_on(data)
                        logger.info("tap: the program closed %s", endpoint.path)
                        break
            except ConnectionLostError:
                logger.info("tap: the program disconnected")
            finally:
                program[0] = None
                if motion.moved:  # a robot left moving by a program that is gone is stopped
                    stop_robot()
                if isinstance(endpoint, TcpEndpoint):
                    side.close()
                    endpoint.release()

    thread = threading.Thread(target=to_controller, name="rovlink-tap", daemon=True)
    thread.start()
    try:
        while not stopping.is_set():
            data = controller.read_available(_POLL_S)
            if data:
                if b"!" in data:  # a frame: the controller is there (a busy one says text)
                    stop_owed[0] = False
                record("in", data)
                side = program[0]
                if side is not None:
                    with contextlib.suppress(ConnectionLostError):
                        side.write(data)
    finally:
        stopping.set()
        thread.join()
