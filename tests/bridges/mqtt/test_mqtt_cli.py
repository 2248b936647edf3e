"""``rovlink mqtt`` as a user runs it: options checked first, and a killed bridge's last will."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.bridges.mqtt.broker import Mosquitto, free_tcp_port
from tests.bridges.mqtt.rig import subscriber
from tests.cli.conftest import RunCli

_SRC = str(Path(__file__).resolve().parents[3] / "src")


@pytest.mark.parametrize(
    ("arguments", "error"),
    [
        (["--broker", "http://h", "--robot", "r"], "expected mqtt://HOST[:PORT]"),
        # Before, urllib's own words alone: "error: Invalid IPv6 URL", naming no option.
        (["--broker", "mqtt://[::1", "--robot", "r"], "broker 'mqtt://[::1': expected mqtt://"),
        (["--broker", "mqtt://h", "--robot", "a/b"], "robot id 'a/b'"),
        (["--broker", "mqtt://h", "--robot", "r", "--tls-insecure"], "need an mqtts:// broker"),
        (["--broker", "mqtts://h", "--robot", "r", "--cafile", "/nonexistent.pem"], "no such file"),
        (
            ["--broker", "mqtts://h", "--robot", "r", "--keyfile", "/nonexistent.pem"],
            "--keyfile needs --certfile",
        ),
    ],
)
def test_bad_options_are_one_line_before_anything_opens(
    run_cli: RunCli, arguments: list[str], error: str
) -> None:
    result = run_cli("mqtt", "sim://", *arguments)
    assert result.status == 2
    assert error in result.err
    assert result.out == ""


def test_a_password_needs_a_user(
    run_cli: RunCli, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("ROVLINK_MQTT_PASSWORD", "secret")
    result = run_cli("mqtt", "sim://", "--broker", "mqtt://h", "--robot", "r")
    assert result.status == 2
    assert "a password needs --username" in result.err
    assert "secret" not in result.err


@pytest.mark.integration
def test_a_key_without_its_certificate_is_a_usage_error_not_ignored(
    run_cli: RunCli, tmp_path: Path
) -> None:
    key = tmp_path / "client.key"
    key.write_text("-----BEGIN PRIVATE KEY-----\n", encoding="utf-8")
    nobody_listens = f"mqtts://127.0.0.1:{free_tcp_port()}"
    result = run_cli("fleet", "--broker", nobody_listens, "--keyfile", str(key), "--snapshot", "1")
    assert result.status == 2
    assert "--keyfile needs --certfile" in result.err
    assert result.out == ""


def _bridge_process(broker_url: str, robot: str) -> subprocess.Popen[str]:
    environment = dict(os.environ, PYTHONPATH=_SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen(
        [sys.executable, "-m", "rovlink", "mqtt", "sim://", "--broker", broker_url,
         "--robot", robot],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=environment,
    )  # fmt: skip


@pytest.mark.integration
async def test_a_killed_bridge_leaves_its_last_will(broker: Mosquitto) -> None:
    process = _bridge_process(broker.url, "k1")
    try:
        async with subscriber(broker, "rovlink/k1/state") as watcher:
            online = await watcher.wait_for("rovlink/k1/state", lambda s: s["online"])
            # Its controller is the simulator: the state says so.
            assert online["simulated"] is True
            process.send_signal(signal.SIGKILL)
            offline = await watcher.wait_for("rovlink/k1/state", lambda s: not s["online"])
            assert offline == {
                "robot": "k1",
                "online": False,
                "reason": "bridge connection lost",
            }
        # Retained: a subscriber that comes later learns it too.
        async with subscriber(broker, "rovlink/k1/state") as late:
            assert (await late.wait_for("rovlink/k1/state"))["online"] is False
    finally:
        if process.poll() is None:
            process.kill()
        process.communicate()


@pytest.mark.integration
async def test_ctrl_c_ends_the_bridge_offline(broker: Mosquitto) -> None:
    process = _bridge_process(broker.url, "i1")
    try:
        async with subscriber(broker, "rovlink/i1/state") as watcher:
            await watcher.wait_for("rovlink/i1/state", lambda s: s["online"])
            process.send_signal(signal.SIGINT)
            offline = await watcher.wait_for("rovlink/i1/state", lambda s: not s["online"])
            assert offline["reason"] == "bridge stopped"
        out, _ = process.communicate(timeout=20)
        assert "rovlink mqtt ready" in out
        assert process.returncode == 130
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()


@pytest.mark.integration
def test_an_unreachable_broker_is_said_and_retried() -> None:
    port = free_tcp_port()
    nobody_listens = f"mqtt://127.0.0.1:{port}"
    process = _bridge_process(nobody_listens, "u1")
    try:
        assert process.stderr is not None
        line = process.stderr.readline()
        # Before, "broker mqtt://127.0.0.1:PORT: [Errno 111] Connection refused; retrying".
        assert (
            f"broker {nobody_listens}: cannot connect: connection refused (is the broker "
            f"running, and listening on port {port}?); retrying in "
        ) in line
        assert "Errno" not in line
        process.send_signal(signal.SIGINT)
        process.communicate(timeout=20)
        assert process.returncode == 130
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
