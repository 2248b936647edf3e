"""The MQTT bridge against a real mosquitto: three robots, commands, bad payloads, restarts."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
from collections.abc import Callable
from typing import Any

import aiomqtt
import pytest
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from rovlink.bridges.mqtt.bridge import _taken_over
from rovlink.client.errors import ConnectionLostError
from rovlink.protocol import Command
from tests.bridges.mqtt.broker import Mosquitto
from tests.bridges.mqtt.rig import CONDITION_TIMEOUT_S, bridged_robot, subscriber, until

pytestmark = pytest.mark.integration

_HUGE_AT_START = b'{"command": "start", "at": 1' + b"0" * 400 + b"}"


async def test_a_subscriber_sees_three_robots_and_a_command_reaches_only_its_robot(
    broker: Mosquitto,
):
    async with contextlib.AsyncExitStack() as stack:
        robots = [
            await stack.enter_async_context(bridged_robot(broker, f"r{n}")) for n in (1, 2, 3)
        ]
        watcher = await stack.enter_async_context(
            subscriber(broker, "rovlink/+/telemetry", "rovlink/+/state", "rovlink/r2/cmd/reply")
        )
        for robot in robots:
            reading = await watcher.wait_for(f"rovlink/{robot.robot_id}/telemetry")
            assert reading["robot"] == robot.robot_id
            assert set(reading) >= {"depth_cm", "leak", "heading_deg", "seq", "at"}
            state = await watcher.wait_for(f"rovlink/{robot.robot_id}/state")
            assert state["online"] is True
            assert state["simulated"] is False  # (a bridge made with no word of it)

        before = {robot.robot_id: len(robot.motion_and_lock_frames()) for robot in robots}
        assert (await watcher.command("r2", "start"))["ok"]
        reply = await watcher.command("r2", "th 90 30")
        assert reply == {"robot": "r2", "ok": True, "command": "th 90 30", "frame": "#th.90.30!"}
        await until(lambda: "#th.90.30!" in robots[1].frames())
        assert robots[1].motion_and_lock_frames()[before["r2"] :] == ["#start!", "#th.90.30!"]
        for other in (robots[0], robots[2]):
            assert other.motion_and_lock_frames()[before[other.robot_id] :] == []
        unlocked = await watcher.wait_for(
            "rovlink/r2/state", lambda s: s.get("lock") == "unlocked" and s["power_percent"] == 30
        )
        assert unlocked["direction_deg"] == 90


async def test_queries_answer_with_named_values(broker: Mosquitto):
    async with bridged_robot(broker, "q1"), subscriber(broker, "rovlink/q1/cmd/reply") as watcher:
        reply = await watcher.command("q1", '{"command": "qd", "id": "depth-1"}')
        assert reply["ok"]
        assert reply["id"] == "depth-1"
        assert reply["replies"][0]["name"] == "qd"
        assert isinstance(reply["replies"][0]["values"]["depth_cm"], int)


@pytest.mark.parametrize(
    ("payload", "error"),
    [
        (b"\xff\xfe", "payload is not UTF-8 text"),
        (b"{not json", "payload is not valid JSON"),
        (b'{"cmd": "th 90 30"}', 'a JSON request needs "command"'),
        (b"th 400 30", "th: direction_deg must be in 0–360, got 400"),
        (b"thrust 1", "unknown command 'thrust'"),
        (b"STOP", "unknown command 'STOP': commands are lower-case, did you mean stop?"),
        (b"", "empty payload"),
        (b"crcon", "owns the checksum and debug modes"),
        (b"x" * 600, "a command is at most 512"),
        (b'{"command": "start", "id": 1.5}', '"id" must be a string or an integer, got 1.5'),
        # An integer too large for a float once ended the bridge (OverflowError); quoted short.
        (_HUGE_AT_START, '"at" must be Unix time in seconds, a number, got 1000000000'),
        (b'{"command": "start", "at": 1e300}', 'its "at" is 1e+300 s ahead of the bridge\'s'),
        # JavaScript's Date.now() is in milliseconds: the clocks were blamed.
        pytest.param(
            f'{{"command": "th 90 30", "at": {int(time.time() * 1000)}}}'.encode(),
            '"at" is Unix time in seconds: this one looks like milliseconds',
            id="at-in-milliseconds",  # (not the time: each test process collects its own)
        ),
        # A lone surrogate has no UTF-8: the reply that quoted it ended the bridge.
        (b'{"command": "\\ud800"}', "unknown command '\\ud800'"),
        # Which one counts depends on the parser: a tool reading the first saw a stop.
        (b'{"command": "stop", "command": "start"}', '"command" is given more than once'),
        # A misspelt "at" was ignored: motion carried out unchecked for lateness, as if sent now.
        (b'{"command": "th 90 30", "time": 1767225600}', 'unknown key "time"'),
        (b'{"command": "start", "Id": 4}', 'unknown key "Id"'),
        # A file of commands sent whole: "start takes 0 value(s), got 3".
        (b"start\nth 90 30\n", 'one command per message: this one has 2 lines ("th 90 30" after'),
        (b'{"command": "start\\nth 90 30"}', "one command per message: this one has 2 lines"),
    ],
)
async def test_malformed_payloads_get_an_error_and_send_nothing(
    broker: Mosquitto, payload: bytes, error: str
):
    async with (
        bridged_robot(broker, "m1") as robot,
        subscriber(broker, "rovlink/m1/cmd/reply") as watcher,
    ):
        before = len(robot.motion_and_lock_frames())
        reply = await watcher.command("m1", payload)
        assert reply["ok"] is False
        assert error in reply["error"]
        assert len(reply["error"]) < 200  # what was wrong, not the payload written out
        assert robot.motion_and_lock_frames()[before:] == []
        assert (await watcher.command("m1", "stop"))["ok"]  # still serving
        await until(lambda: robot.motion_and_lock_frames()[before:] == ["#stop!"])


async def test_a_state_before_the_first_reading_does_not_say_dry(broker: Mosquitto):
    # Before, "leak": false until a sensor reading came: a robot whose controller never
    # answered showed dry on every fleet view.
    async with (
        bridged_robot(broker, "u2", replies_held=True) as robot,
        subscriber(broker, "rovlink/u2/state") as watcher,
    ):
        state = await watcher.wait_for("rovlink/u2/state", lambda s: s.get("online"))
        assert (state["depth_cm"], state["leak"]) == (None, None)
        robot.link.held.clear()
        state = await watcher.wait_for("rovlink/u2/state", lambda s: s["depth_cm"] is not None)
        assert state["leak"] is False


async def test_without_allow_commands_only_stop_is_accepted(broker: Mosquitto):
    async with (
        bridged_robot(broker, "s1", allow_commands=False) as robot,
        subscriber(broker, "rovlink/s1/cmd/reply", "rovlink/s1/state") as watcher,
    ):
        before = len(robot.motion_and_lock_frames())
        refused = await watcher.command("s1", "start")
        assert refused["ok"] is False
        assert "--allow-commands" in refused["error"]
        assert robot.motion_and_lock_frames()[before:] == []
        assert (await watcher.command("s1", "stop"))["frame"] == "#stop!"
        await until(lambda: robot.motion_and_lock_frames()[before:] == ["#stop!"])
        state = await watcher.wait_for("rovlink/s1/state")
        assert state["commands_allowed"] is False


@pytest.mark.parametrize("request_id", ["1.5", '{"n": 1}'])
async def test_a_stop_with_a_bad_id_still_stops_the_robot(broker: Mosquitto, request_id: str):
    # Before, the id's error refused the stop: the robot drove on.
    async with (
        bridged_robot(broker, "i1", allow_commands=False) as robot,
        subscriber(broker, "rovlink/i1/cmd/reply") as watcher,
    ):
        before = len(robot.motion_and_lock_frames())
        reply = await watcher.command("i1", f'{{"command": "stop", "id": {request_id}}}')
        assert (reply["ok"], reply["frame"]) == (True, "#stop!")
        assert "id" not in reply
        assert f'"id" must be a string or an integer, got {request_id}' in reply["warning"]
        await until(lambda: robot.motion_and_lock_frames()[before:] == ["#stop!"])


@pytest.mark.parametrize("payload", [b"stop", b'{"command": "stop", "id": 3}'])
async def test_a_command_from_a_file_with_a_byte_order_mark_is_read(
    broker: Mosquitto, payload: bytes
):
    # A file saved by a Windows editor or PowerShell starts with a UTF-8 byte order mark: the
    # stop published from it (mosquitto_pub -f) was refused, "unknown command '\ufeffstop'".
    async with (
        bridged_robot(broker, "o1", allow_commands=False) as robot,
        subscriber(broker, "rovlink/o1/cmd/reply") as watcher,
    ):
        before = len(robot.motion_and_lock_frames())
        reply = await watcher.command("o1", b"\xef\xbb\xbf" + payload)
        assert (reply["ok"], reply["command"], reply["frame"]) == (True, "stop", "#stop!")
        await until(lambda: robot.motion_and_lock_frames()[before:] == ["#stop!"])


async def test_an_id_with_a_lone_surrogate_comes_back_as_it_was(broker: Mosquitto):
    # Its reply could not be encoded as UTF-8: the bridge ended, after sending the command.
    async with (
        bridged_robot(broker, "u1") as robot,
        subscriber(broker, "rovlink/u1/cmd/reply") as watcher,
    ):
        reply = await watcher.command("u1", b'{"command": "qd", "id": "a\\ud800"}')
        assert (reply["ok"], reply["id"]) == (True, "a\ud800")
        assert not robot.task.done()


async def test_a_stop_with_a_key_given_twice_still_stops_the_robot(broker: Mosquitto):
    async with (
        bridged_robot(broker, "i3", allow_commands=False) as robot,
        subscriber(broker, "rovlink/i3/cmd/reply") as watcher,
    ):
        before = len(robot.motion_and_lock_frames())
        reply = await watcher.command("i3", b'{"command": "stop", "id": 1, "id": 2}')
        assert (reply["ok"], reply["frame"]) == (True, "#stop!")
        assert '"id" is given more than once' in reply["warning"]
        await until(lambda: robot.motion_and_lock_frames()[before:] == ["#stop!"])


async def test_a_stop_with_an_unknown_key_still_stops_the_robot(broker: Mosquitto):
    async with (
        bridged_robot(broker, "i4", allow_commands=False) as robot,
        subscriber(broker, "rovlink/i4/cmd/reply") as watcher,
    ):
        before = len(robot.motion_and_lock_frames())
        reply = await watcher.command("i4", b'{"command": "stop", "id": 9, "reason": "surface"}')
        assert (reply["ok"], reply["frame"], reply["id"]) == (True, "#stop!", 9)
        assert 'unknown key "reason"' in reply["warning"]
        await until(lambda: robot.motion_and_lock_frames()[before:] == ["#stop!"])


async def test_a_stop_followed_by_other_lines_still_stops_the_robot(broker: Mosquitto):
    async with (
        bridged_robot(broker, "i5", allow_commands=False) as robot,
        subscriber(broker, "rovlink/i5/cmd/reply") as watcher,
    ):
        before = len(robot.motion_and_lock_frames())
        reply = await watcher.command("i5", b'{"command": "stop\\nstart", "id": 3}')
        assert (reply["ok"], reply["frame"], reply["id"]) == (True, "#stop!", 3)
        assert "one command per message" in reply["warning"]
        await until(lambda: robot.motion_and_lock_frames()[before:] == ["#stop!"])


async def test_a_stop_with_a_huge_at_still_stops_the_robot(broker: Mosquitto):
    async with (
        bridged_robot(broker, "i2", allow_commands=False) as robot,
        subscriber(broker, "rovlink/i2/cmd/reply") as watcher,
    ):
        before = len(robot.motion_and_lock_frames())
        reply = await watcher.command("i2", _HUGE_AT_START.replace(b"start", b"stop"))
        assert (reply["ok"], reply["frame"]) == (True, "#stop!")
        assert '"at" must be Unix time in seconds' in reply["warning"]
        await until(lambda: robot.motion_and_lock_frames()[before:] == ["#stop!"])
        assert not robot.task.done()


async def test_an_mqtt5_response_topic_and_correlation_data_are_honoured(broker: Mosquitto):
    async with bridged_robot(broker, "c1"), subscriber(broker, "answers/me") as watcher:
        properties = Properties(PacketTypes.PUBLISH)
        properties.ResponseTopic = "answers/me"
        properties.CorrelationData = b"42"
        # The watcher's client speaks MQTT 3.1.1; a v5 client publishes the request.
        async with aiomqtt.Client(
            "127.0.0.1", broker.port, protocol=aiomqtt.ProtocolVersion.V5
        ) as asker:
            await asker.publish("rovlink/c1/cmd", b"qhe", qos=1, properties=properties)
        reply = await watcher.wait_for("answers/me")
        assert reply["ok"]
        assert reply["replies"][0]["name"] == "qhe"


async def test_stale_motion_is_expired_and_reported_as_a_failsafe_event(broker: Mosquitto):
    async with (
        bridged_robot(broker, "f1", motion_timeout_s=0.3) as robot,
        subscriber(broker, "rovlink/f1/events", "rovlink/f1/cmd/reply") as watcher,
    ):
        await watcher.command("f1", "start")
        await watcher.command("f1", "th 180 40")
        event = await watcher.wait_for("rovlink/f1/events", lambda e: e["event"] == "failsafe")
        assert "#th.180.0!" in event["detail"]
        assert "#th.180.0!" in robot.frames()


async def test_a_clean_exit_marks_the_robot_offline_and_locks_it(broker: Mosquitto):
    async with subscriber(broker, "rovlink/e1/state") as watcher:
        async with bridged_robot(broker, "e1") as robot:
            await watcher.wait_for("rovlink/e1/state", lambda s: s["online"])
        offline = await watcher.wait_for("rovlink/e1/state", lambda s: not s["online"])
        assert offline["reason"] == "bridge stopped"
        assert robot.frames()[-1] == "#stop!"


async def test_the_robot_is_locked_before_the_bridge_serves(broker: Mosquitto):
    async with (
        subscriber(broker, "rovlink/l1/state") as watcher,
        bridged_robot(broker, "l1") as robot,
    ):
        first = await watcher.wait_for("rovlink/l1/state", lambda s: s["online"])
        assert first["lock"] == "locked"  # known from the first state on, not "unknown"
        assert robot.motion_and_lock_frames()[:1] == ["#stop!"]


async def test_broker_restart_reconnects_and_keeps_events(broker: Mosquitto):
    async with bridged_robot(broker, "b1", leak_at_s=3.0) as robot:
        # A subscriber with a persistent session: the broker keeps its QoS 1 messages.
        async with subscriber(
            broker, "rovlink/b1/events", "rovlink/b1/telemetry", identifier="watcher", clean=False
        ) as watcher:
            await watcher.wait_for("rovlink/b1/telemetry")
        broker.stop()
        await until(lambda: not robot.bridge.connected.is_set())
        # The leak fires while the broker is away; the event waits in the outbox.
        await until(lambda: len(robot.bridge.outbox) > 0)
        seq_at_outage = robot.bridge.sequence
        broker.start()
        await until(robot.bridge.connected.is_set)
        async with subscriber(
            broker, "rovlink/b1/events", "rovlink/b1/telemetry", identifier="watcher", clean=False
        ) as watcher:
            event = await watcher.wait_for("rovlink/b1/events", lambda e: e["event"] == "leak")
            assert event["robot"] == "b1"
            resumed = await watcher.wait_for(
                "rovlink/b1/telemetry", lambda t: t["seq"] > seq_at_outage
            )
            assert resumed["leak"] is True
        assert len(robot.bridge.outbox) == 0


async def test_events_dropped_during_an_outage_are_said_when_the_broker_is_back(
    broker: Mosquitto, caplog: pytest.LogCaptureFixture
):
    # Regression: beyond the events kept (1000; 2 here) the oldest were dropped and only
    # counted: subscribers got the kept ones as if nothing had happened before them.
    caplog.set_level("WARNING", logger="rovlink.bridges.mqtt")
    async with bridged_robot(broker, "k1", motion_timeout_s=0.05, max_kept_events=2) as robot:
        # A persistent session: the broker keeps for it what the bridge publishes at reconnection.
        async with subscriber(broker, "rovlink/k1/events", identifier="k1-watcher", clean=False):
            pass
        broker.stop()
        await until(lambda: not robot.bridge.connected.is_set())
        outbox = robot.bridge.outbox
        for happened in range(1, 6):  # five failsafe events (motion not renewed) in the outage
            await robot.bridge.rov.send(Command("th", (90, 10)))
            await until(lambda n=happened: outbox.dropped + len(outbox) >= n)  # type: ignore[misc]
        broker.start()
        async with subscriber(
            broker, "rovlink/k1/events", identifier="k1-watcher", clean=False
        ) as watcher:
            await until(lambda: len(watcher.on("rovlink/k1/events")) >= 3)
            events = watcher.on("rovlink/k1/events")
    assert [event["event"] for event in events] == ["events_dropped", "failsafe", "failsafe"]
    said, first_kept = events[0], events[1]
    assert said["dropped"] == 3
    assert said["first_dropped_at"] < said["last_dropped_at"] <= first_kept["at"]
    assert said["detail"].startswith("3 events dropped while the broker could not take them")
    logged = [record.getMessage() for record in caplog.records]
    assert any("oldest now give way" in line for line in logged)  # as it began
    assert f"broker {broker.url}: {said['detail']}" in logged  # and once it was back


async def _ask_with_response_topic(
    broker: Mosquitto, command: bytes, response_topic: str, robot_id: str = "w1"
) -> None:
    """Publish ``command`` as an MQTT 5 request whose replies should go to ``response_topic``."""
    properties = Properties(PacketTypes.PUBLISH)
    properties.ResponseTopic = response_topic
    properties.CorrelationData = b"7"
    async with aiomqtt.Client(
        "127.0.0.1", broker.port, protocol=aiomqtt.ProtocolVersion.V5
    ) as asker:
        await asker.publish(f"rovlink/{robot_id}/cmd", command, qos=1, properties=properties)


async def test_a_response_topic_with_a_wildcard_is_refused_and_the_command_still_handled(
    broker: Mosquitto, caplog: pytest.LogCaptureFixture
):
    caplog.set_level("WARNING", logger="rovlink.bridges.mqtt")
    async with (
        bridged_robot(broker, "w1", allow_commands=False) as robot,
        subscriber(broker, "answers/#", "rovlink/w1/cmd/reply", "rovlink/w1/state") as watcher,
    ):
        before = len(robot.motion_and_lock_frames())
        await _ask_with_response_topic(broker, b"start", "answers/+/b")  # refused as usual
        await _ask_with_response_topic(broker, b"stop", "answers/#")  # sent as usual
        await until(lambda: robot.motion_and_lock_frames()[before:] == ["#stop!"])
        await until(lambda: len(caplog.records) >= 2)
        # Still serving, and the refused response topics got nothing (replies are in order).
        assert (await watcher.command("w1", "stop"))["ok"]
        assert not robot.task.done()
        assert [topic for topic, _ in watcher.received if topic.startswith("answers/")] == []
        assert len(watcher.on("rovlink/w1/cmd/reply")) == 1
        assert all("response topic" in record.getMessage() for record in caplog.records)
        assert watcher.on("rovlink/w1/state")[-1]["online"] is True


@pytest.mark.parametrize(
    ("target", "problem"),
    [
        ("rovlink/w2/cmd", "is a bridge's own topic"),
        ("rovlink/other/cmd", "is a bridge's own topic"),
        ("rovlink/w2/state", "is a bridge's own topic"),
        ("$SYS/x", "is a broker's own topic"),  # (refused by the broker, and logged as an error)
    ],
)
async def test_a_reply_is_never_sent_to_a_bridges_own_topic(
    broker: Mosquitto, caplog: pytest.LogCaptureFixture, target: str, problem: str
):
    # Before, a reply sent to a command topic was read there as a command (it carries its
    # "command"): this bridge carried its `start` out twice, or another robot carried it out.
    caplog.set_level("WARNING", logger="rovlink.bridges.mqtt")
    async with (
        bridged_robot(broker, "w2") as robot,
        subscriber(broker, "rovlink/+/cmd", "rovlink/w2/state", "rovlink/w2/cmd/reply") as watcher,
    ):
        await watcher.wait_for("rovlink/w2/state")
        await _ask_with_response_topic(broker, b'{"command": "start"}', target, robot_id="w2")
        await until(lambda: "response topic" in caplog.text)
        assert problem in caplog.text
        assert not [record for record in caplog.records if record.levelname == "ERROR"]
        assert (await watcher.command("w2", b'{"command": "qd"}'))["ok"]  # after any loop
        assert robot.motion_and_lock_frames().count("#start!") == 1
        assert [topic for topic, p in watcher.received if isinstance(p, dict) and "ok" in p] == [
            "rovlink/w2/cmd/reply"  # (qd's)
        ]


async def test_an_unexpected_error_ends_the_bridge_offline_and_stopped(
    broker: Mosquitto, monkeypatch: pytest.MonkeyPatch
):
    def broken(payload: bytes) -> None:
        raise RuntimeError("injected fault")

    monkeypatch.setattr("rovlink.bridges.mqtt.bridge.read_request", broken)
    async with (
        bridged_robot(broker, "x1") as robot,
        subscriber(broker, "rovlink/x1/state") as watcher,
    ):
        await watcher.wait_for("rovlink/x1/state", lambda s: s["online"])
        await watcher.client.publish("rovlink/x1/cmd", b"stop", qos=1)
        await until(robot.task.done)
        assert isinstance(robot.task.exception(), RuntimeError)
        offline = await watcher.wait_for("rovlink/x1/state", lambda s: not s["online"])
        assert offline["reason"] == "bridge failed: RuntimeError: injected fault"
        assert robot.frames()[-1] == "#stop!"
    # Retained: the fleet learns it later too.
    async with subscriber(broker, "rovlink/x1/state") as late:
        assert (await late.wait_for("rovlink/x1/state"))["online"] is False


async def test_a_lost_controller_is_said_as_such_not_as_a_stop(broker: Mosquitto):
    async with (
        subscriber(broker, "rovlink/n1/state", "rovlink/n1/events") as watcher,
        bridged_robot(broker, "n1") as robot,
    ):
        await watcher.wait_for("rovlink/n1/state", lambda s: s["online"])
        robot.port.close()  # the controller is gone, as a killed simulator or a pulled cable
        await until(robot.task.done)
        assert isinstance(robot.task.exception(), ConnectionLostError)
        event = await watcher.wait_for("rovlink/n1/events", lambda e: e["event"] == "link")
        assert event["detail"].startswith("lost ")
        offline = await watcher.wait_for("rovlink/n1/state", lambda s: not s["online"])
        assert offline["reason"].startswith("controller link lost: ")
        assert "simulated n1" in offline["reason"]
        # Said once: the goodbye waits for the event the publisher was sending, not resends it.
        assert [e["event"] for e in watcher.on("rovlink/n1/events")] == ["link"]


async def test_a_retained_command_is_never_carried_out_again_after_a_reconnection(
    broker: Mosquitto,
):
    # Before, the broker handed the retained `th 90 100` to the bridge on every connection:
    # after a broker restart it drove the unlocked robot at full power.
    async with bridged_robot(broker, "k1") as robot:
        async with subscriber(broker, "rovlink/k1/cmd/reply") as watcher:
            assert (await watcher.command("k1", "stop"))["ok"]
            before = len(watcher.on("rovlink/k1/cmd/reply"))
            await watcher.client.publish("rovlink/k1/cmd", b"th 90 100", qos=1, retain=True)
            await until(lambda: len(watcher.on("rovlink/k1/cmd/reply")) > before)
            refused = watcher.on("rovlink/k1/cmd/reply")[before]
            assert refused["ok"] is False  # live, yet retained: refused, with the reason
            assert "publish commands without retain" in refused["error"]
            assert "clear this one with an empty retained message" in refused["error"]
            assert (await watcher.command("k1", "start"))["ok"]  # the robot is unlocked now
        broker.restart()  # (the broker keeps its retained messages)
        await until(lambda: not robot.bridge.connected.is_set())
        await until(robot.bridge.connected.is_set)
        async with subscriber(broker, "rovlink/k1/cmd/reply") as watcher:
            assert (await watcher.command("k1", "qd"))["ok"]  # served in order: after it
        assert "#th.90.100!" not in robot.frames()


async def test_a_retained_command_is_not_carried_out_on_connecting(broker: Mosquitto):
    async with subscriber(broker, "rovlink/k2/cmd/reply") as watcher:
        await watcher.client.publish("rovlink/k2/cmd", b"th 90 100", qos=1, retain=True)
        async with bridged_robot(broker, "k2") as robot:
            assert (await watcher.command("k2", "qd"))["ok"]
            assert "#th.90.100!" not in robot.frames()


async def test_a_command_flagged_retained_is_refused_with_the_reason(broker: Mosquitto):
    # (However it came: live, or from a broker that ignored MQTT 5's retain handling.)
    published: list[tuple[str, bytes]] = []

    class RecordingBroker:
        async def publish(self, topic: str, payload: bytes, **_: object) -> None:
            published.append((topic, payload))

    class RetainedMessage:
        payload = b"th 90 100"
        retain = True
        properties = None

    async with bridged_robot(broker, "z1") as robot:
        assert await robot.bridge._read_command(RecordingBroker(), RetainedMessage()) is None
        [(topic, payload)] = published
        assert topic == "rovlink/z1/cmd/reply"
        reply = json.loads(payload)
        assert reply["ok"] is False
        assert "a retained command is not carried out" in reply["error"]
        assert "#th.90.100!" not in robot.frames()


async def test_a_stop_published_retained_is_still_carried_out(broker: Mosquitto):
    # "stop is always accepted": a panicking `mosquitto_pub -r … -m stop` was refused as retained
    # and the robot drove on. Clearing the retained message afterwards is no command.
    async with (
        bridged_robot(broker, "s9") as robot,
        subscriber(broker, "rovlink/s9/cmd/reply") as watcher,
    ):
        assert (await watcher.command("s9", "start"))["ok"]
        assert (await watcher.command("s9", "th 90 50"))["ok"]
        await until(lambda: robot.port.robot.controller.state().power_percent == 50)
        replies = watcher.on("rovlink/s9/cmd/reply")
        before = len(replies)
        await watcher.client.publish("rovlink/s9/cmd", b"stop", qos=1, retain=True)
        await until(lambda: len(watcher.on("rovlink/s9/cmd/reply")) > before)
        reply = watcher.on("rovlink/s9/cmd/reply")[before]
        assert reply["ok"] is True
        assert "publish commands without retain" in reply["warning"]
        assert robot.port.robot.controller.state().locked
        await watcher.client.publish("rovlink/s9/cmd", b"", qos=1, retain=True)  # cleared
        assert (await watcher.command("s9", "qd"))["ok"]  # the next reply is the query's
        assert len(watcher.on("rovlink/s9/cmd/reply")) == before + 2


async def test_a_command_the_controller_drops_is_answered_with_why(broker: Mosquitto):
    async with (
        bridged_robot(broker, "w1") as robot,
        subscriber(broker, "rovlink/w1/cmd/reply") as watcher,
    ):
        reply = await watcher.command("w1", "th 90 30")  # the bridge started the robot locked
        assert reply["ok"] is True  # written, as asked
        assert "drops th while motion is locked" in reply["warning"]
        assert (await watcher.command("w1", "mvdirect 0"))["ok"]
        assert (await watcher.command("w1", "start"))["ok"]
        assert "drops mvs in depth mode" in (await watcher.command("w1", "mvs 50"))["warning"]
        assert "warning" not in await watcher.command("w1", "mvd 100")
        assert robot.port.robot.controller.state().target_depth_cm == 100


async def test_after_a_controller_reset_the_state_says_locked_and_the_settings_return(
    broker: Mosquitto,
):
    # A reset locks the robot and brings back the configured defaults in depth mode (P21, P9):
    # the retained state went on saying "unlocked", a max PWM of 100 was 255 again unseen, and
    # `mvs` was dropped.
    async with (
        bridged_robot(broker, "r1", timeout_s=0.5) as robot,
        subscriber(broker, "rovlink/r1/cmd/reply", "rovlink/r1/events") as watcher,
    ):
        for command in ("mgmp 100", "mvdirect 1", "start", "th 0 40"):
            assert (await watcher.command("r1", command))["ok"]
        controller = robot.port.robot.controller
        robot.link.silent.set()  # the controller resets: silent while it boots
        controller.reset()
        event = await watcher.wait_for("rovlink/r1/events", lambda e: "#stop!" in e["detail"])
        assert event["event"] == "reset_suspected"
        assert robot.bridge.rov.commanded.lock_text() == "locked (as last sent)"
        robot.link.silent.clear()
        event = await watcher.wait_for("rovlink/r1/events", lambda e: "sent again" in e["detail"])
        assert event["detail"].endswith("sent again #mgmp.100! #mvdirect.1!")
        state = controller.state()
        assert (state.max_pwm, state.vertical_mode.value) == (100, "direct")
        assert (await watcher.command("r1", "start"))["ok"]
        assert "warning" not in await watcher.command("r1", "mvs 60")
        await until(lambda: controller.state().vertical_thrust_percent == 60)


async def test_two_bridges_with_one_robot_id_are_named_and_do_not_flap_at_full_speed(
    broker: Mosquitto, caplog: pytest.LogCaptureFixture
):
    # The broker gives a client id to its newest connection; each bridge took it back within
    # 0.2 s, for ever (the retained state flipped online and offline five times a second), and
    # the log said only "Disconnected during message iteration".
    caplog.set_level(logging.WARNING, logger="rovlink.bridges.mqtt")
    async with bridged_robot(broker, "twin"), bridged_robot(broker, "twin"):
        await until(lambda: "is a second bridge running with --robot twin?" in caplog.text)
        waits = [
            float(record.getMessage().rsplit("retrying in ", 1)[1].split()[0])
            for record in caplog.records
            if "retrying in" in record.getMessage()
        ]
        assert max(waits) >= 0.8  # backing off, not back at 0.2 s after every connection


async def test_a_broker_that_restarts_again_and_again_is_not_taken_for_a_second_bridge(
    broker: Mosquitto, caplog: pytest.LogCaptureFixture
):
    # A broker that restarts a few times within seconds (crash-looping under systemd) ended
    # three connections "soon after they began": the bridge said a second bridge might be
    # running, and said it again at every attempt while the broker stayed down. A connection
    # refused is no other bridge taking the client id over.
    caplog.set_level(logging.WARNING, logger="rovlink.bridges.mqtt")

    def refusals() -> int:
        return caplog.text.count("cannot connect: connection refused")

    def more_refusals_than(count: int) -> Callable[[], bool]:
        return lambda: refusals() > count

    async with bridged_robot(broker, "flaky") as robot:
        for restart in range(3):
            await until(robot.bridge.connected.is_set)
            refused_before = refusals()
            broker.stop()
            await until(more_refusals_than(refused_before))  # (the broker is down)
            if restart < 2:
                broker.start()
        assert "second bridge" not in caplog.text


def test_a_session_taken_over_is_told_by_the_brokers_reason():
    # Brokers that say why they end a connection (MQTT 5 reason 0x8E) end the replaced bridge.
    from aiomqtt import MqttCodeError
    from paho.mqtt.reasoncodes import ReasonCode

    loop = asyncio.new_event_loop()
    try:

        def ended_with(code: int | None) -> object:
            disconnected: asyncio.Future[None] = loop.create_future()
            if code is not None:
                reason = ReasonCode(PacketTypes.DISCONNECT, identifier=code)
                disconnected.set_exception(MqttCodeError(reason, "Unexpected disconnection"))
            return type("Client", (), {"_disconnected": disconnected})()

        assert _taken_over(ended_with(0x8E))
        assert not _taken_over(ended_with(0x80))  # unspecified (mosquitto 2.0.11 says nothing)
        assert not _taken_over(ended_with(None))
        assert not _taken_over(object())
    finally:
        loop.close()


async def test_a_stop_is_not_held_up_by_a_query_the_controller_does_not_answer(broker: Mosquitto):
    # Commands were carried out one at a time: a stop published after a query waited for that
    # query's reply (a reply timeout and retries, when the controller does not answer) before
    # #stop! was written. The controller's answers are held back until the stop has been
    # answered, with a reply timeout longer than the test waits: a stop queued behind the query
    # is never answered in time, however fast the machine.
    async with (
        bridged_robot(broker, "h1", timeout_s=CONDITION_TIMEOUT_S) as robot,
        subscriber(broker, "rovlink/h1/cmd/reply") as watcher,
    ):
        assert (await watcher.command("h1", "start"))["ok"]
        robot.link.held.set()  # the controller does not answer until released
        before = len(robot.motion_and_lock_frames())
        for text in ("qd", "th 90 30", "mgmp 100", "start", "stop"):
            await watcher.client.publish("rovlink/h1/cmd", text, qos=1)
        # The stop first, while the query still waits; the motion and the unlock that came
        # before it are not sent.
        await until(lambda: len(watcher.on("rovlink/h1/cmd/reply")) == 4)
        replies = watcher.on("rovlink/h1/cmd/reply")[1:]
        assert [(r["command"], r["ok"]) for r in replies] == [
            ("stop", True),
            ("th 90 30", False),
            ("start", False),
        ]
        assert "a stop published after it" in replies[1]["error"]
        assert robot.motion_and_lock_frames()[before:] == ["#stop!"]
        robot.link.held.clear()  # the query is answered; then the setting, in their order
        await until(lambda: len(watcher.on("rovlink/h1/cmd/reply")) == 6)
        replies = watcher.on("rovlink/h1/cmd/reply")[4:]
        assert [(r["command"], r["ok"]) for r in replies] == [("qd", True), ("mgmp 100", True)]
        sent = robot.motion_and_lock_frames()[before:]
        assert sent[:2] == ["#stop!", "#mgmp.100!"]
        assert not [frame for frame in sent if frame.startswith(("#th", "#start"))]


async def test_losing_the_broker_zeroes_the_thrust_even_without_a_motion_timeout(
    broker: Mosquitto,
):
    # With --motion-timeout 0 the robot drove on for as long as the broker was away, though no
    # stop could reach it any more.
    async with bridged_robot(broker, "z1", motion_timeout_s=None) as robot:
        # A persistent session (kept through the broker's restart): the event waits for it.
        async with (
            subscriber(broker, "rovlink/z1/events", identifier="w", clean=False),
            subscriber(broker, "rovlink/z1/cmd/reply") as watcher,
        ):
            for command in ("mvdirect 1", "start", "th 90 30", "mvs 40"):
                assert (await watcher.command("z1", command))["ok"]
        controller = robot.port.robot.controller
        await until(lambda: controller.state().vertical_thrust_percent == 40)
        moving = len(robot.frames())
        broker.stop()
        await until(lambda: {"#th.90.0!", "#mvs.+0!"} <= set(robot.frames()[moving:]))
        await until(lambda: controller.state().power_percent == 0)
        await until(lambda: controller.state().vertical_thrust_percent == 0)
        assert "#stop!" not in robot.frames()[moving:]  # unlocked still: a depth held stays
        broker.start()
        async with subscriber(broker, "rovlink/z1/events", identifier="w", clean=False) as events:
            failsafe = await events.wait_for("rovlink/z1/events", lambda e: "broker" in e["detail"])
        assert failsafe["event"] == "failsafe"


async def test_a_broker_disconnect_that_never_ends_does_not_hold_back_the_final_stop(
    broker: Mosquitto, monkeypatch: pytest.MonkeyPatch
):
    # aiomqtt waits for the broker's side of a disconnect without a bound: a bridge ending
    # behind it never sent its #stop!.
    monkeypatch.setattr("rovlink.bridges.mqtt.bridge._END_WAIT_S", 0.3)
    real_exit = aiomqtt.Client.__aexit__
    let_go = asyncio.Event()

    async def disconnect_that_hangs(self: aiomqtt.Client, *exc_info: object) -> None:
        await let_go.wait()
        await real_exit(self, *exc_info)  # type: ignore[arg-type]

    monkeypatch.setattr(aiomqtt.Client, "__aexit__", disconnect_that_hangs)
    try:
        async with bridged_robot(broker, "h1") as robot:
            stops_before = robot.frames().count("#stop!")
        assert robot.task.done()
        # The one as it began to end, and the final one, after its tasks.
        assert robot.frames().count("#stop!") == stops_before + 2
    finally:
        let_go.set()  # (the connection left behind closes before the loop does)
        await asyncio.sleep(0.1)


async def test_an_ending_bridge_stops_the_robot_before_saying_goodbye_to_a_stalled_broker(
    broker: Mosquitto, monkeypatch: pytest.MonkeyPatch
):
    # The final #stop! came only once the offline state had been published or given up (2 s
    # with a stalled broker): after Ctrl-C a robot without a motion timeout drove on meanwhile.
    # The goodbye waits for the broker as long as it is stalled.
    monkeypatch.setattr("rovlink.bridges.mqtt.bridge._FAREWELL_S", 60.0)
    monkeypatch.setattr("rovlink.bridges.mqtt.bridge._END_WAIT_S", 60.0)
    async with (
        bridged_robot(broker, "e1", motion_timeout_s=None, reply_timeout_s=60.0) as robot,
        subscriber(broker, "rovlink/e1/cmd/reply", "rovlink/e1/state") as watcher,
    ):
        for command in ("start", "th 90 100"):
            assert (await watcher.command("e1", command))["ok"]
        controller = robot.port.robot.controller
        await until(lambda: controller.state().power_percent == 100)
        with broker.stalled():
            robot.task.cancel()
            await until(lambda: controller.state().locked and controller.state().power_percent == 0)
            assert not robot.task.done()  # still saying goodbye, to a broker that answers nothing
        await asyncio.wait({robot.task}, timeout=CONDITION_TIMEOUT_S)
        assert robot.task.done()
        offline = await watcher.wait_for("rovlink/e1/state", lambda s: not s["online"])
        assert offline["reason"] == "bridge stopped"


async def test_a_bridge_ends_though_a_publish_swallows_its_cancellation(
    broker: Mosquitto, monkeypatch: pytest.MonkeyPatch
):
    # On Python 3.10, asyncio.wait_for (aiomqtt's, waiting for a PUBACK) swallows a cancellation
    # that comes as the PUBACK does (bpo-37658): the publishing task ran on and the bridge, waiting
    # for it, never ended. Here a publish in flight swallows the first cancellation, on any Python.
    real_publish = aiomqtt.Client.publish
    hold = asyncio.Event()
    in_flight = asyncio.Event()

    async def publish_swallowing_a_cancellation(self: Any, *args: Any, **kwargs: Any) -> None:
        if not hold.is_set():
            return await real_publish(self, *args, **kwargs)
        hold.clear()  # (only this one)
        in_flight.set()
        with contextlib.suppress(asyncio.CancelledError):  # the acknowledgement came with it
            await asyncio.Event().wait()

    monkeypatch.setattr(aiomqtt.Client, "publish", publish_swallowing_a_cancellation)
    async with (
        subscriber(broker, "rovlink/w1/state") as watcher,
        bridged_robot(broker, "w1") as robot,
    ):
        await watcher.wait_for("rovlink/w1/state", lambda s: s["online"])
        hold.set()
        await asyncio.wait_for(in_flight.wait(), CONDITION_TIMEOUT_S)
        robot.task.cancel()
        await asyncio.wait({robot.task}, timeout=CONDITION_TIMEOUT_S)
        assert robot.task.done()
        offline = await watcher.wait_for("rovlink/w1/state", lambda s: not s["online"])
        assert offline["reason"] == "bridge stopped"
