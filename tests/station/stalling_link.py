"""A TCP proxy between a browser and the station whose open connections can be stalled one way:
what the browser sends on them stops getting through, as after a Wi-Fi roam or on a network
slower than the pilot's input, while a connection opened afterwards carries everything."""

from __future__ import annotations

import contextlib
import selectors
import socket
import threading
from collections.abc import Iterator

_CHUNK = 65536


class StallingLink:
    """Listens on ``127.0.0.1:port`` and forwards every connection to ``target_port``.

    :meth:`stall_open_connections` stops forwarding what the browser sends on the connections
    open now (it waits, unread); what the station sends still flows, and so does every
    connection opened later.
    """

    def __init__(self, target_port: int) -> None:
        self._target_port = target_port
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.port: int = self._listener.getsockname()[1]
        self._lock = threading.Lock()
        self._pairs: list[tuple[socket.socket, socket.socket]] = []
        self._stalled: set[socket.socket] = set()
        self._closing = False
        self._selector = selectors.DefaultSelector()
        self._selector.register(self._listener, selectors.EVENT_READ)
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/"

    def stall_open_connections(self) -> None:
        with self._lock:
            for browser_side, _ in self._pairs:
                self._stalled.add(browser_side)
                with contextlib.suppress(KeyError, ValueError):
                    self._selector.unregister(browser_side)

    def close(self) -> None:
        self._closing = True
        self._thread.join(timeout=5)
        with self._lock:
            for browser_side, station_side in self._pairs:
                browser_side.close()
                station_side.close()
        self._listener.close()
        self._selector.close()

    def _run(self) -> None:
        while not self._closing:
            for key, _ in self._selector.select(timeout=0.05):
                if key.fileobj is self._listener:
                    self._accept()
                else:
                    self._forward(key.fileobj, key.data)  # type: ignore[arg-type]

    def _accept(self) -> None:
        browser_side, _ = self._listener.accept()
        station_side = socket.create_connection(("127.0.0.1", self._target_port))
        with self._lock:
            self._pairs.append((browser_side, station_side))
            self._selector.register(browser_side, selectors.EVENT_READ, station_side)
            self._selector.register(station_side, selectors.EVENT_READ, browser_side)

    def _forward(self, source: socket.socket, destination: socket.socket) -> None:
        try:
            data = source.recv(_CHUNK)
        except OSError:
            data = b""
        if data:
            with contextlib.suppress(OSError):
                destination.sendall(data)
            return
        with self._lock, contextlib.suppress(KeyError, ValueError):
            self._selector.unregister(source)
        with contextlib.suppress(OSError):
            destination.shutdown(socket.SHUT_WR)


@contextlib.contextmanager
def stalling_link(target_port: int) -> Iterator[StallingLink]:
    link = StallingLink(target_port)
    try:
        yield link
    finally:
        link.close()
