"""MQTT bridges on simulated robots in the test's event loop, and a subscriber."""

from __future__ import annotations

import asyncio
import contextlib
import json
import threading
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from typing import Any, Protocol

import aiomqtt

from rovlink.aio import AsyncClient
from rovlink.bridges.mqtt.bridge import REPLY_TIMEOUT_S, MqttBridge
from rovlink.bridges.mqtt.broker import BrokerSettings
from rovlink.bridges.mqtt.command_age import DEFAULT_MAX_COMMAND_AGE_S
from rovlink.bridges.mqtt.outbox import DEFAULT_CAPACITY
from rovlink.client import ClientOptions
from rovlink.client.links import Link, PortLink
from rovlink.piloting.tracked import TrackedClient
from rovlink.sim import SimConfig, SimulatedPort
from tests.bridges.mqtt.broker import Mosquitto
from tests.piloting.rig import SilenceableLink

CONDITION_TIMEOUT_S = 15.0
_DISCONNECT_WAIT_S = 5.0


class BrokerAddress(Protocol):
    """Where a broker listens on the loopback: a mosquitto, or a fake one."""

    @property
    def port(self) -> int: ...


class HoldingLink(SilenceableLink):
    """A link whose controller's answers can also be held back (``held.set()``) until the test
    releases them (``held.clear()``): a query then waits exactly as long as the test says,
    however fast or slow the machine is."""

    def __init__(self, inner: Link) -> None:
        super().__init__(inner)
        self.held = threading.Event()
        self._kept = b""  # (read by the client's one reader only)

    def read_available(self, timeout_s: float) -> bytes:
        data = super().read_available(timeout_s)
        if self.held.is_set():
            self._kept += data
            return b""
        data, self._kept = self._kept + data, b""
        return data


@dataclass
class BridgedRobot:
    robot_id: str
    port: SimulatedPort
    link: HoldingLink
    bridge: MqttBridge
    task: asyncio.Future[None]

    def frames(self) -> list[str]:
        return self.link.frames()

    def motion_and_lock_frames(self) -> list[str]:
        """The frames a command could have caused (not the polls and keep-alives)."""
        return [f for f in self.frames() if not f.startswith(("#q", "#crc"))]


@asynccontextmanager
async def bridged_robot(
    broker: BrokerAddress,
    robot_id: str,
    *,
    allow_commands: bool = True,
    rate_hz: float = 10.0,
    motion_timeout_s: float | None = None,
    leak_at_s: float | None = None,
    timeout_s: float = 2.0,
    reply_timeout_s: float = REPLY_TIMEOUT_S,
    max_command_age_s: float = DEFAULT_MAX_COMMAND_AGE_S,
    max_kept_events: int = DEFAULT_CAPACITY,
    wait_connected: bool = True,
    replies_held: bool = False,
) -> AsyncIterator[BridgedRobot]:
    """A bridge for a simulated robot (once connected to ``broker``, unless not
    ``wait_connected``; with ``replies_held``, the controller's replies held back from the
    start until the test clears ``robot.link.held``); cancelled on leaving."""
    port = SimulatedPort(SimConfig(), seed=1)
    if leak_at_s is not None:
        port.robot.inject_leak(at_s=leak_at_s)
    port.start(realtime=True)
    link = HoldingLink(PortLink(port, f"simulated {robot_id}"))
    if replies_held:
        link.held.set()
    options = ClientOptions(
        keepalive_s=1.0, timeout_s=timeout_s, boot_timeout_s=None, motion_timeout_s=motion_timeout_s
    )
    client = await AsyncClient(link, options).open()
    bridge = MqttBridge(
        TrackedClient(client),
        BrokerSettings("127.0.0.1", broker.port),
        robot_id,
        rate_hz=rate_hz,
        allow_commands=allow_commands,
        reply_timeout_s=reply_timeout_s,
        max_command_age_s=max_command_age_s,
        max_kept_events=max_kept_events,
    )
    task = asyncio.ensure_future(bridge.run())
    robot = BridgedRobot(robot_id, port, link, bridge, task)
    try:
        if wait_connected:
            await until(bridge.connected.is_set)
        yield robot
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        await client.close()
        port.close()


async def until(predicate: Callable[[], bool], timeout_s: float = CONDITION_TIMEOUT_S) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while not predicate():
        if loop.time() > deadline:
            raise AssertionError(f"condition not met within {timeout_s} s")
        await asyncio.sleep(0.01)


@dataclass
class Subscriber:
    """Collects every message on its topics, in order, as (topic, JSON)."""

    client: aiomqtt.Client
    received: list[tuple[str, Any]] = field(default_factory=list)

    def on(self, topic: str) -> list[Any]:
        return [payload for name, payload in self.received if name == topic]

    async def wait_for(self, topic: str, condition: Callable[[Any], bool] = lambda _: True) -> Any:
        await until(lambda: any(condition(p) for p in self.on(topic)))
        return next(p for p in self.on(topic) if condition(p))

    async def command(self, robot_id: str, payload: bytes | str) -> Any:
        """Publish a command; the reply that answers it (the next on cmd/reply)."""
        reply_topic = f"rovlink/{robot_id}/cmd/reply"
        before = len(self.on(reply_topic))
        await self.client.publish(f"rovlink/{robot_id}/cmd", payload, qos=1)
        await until(lambda: len(self.on(reply_topic)) > before)
        return self.on(reply_topic)[before]


@asynccontextmanager
async def subscriber(
    broker: Mosquitto, *topics: str, identifier: str | None = None, clean: bool = True
) -> AsyncIterator[Subscriber]:
    client = aiomqtt.Client("127.0.0.1", broker.port, identifier=identifier, clean_session=clean)
    await client.__aenter__()
    try:
        collected = Subscriber(client)
        for topic in topics:
            await client.subscribe(topic, qos=1)

        async def collect() -> None:
            async for message in client.messages:
                payload = message.payload
                assert isinstance(payload, bytes)
                collected.received.append((message.topic.value, json.loads(payload)))

        task = asyncio.ensure_future(collect())
        try:
            yield collected
        finally:
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)
    finally:
        # aiomqtt waits for the broker's side of the disconnect without a bound; what the test
        # checks is done by now, so a disconnect the broker does not finish only ends the wait.
        with contextlib.suppress(TimeoutError, asyncio.TimeoutError, aiomqtt.MqttError):
            await asyncio.wait_for(client.__aexit__(None, None, None), _DISCONNECT_WAIT_S)
