"""A bridge without --allow-commands is the deck's telemetry: it never stops, on its own, a
robot that another tool flies (its start, its end, a suspected reset); a published ``stop``
still stops it."""

from __future__ import annotations

import asyncio

import pytest

import rovlink.aio
from rovlink.bridges.mqtt.bridge import MqttBridge
from rovlink.bridges.mqtt.broker import BrokerSettings
from rovlink.piloting.tracked import TrackedClient
from tests.bridges.mqtt.broker import Mosquitto
from tests.bridges.mqtt.rig import bridged_robot, subscriber, until
from tests.sim.conftest import StartServer, start_server  # noqa: F401 - the fixture

pytestmark = pytest.mark.integration


async def test_a_telemetry_bridge_starting_and_ending_leaves_the_pilots_robot_flying(
    broker: Mosquitto,
    start_server: StartServer,  # noqa: F811 - the fixture
) -> None:
    # Before, the deck's bridge sent #stop! as it started and as it ended: restarting the
    # telemetry (a service restarted, a broker setting changed) stopped the robot the pilot
    # was flying on the other line.
    server = start_server()
    assert server.tcp_address is not None
    assert server.pty_path is not None
    host, port = server.tcp_address
    controller = server.robot.controller
    async with (
        rovlink.aio.connect(f"socket://{host}:{port}", timeout=1.0) as pilot,
        rovlink.aio.connect(server.pty_path, timeout=1.0) as deck_line,
        subscriber(broker, "rovlink/t1/state", "rovlink/t1/cmd/reply") as deck,
    ):
        await pilot.start()
        await pilot.move(90, 30)
        await until(lambda: controller.state().power_percent == 30)
        bridge = MqttBridge(
            TrackedClient(deck_line), BrokerSettings("127.0.0.1", broker.port), "t1"
        )
        task = asyncio.ensure_future(bridge.run())
        try:
            state = await deck.wait_for("rovlink/t1/state", lambda s: s["depth_cm"] is not None)
            assert state["lock"] == "unknown"  # (it sent no start or stop: it cannot tell)
        finally:
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)
        await deck.wait_for("rovlink/t1/state", lambda s: s["online"] is False)
        state = controller.state()
        assert state.power_percent == 30
        assert state.locked is False


async def test_a_telemetry_bridge_sends_no_stop_of_its_own_after_a_suspected_reset(
    broker: Mosquitto,
) -> None:
    # A suspicion is no proof: a controller slow to answer while another tool flies it would
    # have been stopped by the deck's telemetry.
    async with (
        bridged_robot(broker, "t2", allow_commands=False, timeout_s=0.5) as robot,
        subscriber(broker, "rovlink/t2/events", "rovlink/t2/cmd/reply") as watcher,
    ):
        robot.link.silent.set()
        event = await watcher.wait_for("rovlink/t2/events", lambda e: e["event"] != "link")
        assert event["event"] == "reset_suspected"
        assert "#stop!" not in event["detail"]
        robot.link.silent.clear()
        assert "#stop!" not in robot.frames()
        reply = await watcher.command("t2", "stop")  # a published stop is carried out
        assert (reply["ok"], reply["frame"]) == (True, "#stop!")
    assert robot.motion_and_lock_frames() == ["#stop!"]
