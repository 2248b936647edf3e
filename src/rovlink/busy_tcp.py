"""TCP clients turned away because a line already has its one client (P22's rule on TCP).

The simulated controller and the fault proxy serve one client at a time, as a serial port does.
A second client reads a message saying so and is disconnected; nothing it sends is acted on.
Standard library only: the controller's servers use it.
"""

from __future__ import annotations

import selectors
import socket
import time

__all__ = ["HUNG_UP_GRACE_S", "RefusedClients", "has_hung_up"]

#: How long a client that connects just after the served one hung up waits for the server to
#: finish with that one (its last bytes passed on, its ``#stop!`` sent) rather than be refused,
#: s: a program that closed and connected again at once is no second client.
HUNG_UP_GRACE_S = 1.0


def has_hung_up(connection: socket.socket) -> bool:
    """Whether the client on ``connection`` has closed its end, though its server may not have
    read that end yet (or the connection is closed here already)."""
    try:
        return connection.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
    except BlockingIOError:
        return False  # connected, nothing sent
    except OSError:
        return True  # reset, or closed by its server


class RefusedClients:
    """The refused clients of one server, watched by its ``selector`` until they close.

    A refused client reads ``busy_message``; its sending side is then ended, and what it sends
    is read and dropped until it closes its end, or for at most :attr:`LINGER_S`. Closing at
    once, with its input unread, would reset the connection, and the reset can discard the
    message before the client reads it.

    Example::

        refused = RefusedClients(selector, b"busy\\r\\n", data=on_refused_readable)
        refused.refuse(connection)            # on a second accept()
        refused.on_readable(key.fileobj)      # when the selector says it is readable
        refused.expire(time.monotonic())      # after each select()
    """

    #: How long a refused client may take to close its end before it is cut off.
    LINGER_S = 2.0
    #: Refused clients kept so at once; more are cut off at once (a flood of connections must
    #: not run the server out of descriptors, which would stop the client it serves).
    MAX_KEPT = 8

    def __init__(
        self, selector: selectors.BaseSelector, busy_message: bytes, *, data: object = None
    ) -> None:
        """``data`` is what the refused sockets are registered with in ``selector``."""
        self._selector = selector
        self._busy_message = busy_message
        self._data = data
        self._deadlines_s: dict[socket.socket, float] = {}

    def __len__(self) -> int:
        return len(self._deadlines_s)

    def refuse(self, connection: socket.socket) -> None:
        """Say busy and watch ``connection`` until it closes."""
        try:
            connection.setblocking(False)
            connection.send(self._busy_message)
            connection.shutdown(socket.SHUT_WR)
        except OSError:
            connection.close()
            return
        if len(self._deadlines_s) >= self.MAX_KEPT:
            connection.close()
            return
        self._deadlines_s[connection] = time.monotonic() + self.LINGER_S
        self._selector.register(connection, selectors.EVENT_READ, self._data)

    def on_readable(self, connection: socket.socket) -> None:
        """Read and drop what a refused client sent; forget it once it has closed."""
        try:
            if connection.recv(4096):
                return  # (its commands: read and dropped, never acted on)
        except BlockingIOError:
            return
        except OSError:
            pass
        self._drop(connection)

    def expire(self, now_s: float) -> None:
        """Cut off the refused clients that have not closed by their deadline."""
        for connection, deadline_s in list(self._deadlines_s.items()):
            if now_s >= deadline_s:
                self._drop(connection)

    def close(self) -> None:
        """Cut off every refused client."""
        for connection in list(self._deadlines_s):
            self._drop(connection)

    def _drop(self, connection: socket.socket) -> None:
        del self._deadlines_s[connection]
        self._selector.unregister(connection)
        connection.close()
