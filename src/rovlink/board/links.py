"""The board's serial lines: a UART (or USB serial adapter), a pseudo-terminal, TCP clients.

Each link is a non-blocking file descriptor the board loop watches with :mod:`selectors`.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import socket
import termios
import tty
from typing import Any

__all__ = ["Link", "PtyLink", "SerialLink", "TcpLink", "is_loopback"]

_READ_BYTES = 4096


def is_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback address (only this computer can connect).

    >>> is_loopback("127.0.0.1"), is_loopback("::1"), is_loopback("0.0.0.0")
    (True, True, False)
    """
    import ipaddress  # noqa: PLC0415

    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class Link:
    """One end of a serial line: a file descriptor, and bytes the kernel has not taken yet."""

    def __init__(self, name: str, fd: int) -> None:
        self.name = name
        self.fd = fd
        self.unsent = bytearray()

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


class SerialLink(Link):
    """A serial device (the Pi's UART, a USB adapter), opened exclusively (P22) at ``baud``."""

    def __init__(self, path: str, baud: int) -> None:
        import serial  # noqa: PLC0415 - pyserial, loaded when a serial device is used

        self._serial: Any = serial.Serial(
            path, baud, timeout=0, write_timeout=0, exclusive=True, rtscts=False, dsrdtr=False
        )
        fd = self._serial.fileno()
        os.set_blocking(fd, False)
        # pyserial's lock keeps out programs that lock too; TIOCEXCL keeps out every other
        # opener but root (a forgotten terminal program), until the port is closed.
        with contextlib.suppress(OSError):
            fcntl.ioctl(fd, termios.TIOCEXCL)
        super().__init__(f"serial {path}", fd)

    def read(self) -> bytes | None:
        """Bytes from the line; a serial line never "goes away", so never b""."""
        try:
            return os.read(self.fd, _READ_BYTES) or None
        except BlockingIOError:
            return None
        except OSError as error:
            if error.errno == errno.EIO:  # a pseudo-terminal whose other side is closed
                return None
            raise

    def close(self) -> None:
        """Close the port (and release its lock)."""
        self._serial.close()


class PtyLink(Link):
    """A pseudo-terminal for a host program on the same computer."""

    def __init__(self) -> None:
        master_fd, slave_fd = os.openpty()
        tty.setraw(slave_fd)  # the terminal side sees exactly the controller's bytes
        os.set_blocking(master_fd, False)
        super().__init__("pty", master_fd)
        self._slave_fd = slave_fd  # kept open so the PTY outlives the programs that open it
        self.path = os.ttyname(slave_fd)

    def read(self) -> bytes | None:
        """Bytes from the terminal side; never b"" (programs come and go)."""
        try:
            return os.read(self.fd, _READ_BYTES) or None
        except BlockingIOError:
            return None
        except OSError as error:
            if error.errno == errno.EIO:  # no terminal side open: nothing to read
                return None
            raise

    def close(self) -> None:
        """Close both sides."""
        os.close(self.fd)
        os.close(self._slave_fd)


class TcpLink(Link):
    """One TCP client."""

    def __init__(self, connection: socket.socket) -> None:
        connection.setblocking(False)
        connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        peer = connection.getpeername()
        super().__init__(f"tcp client {peer[0]}:{peer[1]}", connection.fileno())
        self.connection = connection

    def read(self) -> bytes | None:
        """Bytes from the client; b"" when it has gone."""
        try:
            return self.connection.recv(_READ_BYTES)
        except BlockingIOError:
            return None
        except OSError:
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
