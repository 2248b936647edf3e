"""Several tools on one simulated controller at once, one on its PTY and one on its TCP port, as
a team flies a robot: what one tool does to the controller's shared state (the lock, the
set-points, the link-loss failsafe) and what it must not do to another tool's link (the checksum
and debug modes)."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

import rovlink
from rovlink.controller import ControllerConfig
from rovlink.protocol import Event, Text
from rovlink.sim import SimConfig
from rovlink.sim.server import SimServer
from tests.rovlink_process import rovlink_command, rovlink_environment
from tests.sim.conftest import StartServer

pytestmark = pytest.mark.integration


def _wait_for(condition: Callable[[], bool], what: str, timeout_s: float = 3.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting until {what}")
        time.sleep(0.005)


def _pty_url(server: SimServer) -> str:
    assert server.pty_path is not None
    return server.pty_path


def _tcp_url(server: SimServer) -> str:
    assert server.tcp_address is not None
    host, port = server.tcp_address
    return f"socket://{host}:{port}"


def _moving(server: SimServer) -> bool:
    return any(server.robot.controller.duties)


def _stopped(server: SimServer) -> bool:
    controller = server.robot.controller
    return controller.locked and not any(controller.duties)


def test_a_tool_in_checksum_mode_leaves_another_tools_plain_link_alone(
    start_server: StartServer,
) -> None:
    # Before, the checksum mode was the controller's: a tool on TCP putting it on made every
    # query of a tool on the PTY time out, each suspected a reset in turn and re-asserted its
    # own mode, and so on, query after query.
    server = start_server()
    with (
        rovlink.connect(_pty_url(server), timeout=1.0, retries=1, keepalive=None) as plain,
        rovlink.connect(
            _tcp_url(server), checksum=True, timeout=1.0, retries=1, keepalive=None
        ) as checked,
    ):
        for _ in range(3):
            assert plain.depth_cm() == 0
            assert checked.depth_cm() == 0
        checked.set_debug(True)  # debug output is the controller's: text a client skips
        plain.sensors()
        checked.sensors()
        plain.set_debug(False)
        assert checked.depth_cm() == 0
        for client in (plain, checked):
            counters = client.counters
            assert (counters.timeouts, counters.resets_suspected) == (0, 0), counters


def test_a_driver_whose_socket_closes_is_stopped_while_a_passive_tool_keeps_polling(
    start_server: StartServer,
) -> None:
    # A recorder or a telemetry bridge polling on the PTY kept the link-loss failsafe fed, and
    # the motion of a driver that had died over TCP ran on for good.
    server = start_server(SimConfig(controller=ControllerConfig(watchdog_s=0.3)))
    with rovlink.connect(_pty_url(server), keepalive=0.05, timeout=1.0) as passive:
        assert server.tcp_address is not None
        with socket.create_connection(server.tcp_address, timeout=2) as driver:
            driver.sendall(b"#start!#th.0.100!")
            _wait_for(lambda: _moving(server), "the driver moves the robot")
        _wait_for(lambda: _stopped(server), "the failsafe stops the robot")
        assert passive.depth_cm() == 0  # the passive tool's link lives on
        assert passive.counters.timeouts == 0


def test_a_stop_from_any_tool_stops_the_motion_another_commanded(
    start_server: StartServer,
) -> None:
    server = start_server()
    with (
        rovlink.connect(_tcp_url(server), checksum=True, timeout=1.0, keepalive=None) as pilot,
        rovlink.connect(_pty_url(server), timeout=1.0, keepalive=None) as bystander,
    ):
        pilot.start()
        pilot.move(0, 60)
        _wait_for(lambda: _moving(server), "the pilot moves the robot")
        bystander.stop()
        _wait_for(lambda: _stopped(server), "the bystander's stop stops the robot")
        pilot.move(90, 60)  # dropped: locked for every tool (P7)
        assert pilot.depth_cm() == 0  # (the move has been handled)
        assert _stopped(server)


def test_a_driver_whose_socket_closes_is_stopped_at_once_with_the_failsafe_off(
    start_server: StartServer,
) -> None:
    # With --watchdog 0 (a person typing frames on the PTY), the motion of a program that died
    # over TCP ran on for good; with the failsafe on, for its whole timeout.
    server = start_server(SimConfig(controller=ControllerConfig(watchdog_s=0.0)))
    with rovlink.connect(_pty_url(server), timeout=1.0, keepalive=None) as bystander:
        assert server.tcp_address is not None
        with socket.create_connection(server.tcp_address, timeout=2) as driver:
            driver.sendall(b"#start!#th.0.100!")
            _wait_for(lambda: _moving(server), "the driver moves the robot")
        _wait_for(lambda: _stopped(server), "the robot stops", timeout_s=1.0)
        assert bystander.depth_cm() == 0


def test_with_debug_on_a_pilot_hears_a_bystanders_stop_and_a_second_driver(
    start_server: StartServer,
) -> None:
    # Before, what the controller said of a #stop! or of another line's motion went back on the
    # line that sent it only: the pilot's tool (and a recorder on its line) never heard of it.
    server = start_server()
    heard: list[str] = []

    def keep_text(event: Event) -> None:
        if isinstance(event, Text):
            heard.append(event.text)

    with (
        rovlink.connect(_tcp_url(server), timeout=1.0, keepalive=None, on_stray=keep_text) as pilot,
        rovlink.connect(_pty_url(server), timeout=1.0, keepalive=None) as bystander,
    ):
        # Each tool's query after its commands: its reply comes once they have been handled
        # (one line's frames are handled in order; two lines' in any).
        pilot.set_debug(True)
        pilot.start()
        pilot.move(0, 60)
        pilot.depth_cm()
        bystander.move(90, 20)  # a second driver
        bystander.depth_cm()
        bystander.stop()
        bystander.depth_cm()
        assert _stopped(server)
        pilot.depth_cm()  # (the pilot reads what came meanwhile)
        # (The order they are handed on in is the client's: its reader may hand on one chunk
        # and the caller's read the next.)
        assert {
            "debug: <th.90.20> from another line: it drives now, and the link-loss failsafe "
            "follows it",
            "debug: stop command: motors stopped and locked",
        } <= set(heard), heard


def test_a_recorder_on_one_line_records_the_stop_a_tool_on_another_line_sent(
    start_server: StartServer, tmp_path: Path
) -> None:
    # `rovlink record` listening on the PTY, a pilot on TCP with debug output on: before, the
    # recording held nothing of the pilot's start and stop.
    server = start_server()
    recording = tmp_path / "deck.jsonl"
    recorder = subprocess.Popen(
        rovlink_command("record", _pty_url(server), "-o", str(recording)),
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=rovlink_environment(),
    )
    try:
        assert recorder.stderr is not None
        assert recorder.stderr.readline().startswith("recording ")
        with rovlink.connect(_tcp_url(server), timeout=1.0, keepalive=None) as pilot:
            pilot.set_debug(True)
            pilot.start()
            pilot.stop()

            def recorded() -> str:
                return recording.read_text() if recording.exists() else ""

            _wait_for(lambda: "stop command" in recorded(), "the recorder has the stop")
    finally:
        recorder.terminate()
        recorder.communicate(timeout=10)
    texts = [
        entry["detail"]
        for entry in map(json.loads, recording.read_text().splitlines())
        if entry["channel"] == "events" and entry["event"] == "text"
    ]
    assert texts == ["debug: motors unlocked", "debug: stop command: motors stopped and locked"]


_DRIVER_PROGRAM = """
import sys, time, rovlink
rov = rovlink.connect(sys.argv[1], keepalive=0.1)
rov.start()
rov.move(0, 80)
rov.depth_cm()
print("driving", flush=True)
time.sleep(60)
"""


def test_a_driver_killed_with_sigkill_is_stopped_at_once_and_the_others_stay(
    start_server: StartServer,
) -> None:
    # A program driving over TCP killed with SIGKILL (no close(), no #stop!): with the failsafe
    # off its motion ran on for good; the bystander's link must not be touched.
    server = start_server(SimConfig(controller=ControllerConfig(watchdog_s=0.0)))
    with rovlink.connect(_pty_url(server), timeout=1.0, keepalive=0.05) as bystander:
        driver = subprocess.Popen(
            [sys.executable, "-c", _DRIVER_PROGRAM, _tcp_url(server)],
            stdout=subprocess.PIPE,
            text=True,
            env=rovlink_environment(),
        )
        try:
            assert driver.stdout is not None
            assert driver.stdout.readline() == "driving\n"
            _wait_for(lambda: _moving(server), "the driver moves the robot")
        finally:
            driver.kill()
            driver.wait(timeout=10)
        _wait_for(lambda: _stopped(server), "the robot stops", timeout_s=1.0)
        assert bystander.depth_cm() == 0
        assert bystander.counters.timeouts == 0
