"""The MQTT bridge on a simulated controller's TCP port hears a stop sent on its PTY (debug
output on): its retained state says locked, and where that came from."""

from __future__ import annotations

import asyncio

import pytest

import rovlink.aio
from rovlink.bridges.mqtt.bridge import MqttBridge
from rovlink.bridges.mqtt.broker import BrokerSettings
from rovlink.client.events import BytesSent, ClientEvent
from rovlink.piloting.tracked import TrackedClient
from rovlink.protocol import Command
from tests.bridges.mqtt.broker import Mosquitto
from tests.bridges.mqtt.rig import subscriber, until
from tests.sim.conftest import StartServer, start_server  # noqa: F401 - the fixture

pytestmark = pytest.mark.integration


async def test_the_state_says_locked_after_a_stop_from_another_line(
    broker: Mosquitto,
    start_server: StartServer,  # noqa: F811 - the fixture
) -> None:
    # Before, the retained state went on saying "unlocked" after another tool's #stop!.
    server = start_server()
    assert server.tcp_address is not None
    assert server.pty_path is not None
    host, port = server.tcp_address
    sent: list[Command] = []

    def keep_sent(event: ClientEvent) -> None:
        if isinstance(event, BytesSent) and event.command is not None:
            sent.append(event.command)

    async with (
        rovlink.aio.connect(f"socket://{host}:{port}", timeout=1.0, on_event=keep_sent) as client,
        rovlink.aio.connect(server.pty_path, timeout=1.0, keepalive=None) as bystander,
        subscriber(broker, "rovlink/r1/state", "rovlink/r1/events", "rovlink/r1/cmd/reply") as deck,
    ):
        bridge = MqttBridge(
            TrackedClient(client),
            BrokerSettings("127.0.0.1", broker.port),
            "r1",
            allow_commands=True,
        )
        task = asyncio.ensure_future(bridge.run())
        try:
            await until(bridge.connected.is_set)
            await bystander.set_debug(True)  # (any line may: it is the controller's)
            assert (await deck.command("r1", "start"))["ok"]
            await deck.wait_for("rovlink/r1/state", lambda state: state["lock"] == "unlocked")
            before = len(sent)
            await bystander.stop()
            # (Each state is published as it changes: the latest is the one to read.)
            await until(lambda: deck.on("rovlink/r1/state")[-1].get("lock") == "locked")
            assert (
                deck.on("rovlink/r1/state")[-1]["lock_heard_because"] == "stopped by another line"
            )
            event = await deck.wait_for("rovlink/r1/events", lambda e: e["event"] == "lock")
            assert event["detail"] == "motors locked (stopped by another line)"
            # Nothing heard made it send anything but its polls.
            assert [str(command) for command in sent[before:] if not command.spec.is_query] == []
        finally:
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)
