"""A controller that never answers: a TCP listener that accepts one connection and only reads."""

from __future__ import annotations

import socket
import threading
from collections.abc import Callable

#: How long a test waits for a frame to arrive.
WAIT_S = 15.0


class SilentController:
    """Accepts one connection and records what it reads; never answers."""

    def __init__(self) -> None:
        self._server = socket.create_server(("127.0.0.1", 0))
        self.port = self._server.getsockname()[1]
        self.received = b""
        self._changed = threading.Condition()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        return f"socket://127.0.0.1:{self.port}"

    def _serve(self) -> None:
        connection, _ = self._server.accept()
        with connection:
            while data := connection.recv(4096):
                with self._changed:
                    self.received += data
                    self._changed.notify_all()

    def wait_for(self, frame: bytes, timeout_s: float = WAIT_S) -> bool:
        """Whether ``frame`` arrived within ``timeout_s``."""
        return self.wait_until(lambda received: frame in received, timeout_s)

    def wait_until(self, holds: Callable[[bytes], bool], timeout_s: float = WAIT_S) -> bool:
        """Whether what arrived made ``holds`` true within ``timeout_s``."""
        with self._changed:
            return self._changed.wait_for(lambda: holds(self.received), timeout_s)

    def wait_closed(self, timeout_s: float = WAIT_S) -> bool:
        """Whether the connection was closed (and all it carried read) within ``timeout_s``."""
        self._thread.join(timeout_s)
        return not self._thread.is_alive()

    def close(self) -> None:
        self._server.close()
