"""A recording tap: a program talks to the controller through us, and both directions are
recorded (``rovlink record URL --tap socket://127.0.0.1:5761`` or ``--tap pty``).

The program connects to the tap's TCP port, or opens its pseudo-terminal, as if it were the
controller's port; the tap forwards every byte unchanged to the controller at ``URL`` and every
reply back, handing each chunk to the recorder on the way. One program at a time: when it
disconnects, the next may connect. Without ``--tap``, ``rovlink record URL`` listens only
(a sniffer on a line that another program drives, through a Y-cable or a port mirror).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import socket
import threading
import tty
from collections.abc import Callable

from rovlink.client.errors import ConnectionLostError
from rovlink.client.links import FdLink, Link, SocketLink

__all__ = ["PtyEndpoint", "TcpEndpoint", "forward", "parse_tap"]

logger = logging.getLogger(__name__)

_POLL_S = 0.1
Record = Callable[[str, bytes], None]


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

    def accept(self, stopping: threading.Event) -> Link | None:
        """The program's side (always there for a terminal)."""
        return None if stopping.is_set() else self.link

    def close(self) -> None:
        self.link.close()
        os.close(self._slave)


class TcpEndpoint:
    """A TCP port for the program, one connection at a time."""

    def __init__(self, host: str, port: int) -> None:
        self._server = socket.create_server((host, port))
        self._server.settimeout(_POLL_S)
        host, port = self._server.getsockname()[:2]
        self.path = f"socket://{host}:{port}"

    def accept(self, stopping: threading.Event) -> Link | None:
        """Wait for the next program (``None`` once ``stopping`` is set)."""
        while not stopping.is_set():
            try:
                connection, peer = self._server.accept()
            except TimeoutError:
                continue
            except OSError as error:  # closed under us
                logger.debug("tap server: %s", error)
                return None
            logger.info("tap: %s:%s connected", *peer[:2])
            return SocketLink(connection, f"tcp {peer[0]}:{peer[1]}")
        return None

    def close(self) -> None:
        self._server.close()


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
    controller: Link,
    record: Record,
    stopping: threading.Event,
) -> None:
    """Forward bytes both ways until ``stopping`` is set or the controller's link is lost,
    calling ``record(direction, data)`` for each chunk before passing it on."""
    program: list[Link | None] = [None]

    def to_controller() -> None:
        while not stopping.is_set():
            side = program[0] = endpoint.accept(stopping)
            if side is None:
                return
            try:
                while not stopping.is_set():
                    data = side.read_available(_POLL_S)
                    if data:
                        record("out", data)
                        controller.write(data)
            except ConnectionLostError:
                logger.info("tap: the program disconnected")
            finally:
                program[0] = None
                if isinstance(endpoint, TcpEndpoint):
                    side.close()

    thread = threading.Thread(target=to_controller, name="rovlink-tap", daemon=True)
    thread.start()
    try:
        while not stopping.is_set():
            data = controller.read_available(_POLL_S)
            if data:
                record("in", data)
                side = program[0]
                if side is not None:
                    with contextlib.suppress(ConnectionLostError):
                        side.write(data)
    finally:
        stopping.set()
        thread.join()
