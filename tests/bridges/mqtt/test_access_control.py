"""A broker whose access control refuses the bridge something: what it refuses is logged, by
topic and reason, instead of lost without a word (the robot looked online to its bridge)."""

from __future__ import annotations

import glob
import json
from collections.abc import Iterator
from pathlib import Path

import aiomqtt
import pytest
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from tests.bridges.mqtt.broker import Mosquitto, mosquitto_available
from tests.bridges.mqtt.rig import bridged_robot, subscriber, until

pytestmark = pytest.mark.integration


def _broker(tmp_path: Path, listener_options: str) -> Iterator[Mosquitto]:
    if not mosquitto_available():
        pytest.skip("needs mosquitto (Debian package mosquitto)")
    broker = Mosquitto(tmp_path, listener_options="allow_anonymous true\n" + listener_options)
    broker.start()
    try:
        yield broker
    finally:
        broker.stop()


@pytest.fixture
def acl_broker(tmp_path: Path) -> Iterator[Mosquitto]:
    """Anonymous clients may publish a1's commands and telemetry and read its commands, and
    nothing else: the bridge's state and replies are dropped."""
    acl = tmp_path / "acl"
    acl.write_text(
        "topic readwrite rovlink/a1/cmd\ntopic write rovlink/a1/telemetry\n", encoding="utf-8"
    )
    yield from _broker(tmp_path, f"acl_file {acl}\n")


@pytest.fixture
def no_subscriptions_broker(tmp_path: Path) -> Iterator[Mosquitto]:
    """mosquitto's dynamic security plugin, refusing every subscription in its SUBACK."""
    plugins = glob.glob("/usr/lib/*/mosquitto_dynamic_security.so")
    if not plugins:
        pytest.skip("needs mosquitto's dynamic security plugin (Debian package mosquitto)")
    config = tmp_path / "dynsec.json"
    config.write_text(
        json.dumps(
            {
                "defaultACLAccess": {
                    "publishClientSend": True,
                    "publishClientReceive": True,
                    "subscribe": False,
                    "unsubscribe": True,
                },
                "clients": [],
                "groups": [],
                "roles": [],
            }
        ),
        encoding="utf-8",
    )
    yield from _broker(tmp_path, f"plugin {plugins[0]}\nplugin_opt_config_file {config}\n")


async def test_publications_the_broker_refuses_are_logged_by_topic(
    acl_broker: Mosquitto, caplog: pytest.LogCaptureFixture
):
    # Before, mosquitto's "Not authorized" PUBACKs were taken as delivered: the state and every
    # reply were dropped, and nothing said so.
    caplog.set_level("WARNING", logger="rovlink.bridges.mqtt")
    async with (
        bridged_robot(acl_broker, "a1") as robot,
        subscriber(acl_broker) as asker,
    ):
        await asker.client.publish("rovlink/a1/cmd", b"qd", qos=1)
        await until(lambda: "rovlink/a1/cmd/reply" in caplog.text)
        await until(lambda: "rovlink/a1/state" in caplog.text)
        refusals = [r.getMessage() for r in caplog.records if "refused" in r.getMessage()]
        assert len(refusals) == 2
        assert all("(Not authorized)" in text for text in refusals)
        assert all("access control for anonymous clients" in text for text in refusals)
        assert "#qd!" in robot.frames()  # the command itself came through
        # A response topic its asker chose is the asker's business: a warning, not an error.
        properties = Properties(PacketTypes.PUBLISH)
        properties.ResponseTopic = "answers/a1"
        async with aiomqtt.Client(
            "127.0.0.1", acl_broker.port, protocol=aiomqtt.ProtocolVersion.V5
        ) as v5_asker:
            await v5_asker.publish("rovlink/a1/cmd", b"qd", qos=1, properties=properties)
        await until(lambda: "reply to the response topic answers/a1" in caplog.text)
        assert len([r for r in caplog.records if r.levelname == "ERROR"]) == 2
        assert not robot.task.done()


async def test_a_subscription_the_broker_refuses_is_logged(
    no_subscriptions_broker: Mosquitto, caplog: pytest.LogCaptureFixture
):
    caplog.set_level("ERROR", logger="rovlink.bridges.mqtt")
    async with bridged_robot(no_subscriptions_broker, "a2") as robot:
        await until(lambda: "subscription to rovlink/a2/cmd" in caplog.text)
        assert "(Not authorized): no command, not even stop, reaches the robot" in caplog.text
        assert robot.bridge.connected.is_set()  # serving on: telemetry, state, events
