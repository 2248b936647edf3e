"""A bridge process that dies (SIGKILL: no ``#stop!`` of its own) leaves the robot with zero
thrust: its keep-alives stop, and the controller's link-loss watchdog (P17) stops the motors.

The robot is a simulated controller served on TCP in this process, so the test reads its real
outputs; the bridges run as ``rovlink mavlink`` and ``rovlink mqtt`` processes, as users run them.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from rovlink.controller import ControllerState
from rovlink.sim import SimConfig
from rovlink.sim.server import SimServer

pytestmark = pytest.mark.integration

_SRC = str(Path(__file__).resolve().parents[2] / "src")
#: The controller's watchdog (2 s) plus room for a loaded machine.
_STOPPED_WITHIN_S = 8.0


@contextmanager
def served_robot(config: SimConfig | None = None) -> Iterator[tuple[SimServer, str]]:
    """A simulated robot served on a loopback TCP port, and its URL."""
    server = SimServer(config or SimConfig(), seed=1)
    _, port = server.listen_tcp()
    stopping = threading.Event()
    thread = threading.Thread(target=server.serve, args=(stopping.is_set,), daemon=True)
    thread.start()
    try:
        yield server, f"socket://127.0.0.1:{port}"
    finally:
        stopping.set()
        thread.join(timeout=5)
        server.close()


def state(server: SimServer) -> ControllerState:
    return server.robot.controller.state()


def wait_until(condition: Callable[[], bool], timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"{what}: not within {timeout_s} s")
        time.sleep(0.02)


def rovlink_process(*arguments: str) -> subprocess.Popen[str]:
    environment = dict(os.environ, PYTHONPATH=_SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen(
        [sys.executable, "-m", "rovlink", *arguments],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=environment,
    )


def kill(process: subprocess.Popen[str]) -> None:
    if process.poll() is None:
        process.send_signal(signal.SIGKILL)
    process.communicate(timeout=10)


def test_a_killed_mavlink_bridge_leaves_zero_thrust() -> None:
    pytest.importorskip("pymavlink", reason="needs pymavlink: pip install 'rovlink[mavlink]'")
    from tests.bridges.mavlink.rig import GroundStation, free_udp_port

    gcs_port = free_udp_port()
    with served_robot() as (server, url):
        bridge = rovlink_process("mavlink", url, "--out", f"udpout:127.0.0.1:{gcs_port}")
        gcs = GroundStation(f"udpin:127.0.0.1:{gcs_port}")
        try:
            gcs.receive("HEARTBEAT", condition=lambda m: m.type == 12, timeout_s=20.0)
            gcs.start_heartbeats()
            assert gcs.arm() == 0
            gcs.send("manual_control", 1, 1000, 0, 500, 0, 0)
            wait_until(lambda: state(server).power_percent == 100, 10.0, "full ahead")
            assert not state(server).locked
            kill(bridge)  # the ground station goes on beating: only the bridge is gone
            wait_until(
                lambda: state(server).locked and state(server).power_percent == 0,
                _STOPPED_WITHIN_S,
                "the watchdog stopped the robot",
            )
        finally:
            gcs.close()
            kill(bridge)


def test_a_killed_mqtt_bridge_leaves_zero_thrust(tmp_path: Path) -> None:
    pytest.importorskip("aiomqtt", reason="needs aiomqtt: pip install 'rovlink[mqtt]'")
    from tests.bridges.mqtt.broker import Mosquitto, mosquitto_available

    if not mosquitto_available():
        pytest.skip("needs mosquitto (Debian package mosquitto)")
    from paho.mqtt import publish

    broker = Mosquitto(tmp_path)
    broker.start()
    try:
        with served_robot() as (server, url):
            # No motion timeout: the command holds, so only the watchdog can stop it.
            bridge = rovlink_process(
                "mqtt", url, "--broker", broker.url, "--robot", "d1", "--allow-commands",
                "--motion-timeout", "0",
            )  # fmt: skip
            try:
                assert bridge.stdout is not None
                assert "ready" in bridge.stdout.readline()

                def command(text: str) -> None:
                    publish.single("rovlink/d1/cmd", text, qos=1, port=broker.port)

                # The bridge may still be subscribing: repeat until the robot moves.
                def moving() -> bool:
                    command("start")
                    command("th 0 100")
                    time.sleep(0.2)
                    return state(server).power_percent == 100

                wait_until(moving, 15.0, "full ahead")
                kill(bridge)
                wait_until(
                    lambda: state(server).locked and state(server).power_percent == 0,
                    _STOPPED_WITHIN_S,
                    "the watchdog stopped the robot",
                )
            finally:
                kill(bridge)
    finally:
        broker.stop()
