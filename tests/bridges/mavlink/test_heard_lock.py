"""The MAVLink bridge on a simulated controller's TCP port hears a stop sent on its PTY (debug
output on): the ground station sees the vehicle disarmed, and its next ARM unlocks it again."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest

import rovlink
import rovlink.aio
from rovlink.bridges.mavlink.bridge import MavlinkBridge
from rovlink.bridges.mavlink.endpoint import MavlinkEndpoint
from rovlink.client.events import LinkState
from rovlink.piloting.tracked import SentFrame, TrackedClient
from rovlink.protocol import Command
from rovlink.protocol.announcements import STOP_COMMAND, Announcement, AnnouncementKind
from rovlink.sim.server import SimServer
from tests.bridges.mavlink.rig import CONDITION_TIMEOUT_S, GroundStation, free_udp_port, wait_for
from tests.sim.conftest import StartServer, start_server  # noqa: F401 - the fixture

pytestmark = pytest.mark.integration

SUBMARINE = 12
ARMED_FLAG = 128
ACCEPTED = 0


@contextmanager
def _bridge_on(url: str, gcs_port: int) -> Iterator[MavlinkBridge]:
    """``rovlink mavlink URL`` in a thread of its own, sending to ``gcs_port``."""
    holder: dict[str, Any] = {}
    ready = threading.Event()

    async def serve() -> None:
        async with rovlink.aio.connect(url, timeout=1.0, motion_timeout=None) as client:
            bridge = MavlinkBridge(
                TrackedClient(client), MavlinkEndpoint(f"udpout:127.0.0.1:{gcs_port}")
            )
            holder["bridge"], holder["loop"] = bridge, asyncio.get_running_loop()
            holder["task"] = task = asyncio.ensure_future(bridge.run())
            ready.set()
            await asyncio.gather(task, return_exceptions=True)

    thread = threading.Thread(target=asyncio.run, args=(serve(),), daemon=True)
    thread.start()
    assert ready.wait(CONDITION_TIMEOUT_S), "the bridge did not start"
    try:
        yield holder["bridge"]
    finally:
        holder["loop"].call_soon_threadsafe(holder["task"].cancel)
        thread.join(timeout=CONDITION_TIMEOUT_S)


def _tcp_url(server: SimServer) -> str:
    assert server.tcp_address is not None
    host, port = server.tcp_address
    return f"socket://{host}:{port}"


def _disarmed_submarine(heartbeat: Any) -> bool:
    return heartbeat.type == SUBMARINE and not heartbeat.base_mode & ARMED_FLAG


def test_a_stop_from_another_line_disarms_the_vehicle_and_arm_starts_it_again(
    start_server: StartServer,  # noqa: F811 - the fixture
) -> None:
    # Before, the ground station went on showing the vehicle ARMED after another tool's
    # #stop!, and its ARM sent nothing: the pilot had to DISARM, then ARM.
    server = start_server()
    controller = server.robot.controller
    assert server.pty_path is not None
    gcs_port = free_udp_port()
    with (
        rovlink.connect(server.pty_path, timeout=1.0, keepalive=None) as bystander,
        _bridge_on(_tcp_url(server), gcs_port) as bridge,
    ):
        gcs = GroundStation(f"udpin:127.0.0.1:{gcs_port}")
        try:
            gcs.receive("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
            gcs.start_heartbeats()
            bystander.set_debug(True)  # (any line may: it is the controller's)
            assert gcs.arm() == ACCEPTED
            wait_for(lambda: bridge.armed and not controller.locked, CONDITION_TIMEOUT_S)
            bystander.stop()
            # The next HEARTBEAT (1 Hz) after the bridge heard it says DISARMED.
            gcs.receive_new("HEARTBEAT", condition=_disarmed_submarine)
            said = gcs.receive("STATUSTEXT", condition=lambda m: "Disarmed" in m.text)
            assert "stopped by another line" in said.text
            assert controller.locked  # nothing heard was sent: no #start! of its own
            assert gcs.arm() == ACCEPTED  # sends #start! again (before: armed, nothing sent)
            wait_for(lambda: not controller.locked, CONDITION_TIMEOUT_S)
            assert bridge.armed
        finally:
            gcs.close()


async def test_an_armed_bridge_that_heard_a_stop_still_stops_the_robot_when_its_link_drops() -> (
    None
):
    # Before, a stop heard disarmed the bridge, and losing the link then queued no #stop!: with
    # --hear-other-lines the bridge sent less than without (another line may have unlocked the
    # robot since), where every other tool goes by the lock it sent itself (sent_lock).
    async with rovlink.aio.connect("sim://", timeout=1.0, motion_timeout=None) as client:
        rov = TrackedClient(client)
        bridge = MavlinkBridge(rov, MavlinkEndpoint(f"udpout:127.0.0.1:{free_udp_port()}"))
        try:
            await rov.send(Command("start"))  # armed, as after the ground station's ARM
            rov.commanded.hear(Announcement(AnnouncementKind.LOCKED, STOP_COMMAND))
            assert not bridge.armed
            stops: list[SentFrame] = []
            rov.add_sent_listener(
                lambda sent: stops.append(sent) if sent.text == "#stop!" else None
            )
            bridge._on_client_event(LinkState(0.0, "lost", "test"))
            await asyncio.wait_for(asyncio.gather(*bridge._background), CONDITION_TIMEOUT_S)
            assert [sent.text for sent in stops] == ["#stop!"]
        finally:
            bridge.endpoint.close()
