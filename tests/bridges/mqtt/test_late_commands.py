"""Motion that reaches the MQTT bridge late is refused: a mosquitto stopped (SIGSTOP) while a
command is published to it hands the command over when it resumes (SIGCONT), and a JSON
request's ``at`` says how old it is."""

from __future__ import annotations

import asyncio
import json
import re
import socket
import time
from typing import Any

import aiomqtt
import pytest

from tests.bridges.mqtt.broker import Mosquitto
from tests.bridges.mqtt.rig import bridged_robot, subscriber, until

pytestmark = pytest.mark.integration

#: Short, so that a stall beyond it is quickly seen.
_MAX_AGE_S = 0.3


async def test_motion_a_stalled_broker_held_is_refused_once_it_resumes(broker: Mosquitto):
    # The bridge's connection outlives a stall shorter than its reply timeout: a "th" published
    # during the stall was carried out when the broker resumed, after the motion timeout would
    # have expired it (and after its pilot may have given up on it).
    async with (
        bridged_robot(broker, "late1", max_command_age_s=_MAX_AGE_S) as robot,
        subscriber(broker, "rovlink/late1/cmd/reply") as watcher,
        aiomqtt.Client("127.0.0.1", broker.port) as pilot,
    ):
        assert (await watcher.command("late1", "start"))["ok"]
        bridge = robot.bridge
        with broker.stalled():
            published = asyncio.ensure_future(pilot.publish("rovlink/late1/cmd", "th 90 50", qos=1))
            # The bridge's state (republished every 2 s) waits for the broker's answer.
            await until(lambda: bridge.broker_silence.silent_s() > _MAX_AGE_S)
        await published
        reply = await watcher.wait_for("rovlink/late1/cmd/reply", lambda r: r["command"] != "start")
        assert reply["command"] == "th 90 50"
        assert not reply["ok"]
        assert "the broker had answered nothing for" in reply["error"]
        assert "#th.90.50!" not in robot.frames()
        assert bridge.connected.is_set()  # the same connection: the stall was short
        fresh = await watcher.command("late1", "th 90 50")  # published again, now: carried out
        assert fresh["ok"], fresh
        await until(lambda: "#th.90.50!" in robot.frames())


async def test_a_requests_at_says_how_old_it_is(broker: Mosquitto):
    # (A limit long enough for a fresh request on a loaded machine: 5 s is past it all the same.)
    async with (
        bridged_robot(broker, "late2", max_command_age_s=2.0) as robot,
        subscriber(broker, "rovlink/late2/cmd/reply") as watcher,
    ):

        async def ask(command: str, at: object) -> dict[str, object]:
            reply = await watcher.command("late2", json.dumps({"command": command, "at": at}))
            assert isinstance(reply, dict)
            return reply

        assert (await ask("start", time.time()))["ok"]
        old = await ask("th 90 50", time.time() - 5.0)
        assert not old["ok"]
        # (5.0 s, or a little more on a loaded machine: the request takes time to arrive.)
        assert re.search(r'published 5\.[0-4] s ago \(its "at"\)', str(old["error"]))
        ahead = await ask("th 90 50", time.time() + 60.0)
        assert "60.0 s ahead of the bridge's clock" in str(ahead["error"])
        bad = await ask("th 90 50", "yesterday")
        assert bad["error"] == '"at" must be Unix time in seconds, a number, got "yesterday"'
        assert "#th.90.50!" not in robot.frames()
        assert (await ask("qd", time.time() - 5.0))["ok"]  # a query moves nothing: answered
        stop = await ask("stop", time.time() - 5.0)  # stop, however old: carried out
        assert stop["ok"]
        assert (await ask("start", time.time()))["ok"]
        assert (await ask("th 90 50", time.time()))["ok"]
        await until(lambda: "#th.90.50!" in robot.frames())


async def test_motion_a_publishers_client_kept_through_its_reconnection_is_refused_by_its_at(
    broker: Mosquitto,
):
    # paho-mqtt keeps a QoS 1 publication made while its connection is down and sends it once
    # it has reconnected: the broker hands it over as new, however late. Only its "at" tells.
    import paho.mqtt.client as paho_mqtt
    from paho.mqtt.enums import CallbackAPIVersion

    async with (
        bridged_robot(broker, "late3", max_command_age_s=_MAX_AGE_S) as robot,
        subscriber(broker, "rovlink/late3/cmd/reply") as watcher,
    ):
        assert (await watcher.command("late3", "start"))["ok"]
        pilot = paho_mqtt.Client(CallbackAPIVersion.VERSION2)
        pilot.reconnect_delay_set(min_delay=1, max_delay=1)  # (longer than _MAX_AGE_S)
        connected = asyncio.Event()
        loop = asyncio.get_running_loop()

        def on_connect(*_: object) -> None:
            loop.call_soon_threadsafe(connected.set)

        pilot.on_connect = on_connect
        pilot.connect("127.0.0.1", broker.port)
        pilot.loop_start()
        try:
            await asyncio.wait_for(connected.wait(), 15)
            connected.clear()
            link = pilot.socket()
            assert isinstance(link, socket.socket)
            link.shutdown(socket.SHUT_RDWR)  # its network drops
            await until(lambda: not pilot.is_connected())
            stamped = json.dumps({"command": "th 90 50", "at": time.time()})
            for payload in (stamped, "th 90 60"):
                kept = pilot.publish("rovlink/late3/cmd", payload, qos=1)
                assert kept.rc == paho_mqtt.MQTT_ERR_NO_CONN  # kept for later
            await asyncio.wait_for(connected.wait(), 15)  # reconnected: both sent now
            await until(lambda: len(watcher.on("rovlink/late3/cmd/reply")) == 3)
        finally:
            pilot.loop_stop()
            pilot.disconnect()
        late, bare = watcher.on("rovlink/late3/cmd/reply")[1:]
        assert late["ok"] is False
        assert 'ago (its "at"): motion older than 0.3 s is not carried out' in late["error"]
        assert "#th.90.50!" not in robot.frames()
        # Without "at" nothing tells it from a fresh command (docs/bridges.md says so).
        assert bare["ok"] is True


async def test_readings_a_lost_connection_did_not_carry_are_not_published_on_the_next(
    broker: Mosquitto, monkeypatch: pytest.MonkeyPatch
):
    # The readings queued while a stalled broker held the publisher back (up to 64) were
    # published on the next connection, seconds late, ahead of the live ones.
    monkeypatch.setattr("rovlink.bridges.mqtt.bridge._STATE_REFRESH_S", 0.2)  # (noticed soon)
    published: list[tuple[int, int]] = []  # (connection, seq) of each reading published
    real_publish = aiomqtt.Client.publish

    async def recording_publish(
        self: aiomqtt.Client, topic: str, *args: Any, **kwargs: Any
    ) -> None:
        if topic.endswith("/telemetry"):
            published.append((id(self), json.loads(args[0])["seq"]))
        await real_publish(self, topic, *args, **kwargs)

    monkeypatch.setattr(aiomqtt.Client, "publish", recording_publish)
    async with bridged_robot(broker, "late4", rate_hz=50, reply_timeout_s=0.5) as robot:
        bridge = robot.bridge
        await until(lambda: len(published) > 0)
        with broker.stalled():
            await until(lambda: not bridge.connected.is_set())
            given_up_at_seq = bridge.sequence
        await until(bridge.connected.is_set)
        await until(lambda: published[-1][1] > given_up_at_seq + 5)
        last_connection = published[-1][0]
        on_the_next = [seq for connection, seq in published if connection == last_connection]
        assert min(on_the_next) > given_up_at_seq


async def test_readings_beyond_the_backlog_drop_the_oldest_not_the_newest(broker: Mosquitto):
    # A broker too slow for the telemetry: the backlog (64 readings) kept its oldest and dropped
    # every newer one, so the readings published once it caught up were seconds old.
    from rovlink.bridges.mqtt import bridge as bridge_module
    from rovlink.client.sensors import Sensors

    backlog = bridge_module._TELEMETRY_BACKLOG
    async with bridged_robot(broker, "late5", rate_hz=1) as robot:
        bridge = robot.bridge
        await until(bridge.connected.is_set)
        reading = Sensors(100, 600, False, 0, 0, 90)
        # (No await in between: the publisher cannot take any of them meanwhile.)
        for _ in range(backlog + 20):
            bridge._on_reading(reading)
        newest = bridge.sequence
        queued = [json.loads(bridge._telemetry.get_nowait())["seq"] for _ in range(backlog)]
        assert queued[-1] == newest
        assert queued == list(range(newest - backlog + 1, newest + 1))
