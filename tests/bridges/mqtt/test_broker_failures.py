"""What the bridge says when it cannot reach the broker or loses it: what happened, in words,
naming the broker (not the system's ``[Errno 111]``), then that it retries."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

import pytest

from rovlink.aio import AsyncClient
from rovlink.bridges.mqtt.bridge import MqttBridge
from rovlink.bridges.mqtt.broker import BrokerSettings
from rovlink.client import ClientOptions
from rovlink.client.links import PortLink
from rovlink.piloting.tracked import TrackedClient
from rovlink.sim import SimulatedPort
from tests.bridges.mqtt.broker import Mosquitto, free_tcp_port
from tests.bridges.mqtt.rig import until

pytestmark = pytest.mark.integration


@asynccontextmanager
async def _bridge(settings: BrokerSettings) -> AsyncIterator[MqttBridge]:
    port = SimulatedPort(seed=1)
    port.start(realtime=True)
    options = ClientOptions(keepalive_s=1.0, timeout_s=2.0, boot_timeout_s=None)
    client = await AsyncClient(PortLink(port, "simulated"), options).open()
    bridge = MqttBridge(TrackedClient(client), settings, "rov-1", reply_timeout_s=2.0)
    task = asyncio.ensure_future(bridge.run())
    try:
        yield bridge
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        await client.close()
        port.close()


def _retry_warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if "retrying in" in r.getMessage()]


async def _first_retry_warning(settings: BrokerSettings, caplog: pytest.LogCaptureFixture) -> str:
    caplog.set_level("WARNING", logger="rovlink.bridges.mqtt")
    async with _bridge(settings):
        await until(lambda: bool(_retry_warnings(caplog)))
    return _retry_warnings(caplog)[0]


def _said_plainly(warning: str) -> None:
    assert "Errno" not in warning
    assert "[code:" not in warning


async def test_a_port_nobody_listens_on_is_a_connection_refused(
    caplog: pytest.LogCaptureFixture,
):
    # Regression: "broker mqtt://127.0.0.1:PORT: [Errno 111] Connection refused; retrying".
    port = free_tcp_port()
    warning = await _first_retry_warning(BrokerSettings("127.0.0.1", port), caplog)
    assert warning.startswith(
        f"broker mqtt://127.0.0.1:{port}: cannot connect: connection refused (is the broker "
        f"running, and listening on port {port}?); retrying in "
    )
    _said_plainly(warning)


async def test_a_broker_that_stays_away_is_not_a_warning_at_every_attempt(
    caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
):
    # A warning at each attempt: one line every 5 s for as long as the broker is away (720 an
    # hour, all day if the deck's broker is off), burying everything else in the log.
    monkeypatch.setattr("rovlink.bridges.mqtt.bridge._RECONNECT_MAX_S", 0.01)
    monkeypatch.setattr("rovlink.bridges.mqtt.bridge._RECONNECT_FIRST_S", 0.01)
    caplog.set_level("DEBUG", logger="rovlink.bridges.mqtt")
    async with _bridge(BrokerSettings("127.0.0.1", free_tcp_port())):
        await until(lambda: len(_retry_warnings(caplog)) >= 20)  # (attempts, said or not)
    warnings = [r for r in caplog.records if r.levelname == "WARNING"]
    assert len(warnings) == 1, [r.getMessage() for r in warnings]
    assert "cannot connect: connection refused" in warnings[0].getMessage()


async def test_a_host_name_that_does_not_resolve_is_said_so(caplog: pytest.LogCaptureFixture):
    # Regression: "[Errno -2] Name or service not known".
    warning = await _first_retry_warning(BrokerSettings("nonexistent.invalid", 1883), caplog)
    assert warning.startswith(
        "broker mqtt://nonexistent.invalid:1883: cannot connect: name not resolved: the host "
        "'nonexistent.invalid' is unknown ("
    )
    _said_plainly(warning)


async def test_tls_to_a_plain_listener_is_a_tls_failure(
    broker: Mosquitto, caplog: pytest.LogCaptureFixture
):
    # Regression: "[Errno 104] Connection reset by peer".
    settings = BrokerSettings("127.0.0.1", broker.port, tls=True)
    warning = await _first_retry_warning(settings, caplog)
    assert warning.startswith(f"broker mqtts://127.0.0.1:{broker.port}: cannot connect: TLS ")
    assert f"is port {broker.port} a TLS listener?" in warning
    _said_plainly(warning)


async def test_a_broker_that_shuts_down_is_a_connection_lost(
    broker: Mosquitto, caplog: pytest.LogCaptureFixture
):
    # Regression: "Disconnected during message iteration", which says nothing of why.
    caplog.set_level("WARNING", logger="rovlink.bridges.mqtt")
    async with _bridge(BrokerSettings("127.0.0.1", broker.port)) as bridge:
        await until(bridge.connected.is_set)
        broker.stop()
        await until(lambda: bool(_retry_warnings(caplog)))
    warning = _retry_warnings(caplog)[0]
    assert warning.startswith(f"broker mqtt://127.0.0.1:{broker.port}: connection lost: ")
    assert "the connection was closed" in warning
    assert "Disconnected during message iteration" not in warning
    _said_plainly(warning)
