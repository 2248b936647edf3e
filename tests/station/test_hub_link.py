"""The station's hub across a robot link that drops and comes back: a fake controller on TCP
(closed and refused, as an adapter unplugged; listening again, as one plugged back) and the
asyncio driver reopening it (``reconnect=True``, as ``rovlink web`` connects)."""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from typing import Any

import pytest

import rovlink.aio
from rovlink.piloting import LockState, TrackedClient
from rovlink.station.hub import Peer, Station
from tests.client.fake_controller import FakeController, FakeControllerServer

pytestmark = pytest.mark.integration

CONDITION_TIMEOUT_S = 5.0


def released() -> dict[str, Any]:
    return {**held(), "deadman": False, "power_percent": 0}


def held(power_percent: int = 60) -> dict[str, Any]:
    return {
        "type": "input",
        "deadman": True,
        "direction_deg": 90,
        "power_percent": power_percent,
        "vertical_percent": 0,
        "source": "keyboard",
    }


@dataclass
class LinkHub:
    """A station whose robot link can be pulled out and plugged back."""

    station: Station
    port: FakeControllerServer

    async def send(self, peer: Peer, message: dict[str, Any]) -> None:
        assert await self.station.handle(peer, json.dumps(message))

    def controller(self, index: int) -> FakeController:
        return self.port.fakes[index]

    async def until(self, condition: Callable[[], bool]) -> None:
        deadline_s = asyncio.get_running_loop().time() + CONDITION_TIMEOUT_S
        while not condition():
            assert asyncio.get_running_loop().time() < deadline_s, "condition not met in time"
            await asyncio.sleep(0.005)

    async def flying(self) -> Peer:
        """A pilot flying at 60 % once the controller got it."""
        pilot = self.station.join("pilot")
        await self.send(pilot, {"type": "take_control"})
        await self.send(pilot, {"type": "command", "name": "start"})
        await self.send(pilot, released())
        await self.send(pilot, held())
        await self.until(lambda: "#th.90.60!" in self.controller(0).frames())
        return pilot

    async def unplugged(self) -> None:
        self.port.refuse = True
        self.controller(0).close()
        await self.until(lambda: not self.station._link_up)

    async def plugged_back(self) -> None:
        self.port.refuse = False
        await self.until(lambda: self.station._link_up and len(self.port.fakes) == 2)

    def log(self) -> list[str]:
        return [entry["text"] for entry in self.station._log]


@pytest.fixture
async def hub() -> AsyncIterator[LinkHub]:
    port = FakeControllerServer()
    client = await rovlink.aio.connect(port.url, reconnect=True, timeout=0.5)
    try:
        yield LinkHub(Station(TrackedClient(client), description=port.url), port)
    finally:
        await client.close()
        port.close()


def pilot_of(hub: LinkHub) -> Peer | None:
    """The pilot now (a call: each assertion reads it afresh)."""
    return hub.station.pilot


def control_messages(peer: Peer) -> list[dict[str, Any]]:
    messages = []
    while not peer.outbox.empty():
        message = peer.outbox.get_nowait()
        if message["type"] == "control":
            messages.append(message)
    return messages


async def test_control_changes_while_the_link_is_down_are_made_and_shown(hub):
    pilot = await hub.flying()
    watcher = hub.station.join("watcher")
    await hub.unplugged()
    control_messages(watcher)
    # The pilot's page closes: before, the cut's zero thrust raised on the lost link, out of the
    # WebSocket's end, and nobody was told that nobody had control.
    await hub.station.leave(pilot)
    assert pilot_of(hub) is None
    assert [m["pilot_id"] for m in control_messages(watcher)] == [None]
    # Taking control works too (before: "the robot's link: connection lost", still a watcher).
    await hub.send(watcher, {"type": "take_control"})
    assert pilot_of(hub) == watcher  # (Peer: eq is identity)
    assert [m["pilot_id"] for m in control_messages(watcher)] == [watcher.id]
    assert not hub.station.relay.armed
    # And releasing it.
    await hub.send(watcher, {"type": "release_control"})
    assert pilot_of(hub) is None
    assert [m["pilot_id"] for m in control_messages(watcher)] == [None]


async def test_stop_while_the_link_is_down_goes_first_and_is_shown_as_sent(hub):
    pilot = await hub.flying()
    await hub.unplugged()
    await hub.send(pilot, {"type": "stop"})  # returns at once: the driver keeps it
    assert "the robot's link is down" in hub.log()[-1]  # (before: "STOP from ...", as if sent)
    await hub.plugged_back()
    frames = hub.controller(1).frames()
    assert frames[0] == "#stop!"  # the reopened link's first frame
    # The controller got #stop! on the reopened link: locked, and the page says so (before:
    # "unknown" — the reopened link forgot it).
    assert hub.station.tracked.commanded.lock is LockState.LOCKED
    assert hub.station._telemetry(None)["commanded"]["lock"] == "locked"


async def test_a_lost_link_does_not_show_the_motors_unlocked(hub):
    await hub.flying()
    assert hub.station._telemetry(None)["commanded"]["lock"] == "unlocked"
    await hub.unplugged()
    # Before, "unlocked" (as last sent) stood for the whole outage, while the controller's
    # failsafe, or its line going, had locked the robot.
    commanded = hub.station._telemetry(None)["commanded"]
    assert commanded["lock"] == "unknown"
    assert commanded["lock_unknown_because"].startswith("the link was lost")
    await hub.plugged_back()
    assert hub.station._telemetry(None)["commanded"]["lock"] == "unknown"  # (as before)


async def test_a_dead_man_pressed_again_while_the_link_was_down_flies_nothing_when_back(hub):
    pilot = await hub.flying()
    await hub.unplugged()
    # The pilot lets go and holds again while the link is down: nothing is relayed, and the
    # relay is not shown armed or flying (before: "flying", with nothing sent).
    await hub.send(pilot, released())
    await hub.send(pilot, held())
    assert not hub.station.relay.armed
    assert "link was lost" in hub.station.relay.status
    # The pages are not told to release the dead-man to arm: released, it arms nothing while
    # the link is down (before: "...; release the dead-man to arm", and nothing changed).
    shown = hub.station._telemetry(None)["relay"]["status"]
    assert shown == "cut: the robot's link was lost; nothing is relayed until it is back"
    await hub.plugged_back()
    for _ in range(3):  # the page's re-sends while the dead-man is held
        await hub.send(pilot, held())
    assert "link was reopened" in hub.station.relay.status
    await hub.send(pilot, {"type": "command", "name": "h+"})  # a fence
    await hub.until(lambda: "#h+!" in hub.controller(1).frames())
    # (Before, the relay armed during the outage flew the held stick at once on the reopened
    # link, minutes later perhaps: #th.90.60!.)
    assert not [f for f in hub.controller(1).frames() if f.startswith("#th.") and f != "#th.90.0!"]
    await hub.send(pilot, released())
    await hub.send(pilot, held())
    await hub.until(lambda: "#th.90.60!" in hub.controller(1).frames())  # released and again


def error_messages(peer: Peer) -> list[str]:
    messages = []
    while not peer.outbox.empty():
        message = peer.outbox.get_nowait()
        if message["type"] == "error":
            messages.append(message["message"])
    return messages


async def test_a_command_the_down_link_cannot_take_is_named_as_not_sent(hub):
    pilot = await hub.flying()
    await hub.unplugged()
    error_messages(pilot)
    await hub.send(pilot, {"type": "command", "name": "mvd", "values": [300]})
    # Before: "the robot's link: connection lost: ..." and "sending failed: ...", which of
    # the pilot's commands was lost left to guess.
    [error] = error_messages(pilot)
    assert error.startswith("#mvd.300! not sent: the robot's link: ")
    assert hub.log()[-1].startswith("browser 1 (pilot): #mvd.300! not sent: ")
    await hub.plugged_back()
    await hub.send(pilot, {"type": "command", "name": "h+"})  # a fence
    await hub.until(lambda: "#h+!" in hub.controller(1).frames())
    assert "#mvd.300!" not in hub.controller(1).frames()  # not kept for later
