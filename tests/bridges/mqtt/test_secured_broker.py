"""A broker with TLS and passwords: the bridge logs in with its user and trusts the broker's CA;
the wrong password or no TLS gets it nowhere (and nothing crashes)."""

from __future__ import annotations

import asyncio
import shutil
import ssl
import subprocess
from collections.abc import Iterator
from pathlib import Path

import aiomqtt
import pytest

from rovlink.aio import AsyncClient
from rovlink.bridges.mqtt.bridge import REPLY_TIMEOUT_S, MqttBridge
from rovlink.bridges.mqtt.broker import BrokerSettings
from rovlink.client import ClientOptions
from rovlink.client.links import PortLink
from rovlink.piloting.tracked import TrackedClient
from rovlink.sim import SimulatedPort
from tests.bridges.mqtt.broker import Mosquitto, mosquitto_available
from tests.bridges.mqtt.rig import until
from tests.cli.conftest import RunCli

pytestmark = pytest.mark.integration

USER, PASSWORD = "rov-1", "s3cret-pw"


def _openssl(*arguments: str, cwd: Path) -> None:
    subprocess.run(["openssl", *arguments], cwd=cwd, check=True, capture_output=True)


@pytest.fixture
def secured_broker(tmp_path: Path) -> Iterator[Mosquitto]:
    if not mosquitto_available() or shutil.which("openssl") is None:
        pytest.skip("needs mosquitto and openssl (Debian packages mosquitto, openssl)")
    _openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "ca.key", "-out",
             "ca.pem", "-days", "2", "-subj", "/CN=rovlink test CA",
             "-addext", "basicConstraints=critical,CA:TRUE",
             "-addext", "keyUsage=critical,keyCertSign,cRLSign", cwd=tmp_path)  # fmt: skip
    _openssl("req", "-newkey", "rsa:2048", "-nodes", "-keyout", "server.key", "-out",
             "server.csr", "-subj", "/CN=localhost", cwd=tmp_path)  # fmt: skip
    (tmp_path / "san.ext").write_text(
        "subjectAltName=DNS:localhost,IP:127.0.0.1\n"
        "keyUsage=critical,digitalSignature,keyEncipherment\n"
        "extendedKeyUsage=serverAuth\n"
        "authorityKeyIdentifier=keyid,issuer\n"
        "subjectKeyIdentifier=hash\n"
    )
    _openssl("x509", "-req", "-in", "server.csr", "-CA", "ca.pem", "-CAkey", "ca.key",
             "-CAcreateserial", "-out", "server.pem", "-days", "2", "-extfile", "san.ext",
             cwd=tmp_path)  # fmt: skip
    passwords = tmp_path / "passwords"
    passwords.write_text("")
    subprocess.run(["mosquitto_passwd", "-b", str(passwords), USER, PASSWORD], check=True)
    broker = Mosquitto(
        tmp_path,
        listener_options=(
            f"cafile {tmp_path}/ca.pem\ncertfile {tmp_path}/server.pem\n"
            f"keyfile {tmp_path}/server.key\n"
            f"allow_anonymous false\npassword_file {passwords}\n"
        ),
    )
    broker.start()
    try:
        yield broker
    finally:
        broker.stop()


async def _bridge_connects(
    settings: BrokerSettings, within_s: float, reply_timeout_s: float = REPLY_TIMEOUT_S
) -> bool:
    port = SimulatedPort(seed=1)
    port.start(realtime=True)
    options = ClientOptions(keepalive_s=1.0, timeout_s=2.0, boot_timeout_s=None)
    client = await AsyncClient(PortLink(port, "simulated"), options).open()
    bridge = MqttBridge(TrackedClient(client), settings, "rov-1", reply_timeout_s=reply_timeout_s)
    task = asyncio.ensure_future(bridge.run())
    try:
        try:
            await until(bridge.connected.is_set, within_s)
        except AssertionError:
            assert not task.done(), "refused, the bridge must keep retrying, not end"
            return False
        return True
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        await client.close()
        port.close()


async def test_the_bridge_logs_in_over_tls(secured_broker: Mosquitto):
    ca_file = secured_broker.workdir / "ca.pem"
    settings = BrokerSettings(
        "127.0.0.1", secured_broker.port, tls=True, username=USER, password=PASSWORD,
        ca_file=ca_file,
    )  # fmt: skip
    context = ssl.create_default_context(cafile=str(ca_file))
    async with aiomqtt.Client(
        "127.0.0.1", secured_broker.port, username=USER, password=PASSWORD, tls_context=context
    ) as watcher:
        await watcher.subscribe("rovlink/rov-1/state", qos=1)
        assert await _bridge_connects(settings, 15.0)
        first = await asyncio.wait_for(anext(aiter(watcher.messages)), 15)
        assert isinstance(first.payload, bytes)
        assert b'"robot":"rov-1"' in first.payload


_LOGIN_REFUSED = "cannot connect: the broker refused the login: Not authorized (check the user"


@pytest.mark.parametrize(
    ("change", "said"),
    [
        ({"password": "wrong"}, _LOGIN_REFUSED),
        ({"username": None, "password": None}, _LOGIN_REFUSED),
        (
            {"tls": False},  # (its CONNECT reaches a listener waiting for a TLS handshake)
            "cannot connect: no answer to the MQTT connection within 1 s (a stalled or "
            "overloaded broker, or one that expects TLS: mqtts://)",
        ),
        (
            {"ca_file": None},  # the system's CAs do not know this broker
            "cannot connect: TLS failure: the broker's certificate was not accepted "
            "(self-signed certificate in certificate chain)",
        ),
    ],
    ids=["wrong password", "no user", "no TLS", "no CA"],
)
async def test_wrong_credentials_or_trust_never_connect_and_are_said(
    secured_broker: Mosquitto,
    change: dict[str, object],
    said: str,
    caplog: pytest.LogCaptureFixture,
):
    # Regression: the retry warnings said "[code:135] Not authorized", "Operation timed out",
    # "[SSL: CERTIFICATE_VERIFY_FAILED] certificate verify failed: … (_ssl.c:1020)".
    caplog.set_level("WARNING", logger="rovlink.bridges.mqtt")
    settings: dict[str, object] = {
        "host": "127.0.0.1",
        "port": secured_broker.port,
        "tls": True,
        "username": USER,
        "password": PASSWORD,
        "ca_file": secured_broker.workdir / "ca.pem",
    }
    settings.update(change)
    broker = BrokerSettings(**settings)  # type: ignore[arg-type]
    assert not await _bridge_connects(broker, 2.0, reply_timeout_s=1.0)
    warnings = [r.getMessage() for r in caplog.records if "retrying in" in r.getMessage()]
    assert warnings, "the bridge must say why it retries"
    assert warnings[0].startswith(f"broker {broker.describe()}: {said}")


@pytest.mark.parametrize(
    ("wrong", "said"),
    [
        ("password", "cannot connect: the broker refused the login: Not authorized (check"),
        ("ca", "cannot connect: TLS failure: the broker's certificate was not accepted"),
    ],
)
def test_fleet_says_why_it_cannot_connect_as_the_bridge_does(
    secured_broker: Mosquitto, run_cli: RunCli, tmp_path: Path, wrong: str, said: str
) -> None:
    # Before: "cannot connect to the broker …: [code:135] Not authorized", and for a CA not
    # given "[SSL: CERTIFICATE_VERIFY_FAILED] certificate verify failed: … (_ssl.c:1020)".
    password_file = tmp_path / "fleet-password"
    password_file.write_text("not-it" if wrong == "password" else PASSWORD, encoding="utf-8")
    url = f"mqtts://127.0.0.1:{secured_broker.port}"
    trust = [] if wrong == "ca" else ["--cafile", str(secured_broker.workdir / "ca.pem")]
    result = run_cli(
        "fleet", "--broker", url, "--username", USER,
        "--password-file", str(password_file), *trust, "--snapshot", "1",
    )  # fmt: skip
    assert result.status == 1
    # The URL as --broker takes it (before, with the user in it, which --broker refuses).
    assert result.err.startswith(f"rovlink fleet: broker {url} (as {USER}): {said}"), result.err
    assert "[code:" not in result.err
    assert "_ssl.c" not in result.err
