"""A relay between a driving program and the robot, ``rovlink record --tap`` or ``rovlink fault``,
that is ended while the program has the robot moving leaves thrust at zero however it ends: a
signal it handles (Ctrl-C, SIGTERM) sends ``#stop!`` on its way out, and SIGKILL closes its
connection to the controller, which stops the robot at once (the line that drove has gone), the
link-loss watchdog off here so that it cannot be what stopped it.

The relays run as ``rovlink`` processes, as users run them; the program is a real TCP client.
"""

from __future__ import annotations

import re
import signal
import socket
import subprocess
from contextlib import AbstractContextManager
from pathlib import Path

import pytest

from rovlink.controller import ControllerConfig
from rovlink.sim import SimConfig
from rovlink.sim.server import SimServer
from tests.bridges.test_bridge_process_death import (
    kill,
    rovlink_process,
    served_robot,
    state,
    wait_until,
)
from tests.cli.silent_controller import WAIT_S, SilentController

pytestmark = pytest.mark.integration

_RELAYS = ["record", "fault"]


def _start_relay(
    relay: str, controller_url: str, tmp_path: Path
) -> tuple[subprocess.Popen[str], str]:
    """Start ``rovlink record --tap`` or ``rovlink fault`` in front of ``controller_url``, on a
    port the system picks: the process and the program's side, read from its ready line."""
    arguments = (
        ["record", controller_url, "-o", str(tmp_path / "tapped.jsonl"), "--tap"]
        if relay == "record"
        else ["fault", "--to", controller_url, "--listen"]
    )
    process = rovlink_process(*arguments, "socket://127.0.0.1:0")
    stream = process.stderr if relay == "record" else process.stdout
    assert stream is not None
    ready = stream.readline()
    found = re.search(r"(?:program's side|ready): socket://127\.0\.0\.1:(\d+)", ready)
    assert found, ready
    return process, found.group(1)


def _served_robot_without_watchdog() -> AbstractContextManager[tuple[SimServer, str]]:
    return served_robot(SimConfig(controller=ControllerConfig(watchdog_s=0.0)))


@pytest.mark.parametrize(
    "how",
    [signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT],
    ids=lambda how: how.name,
)
@pytest.mark.parametrize("relay", _RELAYS)
def test_a_relay_ended_by_a_signal_while_its_program_drives_sends_stop(
    silent: SilentController, tmp_path: Path, relay: str, how: signal.Signals
) -> None:
    process, port = _start_relay(relay, silent.url, tmp_path)
    try:
        with socket.create_connection(("127.0.0.1", int(port)), timeout=WAIT_S) as program:
            program.sendall(b"#start!#th.0.50!")
            assert silent.wait_for(b"#th.0.50!")
            process.send_signal(how)
            process.communicate(timeout=WAIT_S)
        assert silent.wait_for(b"#th.0.50!#stop!")
    finally:
        kill(process)


@pytest.mark.parametrize("relay", _RELAYS)
def test_a_relay_killed_while_its_program_drives_leaves_zero_thrust(
    tmp_path: Path, relay: str
) -> None:
    with _served_robot_without_watchdog() as (server, url):
        process, port = _start_relay(relay, url, tmp_path)
        try:
            with socket.create_connection(("127.0.0.1", int(port)), timeout=WAIT_S) as program:
                program.sendall(b"#start!#th.0.50!")
                wait_until(lambda: state(server).power_percent == 50, WAIT_S, "half ahead")
                kill(process)  # SIGKILL: no #stop! of its own; the program stays connected
                wait_until(
                    lambda: state(server).locked and state(server).power_percent == 0,
                    WAIT_S,
                    "the controller stopped the robot as the relay's line went",
                )
        finally:
            kill(process)
