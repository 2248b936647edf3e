"""The station shutting down (Ctrl-C, SIGTERM, a closed terminal) with a page whose socket is
stuck behind full buffers: ``#stop!`` goes first, not after the pages' connections are closed.

``serve`` runs in this process, on the simulator, with the station's sockets given buffers small
enough for a page that stops reading to fill them in a moment."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import signal
import socket
from collections.abc import AsyncIterator
from typing import Any

import pytest
from websockets.asyncio.client import ClientConnection, connect

import rovlink.aio
from rovlink.client.events import BytesSent, ClientEvent
from rovlink.station import serve as serve_module
from rovlink.station.hub import Station
from rovlink.station.serve import ServeOptions, serve
from tests.station.test_hub import keys, until

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGTERM"), reason="POSIX signals")

#: How soon after the signal the station's ``#stop!`` must reach the robot's link.
STOP_WITHIN_S = 0.3


class Served:
    """``serve`` on ``sim://`` in this process: its URL, its station, what it wrote and when."""

    def __init__(self) -> None:
        self.url: asyncio.Future[str] = asyncio.get_running_loop().create_future()
        self.station: Station | None = None
        self.sent: list[tuple[float, str]] = []  # (loop time, frame), polls left out

    async def connect(self) -> rovlink.aio.AsyncClient:
        client = await rovlink.aio.connect("sim://")
        client.subscribe(self.on_event)
        return client

    def on_event(self, event: ClientEvent) -> None:
        if isinstance(event, BytesSent) and not event.data.startswith(b"#q"):
            self.sent.append((asyncio.get_running_loop().time(), event.data.decode()))

    def ready(self, urls: list[str]) -> None:
        self.url.set_result(urls[0])

    def first(self, frame: str, after_s: float) -> float | None:
        """When ``frame`` was first written after ``after_s`` (``None``: not yet)."""
        return next((at for at, text in self.sent if text == frame and at >= after_s), None)


@contextlib.asynccontextmanager
async def served_with_small_buffers(monkeypatch: pytest.MonkeyPatch) -> AsyncIterator[Served]:
    served = Served()
    stations: list[Station] = []

    def small_bind(host: str, port: int) -> socket.socket:
        listener = socket.socket()
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)  # the accepted sockets'
        listener.bind((host, port))
        listener.listen()
        listener.setblocking(False)
        return listener

    def station(*arguments: Any, **options: Any) -> Station:
        made = Station(*arguments, **options)
        stations.append(made)
        return made

    monkeypatch.setattr(serve_module, "bind", small_bind)
    monkeypatch.setattr(serve_module, "Station", station)
    monkeypatch.setattr("rovlink.station.hub.OUTBOX_SIZE", 16)
    options = ServeOptions(host="127.0.0.1", port=0, token=None, rate_hz=10, algorithm="crc8")
    serving = asyncio.ensure_future(
        serve(served.connect, options, description="sim://", ready=served.ready)
    )
    try:
        await asyncio.wait_for(asyncio.shield(served.url), 10.0)
        served.station = stations[0]
        yield served
    finally:
        if not serving.done():
            os.kill(os.getpid(), signal.SIGTERM)
        await asyncio.wait_for(serving, 10.0)


async def stuck_page(url: str) -> tuple[ClientConnection, socket.socket]:
    """A page that reads nothing after its ``hello``, on a socket with a small receive buffer."""
    host, port = url.split("//")[1].rstrip("/").split(":")
    stuck = socket.socket()
    stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connecting
    stuck.connect((host, int(port)))
    page = await connect(
        f"ws://{host}:{port}/ws", sock=stuck, max_queue=1, ping_interval=None, compression=None
    )
    return page, stuck


@pytest.mark.integration
@pytest.mark.realtime
async def test_a_shutdown_sends_stop_first_though_a_page_is_stuck_behind_full_buffers(
    monkeypatch: pytest.MonkeyPatch,
):
    async with served_with_small_buffers(monkeypatch) as served:
        url = await served.url
        station = served.station
        assert station is not None
        pilot = await connect(url.replace("http", "ws") + "ws", ping_interval=None)
        for message in (
            {"type": "take_control"},
            {"type": "command", "name": "start"},
            keys(False),
            keys(True, power_percent=50),
        ):
            await pilot.send(json.dumps(message))
        await until(lambda: served.first("#th.90.50!", 0.0) is not None)
        watcher, stuck = await stuck_page(url)
        try:
            peer = next(p for p in station.peers.values() if p is not station.pilot)
            padding = "." * 1000
            for number in range(2000):  # log entries (never dropped) until its writes wait
                if len(peer.outbox) >= 8:
                    break
                station.log("info", f"entry {number} {padding}")
                await asyncio.sleep(0)
            assert len(peer.outbox) >= 8  # its socket's buffers are full
            await pilot.send(json.dumps(keys(True, power_percent=50)))  # still flying
            signalled_s = asyncio.get_running_loop().time()
            os.kill(os.getpid(), signal.SIGTERM)
            await until(lambda: served.first("#stop!", signalled_s) is not None, 5.0)
            stop_s = served.first("#stop!", signalled_s)
            assert stop_s is not None
            # Before, the #stop! waited for the stuck page's connection to close: the whole of
            # uvicorn's graceful shutdown (1 s).
            assert stop_s - signalled_s < STOP_WITHIN_S
            # It is the last frame: the pilot's page closing after it sends nothing more.
            await until(lambda: station.pilot is None)
            assert served.sent[-1][1] == "#stop!"
        finally:
            watcher.transport.abort()
            stuck.close()
            pilot.transport.abort()
