"""``rovlink tune`` and ``rovlink check --motion``, run as users run them and ended by a signal
(Ctrl-C, SIGTERM, SIGHUP, SIGQUIT) while the vehicle moves, leave it locked with zero thrust.

They drive a simulated controller's pseudo-terminal with its link-loss watchdog off: a PTY has no
connection whose end the controller sees, so only the ``#stop!`` the command sends on its way out
can stop the robot here. (A tool killed with SIGKILL sends nothing: on TCP the controller stops
the robot as its connection closes, on a PTY or a serial line its watchdog does; see
``tests/sim/test_sim_team.py`` and ``tests/sim/test_sim_cli.py``.)
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator

import pytest

from rovlink.controller import ControllerConfig
from rovlink.sim import SimConfig
from rovlink.sim.server import SimServer
from tests.bridges.test_bridge_process_death import kill, rovlink_process, wait_until

pytestmark = pytest.mark.integration

#: Generous: a reply or a motion is expected (a loaded machine is slow to start a process).
_WAIT_S = 30.0

_COMMANDS = {
    "tune": ["tune", "--yes", "--no-verify"],
    "check --motion": ["check", "--motion", "--yes", "--only", "motion-stop-halts"],
}


@pytest.fixture
def robot() -> Iterator[SimServer]:
    """A simulated robot in real time on a pseudo-terminal, its link-loss watchdog off."""
    server = SimServer(SimConfig(controller=ControllerConfig(watchdog_s=0.0)), seed=1)
    server.open_pty()
    stopping = threading.Event()
    thread = threading.Thread(target=server.serve, args=(stopping.is_set,), daemon=True)
    thread.start()
    yield server
    stopping.set()
    thread.join(timeout=5)
    server.close()


def _moving(server: SimServer) -> bool:
    controller = server.robot.controller
    return not controller.locked and any(controller.duties)


def _stopped(server: SimServer) -> bool:
    controller = server.robot.controller
    return controller.locked and not any(controller.duties)


@pytest.mark.parametrize(
    "how",
    [signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT],
    ids=lambda how: how.name,
)
@pytest.mark.parametrize("command", list(_COMMANDS))
def test_a_driving_command_ended_by_a_signal_while_the_vehicle_moves_stops_it(
    robot: SimServer, command: str, how: signal.Signals
) -> None:
    assert robot.pty_path is not None
    name, *options = _COMMANDS[command]
    process = rovlink_process(name, robot.pty_path, *options)
    try:
        wait_until(lambda: _moving(robot), _WAIT_S, f"rovlink {command} moves the vehicle")
        process.send_signal(how)
        process.communicate(timeout=_WAIT_S)
        wait_until(lambda: _stopped(robot), _WAIT_S, "the robot is locked with zero thrust")
    finally:
        kill(process)
