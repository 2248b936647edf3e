"""The simulated controller served in a thread of the test, on a real PTY and TCP socket."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator

import pytest

from rovlink.sim import SimConfig
from rovlink.sim.server import SimServer

StartServer = Callable[..., SimServer]


@pytest.fixture
def start_server() -> Iterator[StartServer]:
    """Start a server (seed 1) on a PTY and/or loopback TCP; every one is stopped at the end."""
    running: list[tuple[SimServer, threading.Event, threading.Thread]] = []

    def start(
        config: SimConfig | None = None, *, pty: bool = True, tcp: bool = True, **options: object
    ) -> SimServer:
        server = SimServer(config, seed=1, **options)  # type: ignore[arg-type]
        if pty:
            server.open_pty()
        if tcp:
            server.listen_tcp("127.0.0.1", 0)
        stop = threading.Event()
        thread = threading.Thread(target=server.serve, args=(stop.is_set,), daemon=True)
        thread.start()
        running.append((server, stop, thread))
        return server

    yield start
    for server, stop, thread in running:
        stop.set()
        thread.join(timeout=5)
        assert not thread.is_alive()
        server.close()
