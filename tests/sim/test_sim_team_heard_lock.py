"""A pilot's tool hears the lock another line changes: with debug output on, the simulated
controller announces every lock change to its PTY and its TCP client, and the web station and
the monitor (on TCP) show what a bystander (on the PTY) did, without sending anything for it."""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any

import pytest

import rovlink.aio
from rovlink.aio import AsyncClient
from rovlink.client.events import BytesSent, ClientEvent
from rovlink.client.options import StrayCallback
from rovlink.console.engine import status_lines
from rovlink.monitor.app import MonitorApp
from rovlink.piloting import LockState, TrackedClient
from rovlink.piloting.hearing import hear_other_lines
from rovlink.sim.server import SimServer
from rovlink.station.hub import Peer, Station
from tests.monitor.screen import shown
from tests.sim.conftest import StartServer

pytestmark = pytest.mark.integration

CONDITION_TIMEOUT_S = 3.0


async def _until(condition: Callable[[], bool], what: str) -> None:
    deadline_s = asyncio.get_running_loop().time() + CONDITION_TIMEOUT_S
    while not condition():
        if asyncio.get_running_loop().time() > deadline_s:
            pytest.fail(f"timed out waiting until {what}")
        await asyncio.sleep(0.005)


def _tcp_url(server: SimServer) -> str:
    assert server.tcp_address is not None
    host, port = server.tcp_address
    return f"socket://{host}:{port}"


@asynccontextmanager
async def _bystander(server: SimServer) -> AsyncIterator[AsyncClient]:
    """A tool on the PTY, which turns the controller's debug output on (any line may)."""
    assert server.pty_path is not None
    async with rovlink.aio.connect(server.pty_path, timeout=1.0, keepalive=None) as bystander:
        await bystander.set_debug(True)
        yield bystander


def _locked(server: SimServer) -> bool:
    return server.robot.controller.locked


async def test_a_tracked_client_takes_a_bystanders_stop_and_shows_its_unlock(
    start_server: StartServer,
) -> None:
    server = start_server()
    heard: list[str] = []
    async with (
        rovlink.aio.connect(_tcp_url(server), timeout=1.0, keepalive=None) as client,
        _bystander(server) as bystander,
    ):
        rov = TrackedClient(client)
        rov.add_heard_listener(lambda announcement: heard.append(str(announcement.kind)))
        await rov.send_raw("#start!")
        await rov.send_raw("#th.90.40!")
        await _until(lambda: not _locked(server), "the pilot unlocks")
        sent = client.counters.frames_sent
        await bystander.stop()
        await _until(lambda: rov.commanded.lock is LockState.LOCKED, "the pilot hears the stop")
        assert rov.commanded.lock_text() == "locked (stopped by another line)"
        assert status_lines(rov)[0] == "motors:     locked (stopped by another line)"  # console
        assert rov.commanded.power_percent == 0  # the controller cleared its set-points
        # Another line unlocks: shown, but the pilot's tool stays locked until it unlocks.
        await bystander.start()
        await _until(lambda: rov.commanded.heard_lock is LockState.UNLOCKED, "it hears the unlock")
        assert rov.commanded.lock_text() == "unlocked (started by another line)"
        assert rov.commanded.lock is LockState.LOCKED
        assert client.counters.frames_sent == sent  # nothing heard made it send anything
        assert heard == ["locked", "unlocked"]  # (its own start, heard back, changed nothing)


def _telemetry(peer: Peer, kept: list[dict[str, Any]]) -> list[dict[str, Any]]:
    while not peer.outbox.empty():
        message = peer.outbox.get_nowait()
        if message["type"] == "telemetry":
            kept.append(message)
    return kept


async def test_every_page_of_the_station_shows_a_bystanders_stop(start_server: StartServer) -> None:
    # Before, every page went on showing "unlocked" after another tool's #stop!, and the relay
    # flying, its motion dropped by the locked controller.
    server = start_server()
    async with (
        rovlink.aio.connect(_tcp_url(server), timeout=1.0, keepalive=None) as client,
        _bystander(server) as bystander,
    ):
        station = Station(TrackedClient(client), description="tcp")
        pilot, watcher = station.join("pilot"), station.join("watcher")
        for message in ({"type": "take_control"}, {"type": "command", "name": "start"}):
            assert await station.handle(pilot, json.dumps(message))
        await _until(lambda: not _locked(server), "the pilot unlocks")
        sent = client.counters.frames_sent
        await bystander.stop()
        seen: dict[str, list[dict[str, Any]]] = {pilot.id: [], watcher.id: []}
        for peer in (pilot, watcher):
            await _until(
                lambda peer=peer: any(  # type: ignore[misc]
                    t["commanded"]["lock"] == "locked" for t in _telemetry(peer, seen[peer.id])
                ),
                f"{peer.label} is told",
            )
            commanded = seen[peer.id][-1]["commanded"]
            assert commanded["heard_lock"] == "locked"
            assert commanded["heard_lock_because"] == "stopped by another line"
        assert "cut: motors locked (stopped by another line)" in station.relay.status
        assert client.counters.frames_sent == sent  # no zero thrust, no #stop!
        # The pilot unlocks again: as last sent once more.
        assert await station.handle(pilot, json.dumps({"type": "command", "name": "start"}))
        await _until(lambda: not _locked(server), "the pilot unlocks again")
        commanded = station._telemetry(None)["commanded"]
        assert (commanded["lock"], commanded["heard_lock"]) == ("unlocked", None)


async def test_the_monitors_motors_row_shows_a_bystanders_stop(start_server: StartServer) -> None:
    server = start_server()
    sent: list[bytes] = []

    def keep_sent(event: ClientEvent) -> None:
        if isinstance(event, BytesSent):
            sent.append(event.data)

    async def connect(on_stray: StrayCallback) -> AsyncClient:
        return await rovlink.aio.connect(
            _tcp_url(server), timeout=1.0, on_stray=on_stray, on_event=keep_sent
        )

    app = MonitorApp(connect, description="tcp", rate_hz=20)
    async with _bystander(server) as bystander, app.run_test(size=(100, 34)) as pilot:
        await _until(lambda: app.rov is not None, "the monitor connects")
        await pilot.press("s")
        await _until(lambda: not _locked(server), "the monitor unlocks")
        assert "unlocked (as last sent)" in shown(app, "#commanded")
        await bystander.stop()
        await _until(
            lambda: "locked (stopped by another line)" in shown(app, "#commanded"),
            "the monitor shows the stop",
        )
        before = len(sent)
        await pilot.press("q")
    # It unlocked the robot and never stopped it itself: leaving, it still does (a stop heard
    # is no reason to send less than before; the monitor and its driver both see to it).
    assert b"#stop!" in sent[before:]


async def test_hearing_other_lines_hears_a_stop_with_no_bystander_turning_debug_on(
    start_server: StartServer,
) -> None:
    # What --hear-other-lines does: the tool itself puts the controller's debug output on.
    server = start_server()
    assert server.pty_path is not None
    async with (
        rovlink.aio.connect(_tcp_url(server), timeout=1.0, keepalive=None) as client,
        rovlink.aio.connect(server.pty_path, timeout=1.0, keepalive=None) as bystander,
    ):
        rov = TrackedClient(client)
        await hear_other_lines(client)
        await rov.send_raw("#start!")
        await bystander.stop()
        await _until(lambda: rov.commanded.heard_lock is LockState.LOCKED, "the stop is heard")
