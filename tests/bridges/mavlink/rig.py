"""A MAVLink bridge on a real-time simulated robot, in its own thread and event loop, with a
recording link (the frames on the wire) and a pymavlink ground station on a real UDP socket."""

from __future__ import annotations

import asyncio
import os
import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from rovlink.aio import AsyncClient
from rovlink.bridges.mavlink.bridge import MavlinkBridge
from rovlink.bridges.mavlink.endpoint import MavlinkEndpoint
from rovlink.bridges.mavlink.parameters import ParameterTable
from rovlink.client import ClientOptions
from rovlink.client.links import PortLink
from rovlink.controller import ControllerConfig
from rovlink.piloting.tracked import TrackedClient
from rovlink.sim import SimConfig, SimulatedPort
from tests.piloting.rig import SilenceableLink

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil

#: How long a test waits for something that is bound to happen (only a failing test waits it out).
CONDITION_TIMEOUT_S = 10.0
GCS_TYPE = 6  # MAV_TYPE_GCS
VEHICLE = 1
_BACKLOG = 500  # messages kept for a later receive()


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def free_tcp_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def wait_for(predicate: Callable[[], bool], timeout_s: float = CONDITION_TIMEOUT_S) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"condition not met within {timeout_s} s")
        time.sleep(0.01)


class GroundStation:
    """pymavlink as a ground station: sends under a lock (a heartbeat thread shares it)."""

    def __init__(self, address: str, system: int = 255) -> None:
        self.connection: Any = mavutil.mavlink_connection(
            address, source_system=system, source_component=190, dialect="ardupilotmega"
        )
        self._lock = threading.Lock()
        self._backlog: list[Any] = []
        self._beating = threading.Event()
        self._beat_thread: threading.Thread | None = None
        #: When the last heartbeat was sent (taken just before: the bridge has it later).
        self.last_heartbeat_s: float | None = None

    def send(self, name: str, *fields: Any) -> None:
        with self._lock:
            getattr(self.connection.mav, f"{name}_send")(*fields)

    def heartbeat(self) -> None:
        with self._lock:
            self.last_heartbeat_s = time.monotonic()
            self.connection.mav.heartbeat_send(GCS_TYPE, 8, 0, 0, 0)

    def start_heartbeats(self, period_s: float = 0.5) -> None:
        """A ground station's 1 Hz heartbeat (faster, to be well inside the 3 s)."""
        self._beating.set()

        def beat() -> None:
            while self._beating.is_set():
                self.heartbeat()
                time.sleep(period_s)

        self._beat_thread = threading.Thread(target=beat, daemon=True)
        self._beat_thread.start()

    def stop_heartbeats(self) -> None:
        self._beating.clear()
        if self._beat_thread is not None:
            self._beat_thread.join(timeout=5)

    def receive(
        self,
        kind: str | list[str],
        timeout_s: float = CONDITION_TIMEOUT_S,
        condition: Callable[[Any], bool] | None = None,
    ) -> Any:
        """The first message of ``kind`` (meeting ``condition``), received or kept from before:
        messages that another call skipped are kept, not dropped as pymavlink's filter would."""
        kinds = [kind] if isinstance(kind, str) else kind

        def wanted(message: Any) -> bool:
            return message.get_type() in kinds and (condition is None or condition(message))

        for index, kept in enumerate(self._backlog):
            if wanted(kept):
                del self._backlog[index]
                return kept
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            message = self.connection.recv_match(
                blocking=True, timeout=max(deadline - time.monotonic(), 0.01)
            )
            if message is None or message.get_type() == "BAD_DATA":
                continue
            if wanted(message):
                return message
            self._backlog.append(message)
            del self._backlog[:-_BACKLOG]
        raise AssertionError(f"no {kind} within {timeout_s} s")

    def kept(self, kind: str) -> list[Any]:
        """The messages of ``kind`` received so far that no receive() took."""
        return [kept for kept in self._backlog if kept.get_type() == kind]

    def forget_kept(self) -> None:
        """Drop every message kept so far (received earlier, taken by no receive())."""
        self._backlog.clear()

    def receive_new(self, kind: str, condition: Callable[[Any], bool] | None = None) -> Any:
        """The next message of ``kind`` received from now on (none kept from before)."""
        self._backlog = [kept for kept in self._backlog if kept.get_type() != kind]
        return self.receive(kind, condition=condition)

    def command(self, command: int, *params: float) -> int:
        """COMMAND_LONG; the result of its COMMAND_ACK."""
        padded = [*params, *[0.0] * (7 - len(params))]
        self.send("command_long", VEHICLE, 1, command, 0, *padded)
        ack = self.receive("COMMAND_ACK", condition=lambda m: m.command == command)
        return int(ack.result)

    def arm(self) -> int:
        return self.command(400, 1)

    def set_mode(self, custom_mode: int) -> int:
        return self.command(176, 1, custom_mode)

    def close(self) -> None:
        self.stop_heartbeats()
        self.connection.close()


@dataclass
class BridgeRig:
    port: SimulatedPort
    link: SilenceableLink
    bridge: MavlinkBridge
    gcs_address: str

    def frames(self) -> list[str]:
        return self.link.frames()

    def frames_since(self, mark: int) -> list[str]:
        return self.link.frames()[mark:]

    def wait_frame(
        self, frame: str, since: int = 0, timeout_s: float = CONDITION_TIMEOUT_S
    ) -> None:
        wait_for(lambda: frame in self.frames_since(since), timeout_s)


@contextmanager
def running_bridge(
    *,
    leak_at_s: float | None = None,
    endpoint: str | None = None,
    send_on_start: tuple[str, ...] = (),
    timeout_s: float = 2.0,
) -> Iterator[BridgeRig]:
    """A bridge sending to a free UDP port (``rig.gcs_address`` is where a GCS listens)."""
    gcs_port = free_udp_port()
    out = endpoint or f"udpout:127.0.0.1:{gcs_port}"
    port = SimulatedPort(SimConfig(controller=ControllerConfig()), seed=1)
    if leak_at_s is not None:
        port.robot.inject_leak(at_s=leak_at_s)
    port.start(realtime=True)
    link = SilenceableLink(PortLink(port, "simulated controller"))
    ready = threading.Event()
    holder: dict[str, Any] = {}

    async def serve() -> None:
        # No driver motion timeout, as ``rovlink mavlink``: the bridge expires motion itself (P23),
        # and a test must see the bridge's zero thrust, not the driver's.
        options = ClientOptions(
            keepalive_s=1.0, timeout_s=timeout_s, boot_timeout_s=None, motion_timeout_s=None
        )
        client = await AsyncClient(link, options).open()
        bridge = MavlinkBridge(TrackedClient(client), MavlinkEndpoint(out), ParameterTable(
            {"RL_DEPTH_P": 40, "RL_DEPTH_I": 30, "RL_DEPTH_D": 20, "RL_MAX_PWM": 255,
             "RL_DEPTH_ZERO": 20, "RL_DEPTH_K": 200}
        ), send_on_start=send_on_start)  # fmt: skip
        holder["bridge"] = bridge
        holder["loop"] = asyncio.get_running_loop()
        task = asyncio.ensure_future(bridge.run())
        holder["task"] = task
        ready.set()
        try:
            await task
        except asyncio.CancelledError:
            pass
        finally:
            await client.close()

    def thread_main() -> None:
        try:
            asyncio.run(serve())
        except BaseException as error:
            holder["error"] = error
            ready.set()

    thread = threading.Thread(target=thread_main, daemon=True)
    thread.start()
    assert ready.wait(CONDITION_TIMEOUT_S), "the bridge did not start"
    if "error" in holder:
        raise holder["error"]
    rig = BridgeRig(port, link, holder["bridge"], f"udpin:127.0.0.1:{gcs_port}")
    try:
        yield rig
    finally:
        loop: asyncio.AbstractEventLoop = holder["loop"]
        if not loop.is_closed():
            loop.call_soon_threadsafe(holder["task"].cancel)
        thread.join(timeout=10)
        port.close()
