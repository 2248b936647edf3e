"""A page too slow to take its messages (a slow network, a throttled browser): it skips old
readings and heartbeats, never a control change, a log entry or an error; a page so far behind
that only those wait for it is closed, and a pilot's thrust goes to zero first."""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import json
import socket
from collections.abc import AsyncIterator, MutableMapping
from typing import Any

import pytest
import uvicorn
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

from rovlink.station.access import Access
from rovlink.station.app import build_app
from rovlink.station.hub import OUTBOX_SIZE, Peer
from tests.station.test_hub import Hub, drain, keys, station_on_sim, thrust, until


@pytest.fixture
async def hub() -> AsyncIterator[Hub]:
    async with station_on_sim() as made:
        yield made


async def readings(hub: Hub, count: int) -> None:
    """``count`` polls' readings, a tenth of a second apart on the station's clock."""
    reading = await hub.station.tracked.sensors()
    for _ in range(count):
        hub.clock.now_s += 0.1
        hub.station._reading(reading)


async def test_a_page_far_behind_gets_every_control_log_and_error_and_the_newest_reading(hub):
    slow = hub.station.join("slow")  # a page that takes none of its messages meanwhile
    pilot = await hub.pilot()
    await readings(hub, OUTBOX_SIZE)  # its outbox is full of readings
    await hub.send(slow, {"type": "command", "name": "start"})  # refused: not the pilot
    await hub.send(pilot, {"type": "release_control"})
    leaking = dataclasses.replace(await hub.station.tracked.sensors(), leak_detected=True)
    hub.station._reading(leaking)
    await readings(hub, OUTBOX_SIZE)
    newest_t = round(hub.station.now_s(), 3)

    got = drain(slow)
    kinds = [message["type"] for message in got]
    assert kinds[0] == "hello"
    errors = [m["message"] for m in got if m["type"] == "error"]
    assert len(errors) == 1
    assert "only the pilot may" in errors[0]
    control = [m for m in got if m["type"] == "control"][-1]
    assert control["pilot_id"] is None
    assert "released control" in control["text"]
    alarms = [m["text"] for m in got if m["type"] == "log" and m["level"] == "alarm"]
    assert any("LEAK" in text for text in alarms)
    assert got[-1]["type"] == "telemetry"
    assert got[-1]["t"] == newest_t
    assert len(got) == OUTBOX_SIZE  # what was dropped made room for the rest
    assert slow.dropped_messages == 2 * OUTBOX_SIZE + 1 - kinds.count("telemetry")  # readings
    # The oldest readings went: those kept are the newest, in order.
    times = [m["t"] for m in got if m["type"] == "telemetry"]
    assert times == sorted(times)
    assert times[0] > OUTBOX_SIZE * 0.1


def test_the_oldest_superseded_message_goes_first_and_a_newer_state_is_kept():
    peer = Peer("p1", "browser 1")
    peer.put({"type": "recording", "active": True})
    for t in range(OUTBOX_SIZE - 1):
        peer.put({"type": "heartbeat", "t": t})
    peer.put({"type": "heartbeat", "t": 999})  # the oldest heartbeat goes, not the recording
    peer.put({"type": "recording", "active": False})  # the older recording state goes
    got = drain(peer)
    assert got[0] == {"type": "heartbeat", "t": 1}
    assert got[-2:] == [{"type": "heartbeat", "t": 999}, {"type": "recording", "active": False}]
    assert {"type": "recording", "active": True} not in got
    assert peer.dropped_messages == 2


def test_the_newest_reading_is_not_dropped_for_a_log_entry_nor_a_log_entry_for_it():
    peer = Peer("p1", "browser 1")
    peer.put({"type": "telemetry", "t": 0.0})
    for number in range(OUTBOX_SIZE - 1):
        peer.put({"type": "log", "text": f"entry {number}"})
    peer.put({"type": "log", "text": "one more"})  # nothing superseded to drop: overflow
    assert peer.outbox.overflowed
    assert peer.outbox.empty()  # what waited is let go with the page, not kept
    assert peer.dropped_messages == OUTBOX_SIZE + 1
    peer.put({"type": "telemetry", "t": 0.1})
    assert peer.outbox.empty()
    assert peer.dropped_messages == OUTBOX_SIZE + 2


async def test_a_pilot_whose_outbox_overflows_leaves_with_its_thrust_zeroed(hub):
    pilot = await hub.pilot()
    watcher = hub.station.join("watcher")
    await hub.send(pilot, {"type": "command", "name": "start"})
    await hub.send(pilot, keys(False))
    await hub.send(pilot, keys(True, power_percent=50))
    assert thrust(hub.sent)[-1] == "#th.90.50!"
    for number in range(OUTBOX_SIZE):
        drain(watcher)
        hub.station.log("info", f"entry {number}")
    assert pilot.outbox.overflowed
    assert not watcher.outbox.overflowed
    await hub.station.leave(pilot)  # what the WebSocket endpoint does at once (see below)
    assert thrust(hub.sent)[-1] == "#th.90.0!"
    assert hub.station.pilot is None
    assert f"{pilot.label} fell too far behind" in hub.warnings()[-1]
    control = [m for m in drain(watcher) if m["type"] == "control"][-1]
    assert control["pilot_id"] is None
    assert "fell too far behind" in control["text"]


class StalledPage:
    """A page on the station's ASGI app that sends what it is given and stops reading once
    it has its ``hello``: each write to it waits, as on a socket whose buffers are full."""

    def __init__(self) -> None:
        self.incoming: asyncio.Queue[dict[str, Any]] = asyncio.Queue()
        self.received: list[dict[str, Any]] = []
        self.closed: dict[str, Any] | None = None
        self.reading = asyncio.Event()  # never set: the page does not read

    def say(self, message: dict[str, Any]) -> None:
        self.incoming.put_nowait({"type": "websocket.receive", "text": json.dumps(message)})

    async def receive(self) -> dict[str, Any]:
        return await self.incoming.get()

    async def send(self, message: MutableMapping[str, Any]) -> None:
        if message["type"] == "websocket.close":
            self.closed = dict(message)
            self.incoming.put_nowait({"type": "websocket.disconnect", "code": message["code"]})
        elif message["type"] == "websocket.send":
            if self.received:
                await self.reading.wait()
            self.received.append(json.loads(message["text"]))


async def test_the_endpoint_closes_a_page_too_far_behind_and_cuts_its_thrust_first(hub):
    app = build_app(hub.station, Access(bind_host="127.0.0.1", port=8600))
    page = StalledPage()
    page.incoming.put_nowait({"type": "websocket.connect"})
    host = [(b"host", b"127.0.0.1:8600"), (b"origin", b"http://127.0.0.1:8600")]
    scope = {
        "type": "websocket",
        "path": "/ws",
        "raw_path": b"/ws",
        "root_path": "",
        "scheme": "ws",
        "query_string": b"",
        "headers": host,
        "client": ("127.0.0.1", 50000),
        "server": ("127.0.0.1", 8600),
        "subprotocols": [],
        "asgi": {"version": "3.0"},
    }
    serving = asyncio.ensure_future(app(scope, page.receive, page.send))
    try:
        await until(lambda: len(page.received) == 1)
        assert page.received[0]["type"] == "hello"
        for message in (
            {"type": "take_control"},
            {"type": "command", "name": "start"},
            keys(False),
            keys(True, power_percent=50),
        ):
            page.say(message)
        await until(lambda: thrust(hub.sent)[-1:] == ["#th.90.50!"])
        for number in range(OUTBOX_SIZE + 1):  # log entries: none may be dropped
            hub.station.log("info", f"entry {number}")
        await until(lambda: hub.station.pilot is None)
        assert thrust(hub.sent)[-1] == "#th.90.0!"
        await until(lambda: page.closed is not None)
        assert page.closed is not None
        assert page.closed["code"] == 1013
        await asyncio.wait_for(serving, 5.0)
    finally:
        serving.cancel()
    assert "fell too far behind" in hub.warnings()[-1]


@pytest.mark.integration
async def test_a_pilot_on_a_real_socket_that_stops_reading_is_closed_and_its_thrust_zeroed(
    hub, monkeypatch: pytest.MonkeyPatch
):
    # uvicorn in this process, with buffers small enough on both sides of the TCP connection
    # (and a small outbox) for a page that stops reading to fill them in a moment.
    monkeypatch.setattr("rovlink.station.hub.OUTBOX_SIZE", 16)
    listener = socket.socket()
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)  # the accepted socket's
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    port = listener.getsockname()[1]
    app = build_app(hub.station, Access(bind_host="127.0.0.1", port=port))
    config = uvicorn.Config(app, log_level="warning", lifespan="off", ws="websockets-sansio")
    server = uvicorn.Server(config)
    serving = asyncio.ensure_future(server.serve(sockets=[listener]))
    stuck = socket.socket()
    try:
        await until(lambda: server.started)
        stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connecting
        stuck.connect(("127.0.0.1", port))
        url = f"ws://127.0.0.1:{port}/ws"
        # max_queue=1: once it holds the hello, the client reads nothing more from its socket.
        page = await connect(url, sock=stuck, max_queue=1, ping_interval=None)
        for message in (
            {"type": "take_control"},
            {"type": "command", "name": "start"},
            keys(False),
            keys(True, power_percent=50),
        ):
            await page.send(json.dumps(message))
        await until(lambda: thrust(hub.sent)[-1:] == ["#th.90.50!"])
        padding = "." * 2000  # long entries: the buffers fill sooner
        for number in range(20_000):  # log entries: a page may not miss one
            if hub.station.pilot is None:
                break
            hub.station.log("info", f"entry {number} {padding}")
            await asyncio.sleep(0)  # the page's writer fills the socket until it waits
        assert hub.station.pilot is None
        assert thrust(hub.sent)[-1] == "#th.90.0!"
        assert "fell too far behind" in hub.warnings()[-1]
        received = []
        with contextlib.suppress(ConnectionClosed):  # it reads again, to the close
            while True:
                received.append(json.loads(await page.recv()))
        assert page.close_code == 1013
        logged = [m["text"].split() for m in received if m["type"] == "log"]
        entries = [int(words[1]) for words in logged if words[0] == "entry"]
        assert entries == list(range(len(entries)))  # none missing up to where it was closed
        assert number > 16  # it was closed with its buffers full, not for one entry too many
        assert len(entries) > 16  # what the buffers held reached it, then the close
    finally:
        stuck.close()  # a page still stuck (on a failure) must not hold the server's shutdown
        server.should_exit = True
        await asyncio.wait_for(serving, 5.0)
