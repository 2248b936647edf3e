"""The MQTT bridge while its controller link is down and being reopened (a client with
``reconnect``): a fake controller on TCP that is unplugged and plugged back, a real mosquitto."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

import pytest

import rovlink.aio
from rovlink.bridges.mqtt.bridge import MqttBridge
from rovlink.bridges.mqtt.broker import BrokerSettings
from rovlink.piloting.tracked import TrackedClient
from tests.bridges.mqtt.broker import Mosquitto
from tests.bridges.mqtt.rig import Subscriber, subscriber, until
from tests.client.fake_controller import FakeControllerServer

pytestmark = pytest.mark.integration

ROBOT = "down1"


@asynccontextmanager
async def unplugged_bridge(
    broker: Mosquitto, controller: FakeControllerServer, *, allow_commands: bool = False
) -> AsyncIterator[Subscriber]:
    """A bridge whose controller link has just been lost (and is not reopened until
    ``controller.refuse`` is cleared); a subscriber to its replies and events."""
    async with (
        rovlink.aio.connect(controller.url, reconnect=True, keepalive=None, timeout=1.0) as rov,
        subscriber(broker, f"rovlink/{ROBOT}/cmd/reply", f"rovlink/{ROBOT}/events") as watcher,
    ):
        bridge = MqttBridge(
            TrackedClient(rov),
            BrokerSettings("127.0.0.1", broker.port),
            ROBOT,
            allow_commands=allow_commands,
        )
        task = asyncio.ensure_future(bridge.run())
        try:
            await until(bridge.connected.is_set)
            await until(lambda: "#qsa!" in controller.fakes[0].frames())  # it polls
            controller.refuse = True  # unplugged
            controller.fakes[0].close()
            await watcher.wait_for(
                f"rovlink/{ROBOT}/events",
                lambda e: e["event"] == "link" and e["detail"].startswith("lost"),
            )
            yield watcher
        finally:
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)


async def test_a_stop_while_the_link_is_down_is_not_answered_as_sent(broker: Mosquitto):
    # Before, the reply said "ok": true and "frame": "#stop!" while nothing had been written.
    controller = FakeControllerServer()
    try:
        async with unplugged_bridge(broker, controller) as watcher:
            reply = await watcher.command(ROBOT, '{"command": "stop", "id": 3}')
            assert reply["ok"] is False
            assert reply["id"] == 3
            assert "frame" not in reply
            assert "link is down" in reply["error"]
            assert "first frame" in reply["error"]
            controller.refuse = False  # plugged back: the stop goes out first
            await until(lambda: len(controller.fakes) == 2)
            await until(lambda: bool(controller.fakes[1].frames()))
            assert controller.fakes[1].frames()[0] == "#stop!"
    finally:
        controller.close()


async def test_another_command_while_the_link_is_down_is_refused_and_not_kept(broker: Mosquitto):
    controller = FakeControllerServer()
    try:
        async with unplugged_bridge(broker, controller, allow_commands=True) as watcher:
            reply = await watcher.command(ROBOT, "start")
            assert reply["ok"] is False
            assert reply["error"].startswith("not sent: the controller link is down")
            controller.refuse = False
            await until(lambda: len(controller.fakes) == 2)
            await until(lambda: "#qsa!" in controller.fakes[1].frames())  # served again
            assert "#start!" not in controller.fakes[1].frames()
    finally:
        controller.close()
