"""The controller's link drops and comes back (a USB adapter unplugged and plugged back, a
serial server restarting): ``rovlink mavlink`` and ``rovlink mqtt`` reopen it and serve on.

The robot is a simulated controller served on TCP in this process, stopped and served again on
the same port (a new controller, as after a power cycle: locked, its defaults back); the bridges
run as processes, as users run them. Before, each bridge ended at the first lost connection.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from rovlink.controller import ControllerState
from rovlink.sim import SimConfig
from rovlink.sim.server import SimServer
from tests.bridges.test_bridge_process_death import kill, rovlink_process, wait_until

pytestmark = pytest.mark.integration


class RestartableRobot:
    """A simulated controller on a fixed TCP port that can be stopped and served anew."""

    def __init__(self) -> None:
        self.port = 0
        self.server: SimServer | None = None
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        return f"socket://127.0.0.1:{self.port}"

    def start(self) -> None:
        server = SimServer(SimConfig(), seed=1)
        _, self.port = server.listen_tcp(port=self.port)
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=server.serve, args=(self._stopping.is_set,))
        self._thread.daemon = True
        self._thread.start()
        self.server = server

    def stop(self) -> None:
        if self.server is None or self._thread is None:
            return
        self._stopping.set()
        self._thread.join(timeout=5)
        self.server.close()
        self.server = None

    def state(self) -> ControllerState:
        assert self.server is not None
        return self.server.robot.controller.state()


@contextmanager
def restartable_robot() -> Iterator[RestartableRobot]:
    robot = RestartableRobot()
    robot.start()
    try:
        yield robot
    finally:
        robot.stop()


def test_the_mavlink_bridge_serves_on_when_the_controller_link_comes_back() -> None:
    pytest.importorskip("pymavlink", reason="needs pymavlink: pip install 'rovlink[mavlink]'")
    from tests.bridges.mavlink.rig import GroundStation, free_udp_port

    armed_flag, critical = 128, 5
    gcs_port = free_udp_port()
    with restartable_robot() as robot:
        bridge = rovlink_process("mavlink", robot.url, "--out", f"udpout:127.0.0.1:{gcs_port}")
        gcs = GroundStation(f"udpin:127.0.0.1:{gcs_port}")
        try:
            gcs.receive("HEARTBEAT", condition=lambda m: m.type == 12, timeout_s=20.0)
            gcs.start_heartbeats()
            gcs.send("param_set", 1, 1, b"RL_MAX_PWM", 100.0, 6)
            wait_until(lambda: robot.state().max_pwm == 100, 10.0, "RL_MAX_PWM set")
            assert gcs.arm() == 0
            robot.stop()  # the link drops
            gcs.receive("STATUSTEXT", condition=lambda m: "link lost" in m.text)
            down = gcs.receive_new("HEARTBEAT", condition=lambda m: m.type == 12)
            assert not down.base_mode & armed_flag
            assert down.system_status == critical
            assert gcs.arm() in (1, 4)  # TEMPORARILY_REJECTED or FAILED: not now

            # A disarm is carried out (#stop! waits to be the reopened link's first frame); it
            # once said "Disarmed: disarmed by the ground station", as if #stop! had been sent.
            def disarmed(message: Any) -> bool:
                return bool(message.text.startswith("Disarmed"))

            gcs.receive("STATUSTEXT", condition=disarmed)  # the bridge's own, on losing the link
            assert gcs.command(400, 0) == 0
            assert "link down" in gcs.receive("STATUSTEXT", condition=disarmed).text
            robot.start()  # and comes back, to a controller that was reset
            gcs.receive("STATUSTEXT", condition=lambda m: "link back" in m.text, timeout_s=20.0)
            wait_until(lambda: robot.state().max_pwm == 100, 10.0, "RL_MAX_PWM sent again")
            assert gcs.arm() == 0
            wait_until(lambda: not robot.state().locked, 10.0, "armed on the new link")
            assert bridge.poll() is None
        finally:
            gcs.close()
            kill(bridge)


def test_the_mqtt_bridge_serves_on_when_the_controller_link_comes_back(tmp_path: Path) -> None:
    pytest.importorskip("aiomqtt", reason="needs aiomqtt: pip install 'rovlink[mqtt]'")
    import paho.mqtt.client as mqtt
    from paho.mqtt import publish
    from paho.mqtt.enums import CallbackAPIVersion

    from tests.bridges.mqtt.broker import Mosquitto, mosquitto_available

    if not mosquitto_available():
        pytest.skip("needs mosquitto (Debian package mosquitto)")
    broker = Mosquitto(tmp_path)
    broker.start()
    states: list[dict[str, Any]] = []
    events: list[dict[str, Any]] = []

    def link_status(state: dict[str, Any]) -> object:
        link = state.get("link")
        return link.get("status") if isinstance(link, dict) else None

    def collect(_client: object, _userdata: object, message: mqtt.MQTTMessage) -> None:
        payload = json.loads(message.payload)
        (states if message.topic.endswith("/state") else events).append(payload)

    watcher = mqtt.Client(CallbackAPIVersion.VERSION2)
    watcher.on_message = collect
    watcher.connect("127.0.0.1", broker.port)
    watcher.subscribe([("rovlink/c1/state", 1), ("rovlink/c1/events", 1)])
    watcher.loop_start()
    try:
        with restartable_robot() as robot:
            bridge = rovlink_process(
                "mqtt", robot.url, "--broker", broker.url, "--robot", "c1", "--allow-commands"
            )  # fmt: skip
            try:

                def command(text: str) -> None:
                    publish.single("rovlink/c1/cmd", text, qos=1, port=broker.port)

                def set_max_pwm() -> bool:  # (the bridge may still be subscribing)
                    command("mgmp 100")
                    time.sleep(0.2)
                    return robot.state().max_pwm == 100

                wait_until(set_max_pwm, 15.0, "mgmp 100")
                command("start")
                wait_until(lambda: not robot.state().locked, 10.0, "started")
                robot.stop()
                wait_until(
                    lambda: any(link_status(state) == "lost" for state in states),
                    10.0,
                    "the state says the link is lost",
                )
                robot.start()
                wait_until(
                    lambda: any("sent again #mgmp.100!" in str(e["detail"]) for e in events),
                    20.0,
                    "the settings sent again",
                )
                assert robot.state().max_pwm == 100
                wait_until(  # stopped on losing it: #stop! was the reopened link's first frame
                    lambda: (states[-1]["online"], states[-1]["lock"]) == (True, "locked"),
                    10.0,
                    "online and locked",
                )
                command("start")
                wait_until(lambda: not robot.state().locked, 10.0, "started on the new link")
                assert bridge.poll() is None
            finally:
                kill(bridge)
    finally:
        watcher.loop_stop()
        watcher.disconnect()
        broker.stop()
