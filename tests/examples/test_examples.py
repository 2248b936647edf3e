"""The programs in ``examples/`` run against the simulator, print what they say, and leave the
robot stopped and locked.

Each example runs through its own ``main(argv)``, as ``python examples/NAME.py URL …`` would,
with a ``keptsim://`` URL: the in-process simulator, whose port the test keeps to read the
controller's state once the example has closed its client. The simulation runs as fast as the
CPU allows, so a dive takes a fraction of a second; its link-loss watchdog counts simulated
seconds, which pass far faster than the examples' wall-clock polling, so it is off — and so a
locked robot at the end is the example's doing, not the failsafe's. A few tests run an example
as a script, in a process of its own, as a user does (Ctrl-C, SIGTERM and a terminal that closes
included).
"""

from __future__ import annotations

import contextlib
import doctest
import importlib.util
import io
import json
import os
import queue
import re
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from rovlink.client.events import Unsolicited
from rovlink.client.schemes import register_scheme, unregister_scheme
from rovlink.controller.controller import ControllerState
from rovlink.protocol import BadFrame, Frame, Reason, Response, Text
from rovlink.sim.port import SimulatedPort
from rovlink.sim.robot import load_sim_config
from rovlink.sim.server import SimServer
from tests.client.conftest import CONDITION_TIMEOUT_S, wait_until
from tests.examples import kept_sim
from tests.terminals import Terminal

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
#: A reading line of poll_sensors.py.
READING_LINE = re.compile(
    r"^ +\d+\.\d\d s  depth +-?\d+ cm  roll +[+-]\d+°  pitch +[+-]\d+°  heading +\d+°  "
    r"leak (no|YES)$",
    re.MULTILINE,
)


def example_names() -> list[str]:
    """Every example program, by name."""
    return sorted(path.stem for path in EXAMPLES.glob("*.py"))


def load_example(name: str) -> Any:
    """Import ``examples/NAME.py`` as a module (once)."""
    module_name = f"rovlink_example_{name}"
    if module_name in sys.modules:
        return sys.modules[module_name]
    spec = importlib.util.spec_from_file_location(module_name, EXAMPLES / f"{name}.py")
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # (dataclasses look their module up while it loads)
    spec.loader.exec_module(module)
    return module


@dataclass(frozen=True)
class KeptSim:
    """The URL to give an example, and the simulator it opened."""

    url: str
    #: Set when the test has ended: a watch still waiting gives up (it must not act on the
    #: next test's simulator).
    ended: threading.Event = field(default_factory=threading.Event)

    def port(self) -> SimulatedPort:
        """The one port the example opened."""
        assert len(kept_sim.OPENED) == 1, f"{len(kept_sim.OPENED)} connections opened"
        return kept_sim.OPENED[0]

    def state(self) -> ControllerState:
        """The simulated controller's settings now."""
        port = self.port()
        with port.lock:
            return port.controller.state()

    def assert_stopped_and_locked(self) -> None:
        """The robot was left with its motors locked and no thrust asked for."""
        state = self.state()
        assert state.locked
        assert state.power_percent == 0
        assert state.vertical_thrust_percent == 0

    def when(
        self,
        condition: Callable[[SimulatedPort], bool],
        action: Callable[[SimulatedPort], None] = lambda port: None,
    ) -> threading.Event:
        """Once ``condition(port)`` holds, do ``action(port)`` (both under the port's lock); the
        event is set when it has been done."""
        done = threading.Event()

        def watch() -> None:
            def check() -> bool:
                if self.ended.is_set():
                    return True
                if not kept_sim.OPENED:
                    return False
                port = kept_sim.OPENED[0]
                with port.lock:
                    if not condition(port):
                        return False
                    action(port)
                    return True

            if wait_until(check) and not self.ended.is_set():
                done.set()

        threading.Thread(target=watch, daemon=True).start()
        return done

    def inject_leak_when(self, condition: Callable[[SimulatedPort], bool]) -> threading.Event:
        """Wet the leak probe once ``condition(port)`` holds; the event says it was."""
        return self.when(condition, lambda port: port.robot.inject_leak())


@pytest.fixture
def sim(tmp_path: Path) -> Iterator[KeptSim]:
    """A fast simulator without the link-loss watchdog, behind ``keptsim://``."""
    config = tmp_path / "fast.toml"
    config.write_text("[controller]\nwatchdog_s = 0\n")
    kept_sim.OPENED.clear()
    register_scheme(kept_sim.SCHEME, "tests.examples.kept_sim")
    kept = KeptSim(f"{kept_sim.SCHEME}://?realtime=0&seed=1&config={config}")
    try:
        yield kept
    finally:
        kept.ended.set()
        unregister_scheme(kept_sim.SCHEME)
        for port in kept_sim.OPENED:
            port.close()
        kept_sim.OPENED.clear()


def run_example(name: str, *argv: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """Run an example's ``main``; its exit status and what it printed."""
    capsys.readouterr()
    status = load_example(name).main(list(argv))
    return status, capsys.readouterr().out


def unlocked_at_depth(depth_cm: int) -> Callable[[SimulatedPort], bool]:
    """A condition: the robot is unlocked and at least ``depth_cm`` deep."""
    return lambda port: not port.controller.locked and port.controller.depth_cm >= depth_cm


def script_command(name: str, *argv: str) -> list[str]:
    """The command line that runs ``examples/NAME.py`` as a user would."""
    return [sys.executable, str(EXAMPLES / f"{name}.py"), *argv]


@contextlib.contextmanager
def served_on_a_pty(tmp_path: Path, speed: float) -> Iterator[tuple[SimServer, str]]:
    """A simulator without the link-loss watchdog on a real pseudo-terminal at ``speed`` (0: as
    fast as the CPU allows), served from a thread of the test (so the test reads its state), and
    the terminal's path."""
    config = tmp_path / "no-watchdog.toml"
    config.write_text("[controller]\nwatchdog_s = 0\n")
    server = SimServer(load_sim_config(config), seed=1, speed=speed)
    path = server.open_pty()
    stopping = threading.Event()
    thread = threading.Thread(target=server.serve, args=(stopping.is_set,), daemon=True)
    thread.start()
    try:
        yield server, path
    finally:
        stopping.set()
        thread.join(timeout=CONDITION_TIMEOUT_S)
        server.close()


@pytest.fixture
def pty_sim(tmp_path: Path) -> Iterator[tuple[SimServer, str]]:
    """A fast simulator on a pseudo-terminal (:func:`served_on_a_pty`): a dive takes no time."""
    with served_on_a_pty(tmp_path, speed=0) as served:
        yield served


@pytest.fixture
def realtime_pty_sim(tmp_path: Path) -> Iterator[tuple[SimServer, str]]:
    """A simulator on a pseudo-terminal (:func:`served_on_a_pty`) in real time: it leaves the
    CPU to the example between its ticks."""
    with served_on_a_pty(tmp_path, speed=1) as served:
        yield served


def interrupt_when_printed(command: list[str], marker: str) -> tuple[int, str]:
    """Run ``command``, press Ctrl-C (SIGINT) once a line containing ``marker`` is printed;
    its exit status and everything it printed."""
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: queue.Queue[str] = queue.Queue()

    def read() -> None:
        assert process.stdout is not None
        for line in process.stdout:
            lines.put(line)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    seen = ""
    try:
        while marker not in seen:
            seen += lines.get(timeout=CONDITION_TIMEOUT_S)
        process.send_signal(signal.SIGINT)
        status = process.wait(timeout=CONDITION_TIMEOUT_S)
    finally:
        process.kill()
        process.wait()
    reader.join(timeout=CONDITION_TIMEOUT_S)
    while not lines.empty():
        seen += lines.get()
    return status, seen


# -- every example -------------------------------------------------------------------------------


def test_every_example_has_a_test() -> None:
    names = example_names()
    assert names, "no examples found"
    tested = {name for name in names if any(key.startswith(f"test_{name}_") for key in globals())}
    assert sorted(set(names) - tested) == [], "examples without a test_<name>_… test here"


@pytest.mark.integration
@pytest.mark.parametrize("name", example_names())
def test_every_example_runs_as_a_script_and_says_what_it_does(name: str) -> None:
    result = subprocess.run(
        script_command(name, "--help"), capture_output=True, text=True, timeout=30, check=False
    )
    assert result.returncode == 0, result.stderr
    module = load_example(name)
    assert module.__doc__.splitlines()[0] in " ".join(result.stdout.split())
    assert "default: sim://" in result.stdout
    assert "python examples/" in module.__doc__  # how to run it


@pytest.mark.parametrize("name", example_names())
def test_every_example_docstring_example_holds(name: str) -> None:
    results = doctest.testmod(load_example(name), raise_on_error=False, verbose=False)
    assert results.failed == 0


@pytest.mark.parametrize("name", example_names())
@pytest.mark.parametrize(
    ("url", "said"),
    [
        ("sim://?speed=2", "unknown sim option 'speed'"),
        ("/dev/ttyUSB0?baud=9600", "a serial device takes only ?baudrate=, not baud"),
    ],
)
def test_every_example_refuses_a_bad_url_as_a_usage_error(
    name: str, url: str, said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    # (It was a traceback of the ValueError raised by connect.)
    with pytest.raises(SystemExit) as exit_info:
        load_example(name).main([url])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: ")
    assert f"error: {url!r}: {said}" in err.splitlines()[-1]


@pytest.mark.parametrize(
    ("name", "option", "said"),
    [
        ("poll_sensors", "--duration", "--duration must not be negative, got nan"),
        ("dive_and_hold", "--hold", "--hold must be 0 or more, got nan"),
        ("dive_and_hold", "--reach-timeout", "--reach-timeout must be 0 or more, got nan"),
        ("async_telemetry_and_control", "--leg", "--leg must be positive, got nan"),
        ("async_telemetry_and_control", "--deadline", "--deadline must be positive, got nan"),
        ("frame_logger", "--duration", "--duration must not be negative, got nan"),
    ],
)
def test_every_example_refuses_a_number_of_seconds_that_is_not_a_number(
    name: str, option: str, said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    # (argparse's float takes "nan": a hold that never ended, a deadline never reached.)
    with pytest.raises(SystemExit) as exit_info:
        load_example(name).parse_arguments([option, "nan"])
    assert exit_info.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1].endswith(f"error: {said}")


#: A short run of each example, its arguments after the URL ("SCRIPT": a file of two lines).
SHORT_RUNS: dict[str, list[str]] = {
    "poll_sensors": ["--duration", "0.05", "--rate", "50"],
    "dive_and_hold": ["--depth", "20", "--hold", "0", "--interval", "0.05"],
    "async_telemetry_and_control": ["--depth", "5", "--leg", "0.05", "--rate", "50"],
    "frame_logger": ["--duration", "0", "--output", os.devnull],
    "script_teleop": ["--script", "SCRIPT"],
}


@pytest.mark.parametrize("name", example_names())
def test_every_example_runs_in_checksum_mode_when_asked(
    name: str, sim: KeptSim, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    # On a noisy tether a bit error can turn #mvd.100! into #mvd.900!: with --checksum the
    # controller drops it instead.
    script = tmp_path / "short.txt"
    script.write_text("start\nqd\n")
    arguments = [str(script) if word == "SCRIPT" else word for word in SHORT_RUNS[name]]
    status, out = run_example(name, sim.url, "--checksum", *arguments, capsys=capsys)
    assert status == 0, out
    assert sim.state().checksum_enabled
    sim.assert_stopped_and_locked()


# -- poll_sensors.py -----------------------------------------------------------------------------


def test_poll_sensors_prints_a_line_per_reading(
    sim: KeptSim, capsys: pytest.CaptureFixture[str]
) -> None:
    status, out = run_example(
        "poll_sensors", sim.url, "--rate", "50", "--duration", "0.2", capsys=capsys
    )
    assert status == 0
    lines = READING_LINE.findall(out)
    assert len(lines) >= 3
    summary = re.search(r"^(\d+) readings, 0 missed; \d+ frames sent, 0 timeouts", out, re.M)
    assert summary is not None, out
    assert int(summary[1]) == len(lines)
    sim.assert_stopped_and_locked()  # it never unlocked


@pytest.mark.integration
def test_poll_sensors_ends_cleanly_on_ctrl_c_and_defaults_to_the_simulator() -> None:
    status, out = interrupt_when_printed(script_command("poll_sensors", "--rate", "20"), "°")
    assert status == 0, out
    assert out.startswith("connected to simulated controller")
    assert READING_LINE.search(out), out
    assert "interrupted" in out
    assert re.search(r"^\d+ readings, 0 missed", out, re.M), out


def test_poll_sensors_refuses_a_bad_rate(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        load_example("poll_sensors").main(["--rate", "0"])
    assert exit_info.value.code == 2
    assert "--rate must be in (0, 100]" in capsys.readouterr().err


# -- dive_and_hold.py ----------------------------------------------------------------------------


def test_dive_and_hold_dives_holds_surfaces_and_locks(
    sim: KeptSim, capsys: pytest.CaptureFixture[str]
) -> None:
    status, out = run_example(
        "dive_and_hold", sim.url, "--depth", "40", "--hold", "0.2", "--reach-timeout", "10",
        "--interval", "0.05",
        capsys=capsys,
    )  # fmt: skip
    assert status == 0, out
    steps = [line for line in out.splitlines() if not line.startswith("  depth")]
    assert steps[:2] == ["unlocking", "diving to 40 cm"]
    held = re.fullmatch(r"holding (\d+) cm for 0.2 s", steps[2])
    assert held is not None, steps
    assert abs(int(held[1]) - 40) <= 10
    assert steps[3] == "surfacing"
    assert re.fullmatch(r"at the surface \(\d+ cm\)", steps[4]), steps
    assert steps[5:] == ["motors off and locked", "dive completed"]
    sim.assert_stopped_and_locked()


def test_dive_and_hold_surfaces_on_a_leak_during_the_dive(
    sim: KeptSim, capsys: pytest.CaptureFixture[str]
) -> None:
    leaked = sim.inject_leak_when(unlocked_at_depth(20))
    status, out = run_example(
        "dive_and_hold", sim.url, "--depth", "60", "--hold", "30", "--reach-timeout", "10",
        "--interval", "0.05",
        capsys=capsys,
    )  # fmt: skip
    assert leaked.is_set()
    assert status == 1
    assert re.search(r"^LEAK: the leak sensor fired at \d+ cm; aborting the dive$", out, re.M)
    after_leak = out.split("LEAK:")[1]
    assert "surfacing" in after_leak
    assert re.search(r"^at the surface \(\d+ cm\)$", after_leak, re.M), out
    assert re.search(
        r"motors off and locked\ndive aborted: the leak sensor fired at \d+ cm\n$", out
    )
    sim.assert_stopped_and_locked()
    assert sim.state().leak_latched


def test_dive_and_hold_does_not_start_with_the_leak_latch_set(
    sim: KeptSim, capsys: pytest.CaptureFixture[str]
) -> None:
    status, out = run_example("dive_and_hold", f"{sim.url}&leak_at=0", capsys=capsys)
    assert status == 1
    assert "unlocking" not in out
    assert "dive aborted: the leak sensor had fired before the dive" in out
    sim.assert_stopped_and_locked()


def test_dive_and_hold_aborts_when_the_controller_resets_while_it_holds(
    sim: KeptSim, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # A reset (a brown-out, the board's own watchdog) or a failsafe of the controller locks the
    # motors and the hull floats up: the hold must notice, not report the dive completed.
    example = load_example("dive_and_hold")
    hold = example.hold

    def reset_then_hold(rov: object, plan: object) -> None:
        port = sim.port()
        with port.lock:
            port.controller.reset()
        hold(rov, plan)

    monkeypatch.setattr(example, "hold", reset_then_hold)
    status, out = run_example(
        "dive_and_hold", sim.url, "--depth", "60", "--hold", "30", "--reach-timeout", "10",
        "--interval", "0.05",
        capsys=capsys,
    )  # fmt: skip
    assert status == 1, out
    assert "dive completed" not in out
    after_hold = out.split("holding")[1]
    assert "surfacing" in after_hold
    assert re.search(
        r"motors off and locked\ndive aborted: lost the depth while holding 60 ± 10 cm: at \d+ cm "
        r"for 3 readings \(did the controller reset or stop\?\)\n$",
        out,
    ), out
    sim.assert_stopped_and_locked()


def test_dive_and_hold_stops_the_robot_when_interrupted(
    sim: KeptSim, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    example = load_example("dive_and_hold")

    def interrupted_hold(rov: object, plan: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(example, "hold", interrupted_hold)
    status, out = run_example(
        "dive_and_hold", sim.url, "--depth", "30", "--interval", "0.05", capsys=capsys
    )
    assert status == 130
    assert out.endswith("motors off and locked\ninterrupted\n")
    sim.assert_stopped_and_locked()


def test_dive_and_hold_reports_a_lost_link_and_exits(
    sim: KeptSim, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    diving = sim.when(unlocked_at_depth(10))

    def unplug() -> None:  # (outside the port's lock: closing joins the simulation's thread)
        if diving.wait(CONDITION_TIMEOUT_S):
            sim.port().close()

    threading.Thread(target=unplug, daemon=True).start()
    status, out = run_example(
        "dive_and_hold", sim.url, "--depth", "60", "--hold", "30", "--interval", "0.05",
        capsys=capsys,
    )  # fmt: skip
    assert diving.is_set()
    assert status == 1
    assert "motors off and locked" not in out  # nothing could be sent: the controller's
    messages = [record.getMessage() for record in caplog.records]  # failsafe's job now
    assert any(message.startswith("could not send #stop!: connection lost") for message in messages)
    assert any(message.startswith("dive aborted: connection lost") for message in messages)


def stops_the_robot_on_ctrl_c(
    pty_sim: tuple[SimServer, str], name: str, arguments: list[str], printed: str
) -> None:
    """Run example ``name`` as a script on the simulator's pseudo-terminal, Ctrl-C it once it has
    printed ``printed``: it says it stopped, and the robot is locked, with nothing set."""
    server, path = pty_sim
    status, out = interrupt_when_printed(script_command(name, path, *arguments), printed)
    assert status == 130, out
    assert out.endswith("motors off and locked\ninterrupted\n")
    state = server.robot.controller.state()
    assert state.locked
    assert state.power_percent == 0
    assert state.target_depth_cm is None


@pytest.mark.integration
def test_dive_and_hold_stops_the_robot_on_ctrl_c_over_a_serial_line(
    pty_sim: tuple[SimServer, str],
) -> None:
    arguments = ["--depth", "30", "--hold", "60", "--interval", "0.05"]
    stops_the_robot_on_ctrl_c(pty_sim, "dive_and_hold", arguments, "holding")


def signal_when(
    command: list[str],
    server: SimServer,
    moving: Callable[[ControllerState], bool],
    signum: signal.Signals,
) -> tuple[int, str]:
    """Run ``command``, send it ``signum`` once the controller's state is ``moving``; its exit
    status and everything it printed."""
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        controller = server.robot.controller
        assert wait_until(lambda: moving(controller.state()) or process.poll() is not None)
        assert process.poll() is None, process.communicate()[0]
        process.send_signal(signum)
        out, _ = process.communicate(timeout=CONDITION_TIMEOUT_S)
    finally:
        process.kill()
        process.wait()
    return process.returncode, out


def assert_stopped(server: SimServer) -> None:
    """The robot is locked, with no thrust and no depth asked for."""
    # The program's last frames can still be on their way through the pseudo-terminal when it
    # has exited: the simulator reads them in its own time.
    controller = server.robot.controller
    wait_until(lambda: controller.state().locked)
    state = controller.state()
    assert state.locked
    assert state.power_percent == 0
    assert state.vertical_thrust_percent == 0
    assert state.target_depth_cm is None


#: A script that drives ahead until stopped, for script_teleop.py.
DRIVING_SCRIPT = "start\nth 0 40 for 60\n"

#: Each example that moves the robot: its arguments after the URL ("SCRIPT" for a file holding
#: DRIVING_SCRIPT), and when it is moving.
MOVING: dict[str, tuple[list[str], Callable[[ControllerState], bool]]] = {
    "dive_and_hold": (
        ["--depth", "30", "--hold", "60", "--interval", "0.05"],
        lambda state: not state.locked and state.target_depth_cm == 30,
    ),
    "async_telemetry_and_control": (  # (at 5 cm from the start: within the tolerance)
        ["--depth", "5", "--leg", "60", "--rate", "20"],
        lambda state: state.power_percent == 30,
    ),
    "frame_logger": (
        ["--duration", "60", "--output", os.devnull],
        lambda state: state.power_percent == 20,
    ),
    "script_teleop": (["--script", "SCRIPT"], lambda state: state.power_percent == 40),
}


def moving_arguments(name: str, tmp_path: Path) -> list[str]:
    """The arguments of ``MOVING[name]``, with its script written out."""
    script = tmp_path / "drive.txt"
    script.write_text(DRIVING_SCRIPT)
    return [str(script) if word == "SCRIPT" else word for word in MOVING[name][0]]


@pytest.mark.integration
@pytest.mark.parametrize(
    ("name", "signum"),
    [
        *((name, signal.SIGTERM) for name in sorted(MOVING)),
        ("dive_and_hold", signal.SIGQUIT),
        ("async_telemetry_and_control", signal.SIGQUIT),
    ],
)
def test_every_example_that_moves_stops_the_robot_on_sigterm_and_sigquit(
    realtime_pty_sim: tuple[SimServer, str], name: str, signum: signal.Signals, tmp_path: Path
) -> None:
    # kill, systemctl stop, Ctrl-\: by Python's default the process ends at once, running no
    # finally, and the robot drives on until the controller's own failsafe (off here) stops it.
    server, path = realtime_pty_sim
    command = script_command(name, path, *moving_arguments(name, tmp_path))
    status, out = signal_when(command, server, MOVING[name][1], signum)
    assert status == 130, out
    assert out.endswith("interrupted\n") or name == "frame_logger", out
    assert_stopped(server)


@pytest.mark.integration
@pytest.mark.parametrize("name", ["dive_and_hold", "async_telemetry_and_control"])
def test_every_example_that_moves_stops_the_robot_when_its_terminal_closes(
    realtime_pty_sim: tuple[SimServer, str], name: str, tmp_path: Path
) -> None:
    # An SSH session dropped: the kernel sends SIGHUP, and the terminal fails every write.
    server, path = realtime_pty_sim
    terminal = Terminal(path, *moving_arguments(name, tmp_path), script=EXAMPLES / f"{name}.py")
    try:
        controller = server.robot.controller
        assert wait_until(lambda: MOVING[name][1](controller.state()))
        terminal.hang_up()
        terminal.process.wait(timeout=CONDITION_TIMEOUT_S)
        assert terminal.process.returncode != -signal.SIGHUP
    finally:
        terminal.close()
    assert_stopped(server)


@pytest.mark.integration
def test_script_teleop_stops_the_robot_when_the_terminal_it_is_typed_on_closes(
    realtime_pty_sim: tuple[SimServer, str],
) -> None:
    server, path = realtime_pty_sim
    terminal = Terminal(path, script=EXAMPLES / "script_teleop.py")
    try:
        assert terminal.wait_shown(b"dead-man 1 s")
        terminal.type(DRIVING_SCRIPT)
        controller = server.robot.controller
        assert wait_until(lambda: controller.state().power_percent == 40)
        terminal.hang_up()
        terminal.process.wait(timeout=CONDITION_TIMEOUT_S)
        assert terminal.process.returncode != -signal.SIGHUP
    finally:
        terminal.close()
    assert_stopped(server)


# -- async_telemetry_and_control.py -------------------------------------------------------------


def test_async_telemetry_and_control_drives_the_square_and_locks(
    sim: KeptSim, capsys: pytest.CaptureFixture[str]
) -> None:
    status, out = run_example(
        "async_telemetry_and_control", sim.url, "--depth", "30", "--leg", "0.05", "--rate", "50",
        capsys=capsys,
    )  # fmt: skip
    assert status == 0, out
    pilot = [line for line in out.splitlines() if line.startswith("pilot:")]
    assert pilot[0] == "pilot: unlocking"
    assert re.fullmatch(r"pilot: at \d+ cm", pilot[1])
    assert pilot[2:6] == [
        "pilot: ahead (0°) at 30 %",
        "pilot: starboard (90°) at 30 %",
        "pilot: astern (180°) at 30 %",
        "pilot: port (270°) at 30 %",
    ]
    assert pilot[6] == "pilot: surfacing"
    assert re.fullmatch(r"pilot: at the surface \(\d+ cm\)", pilot[7])
    assert out.count("telemetry: depth") >= 3
    assert out.endswith("motors off and locked\npattern completed\n")
    sim.assert_stopped_and_locked()


def test_async_telemetry_and_control_cancels_the_pilot_at_its_deadline(
    sim: KeptSim, capsys: pytest.CaptureFixture[str]
) -> None:
    # The pilot is in its first leg (of 30 s), moving, when the deadline cancels it.
    moving = sim.when(lambda port: port.controller.state().power_percent == 30)
    status, out = run_example(
        "async_telemetry_and_control", sim.url, "--depth", "20", "--leg", "30", "--rate", "50",
        "--deadline", "1", capsys=capsys,
    )  # fmt: skip
    assert moving.is_set()
    assert status == 1
    assert "pilot: ahead (0°) at 30 %" in out
    assert "pilot: starboard" not in out
    assert out.endswith(
        "motors off and locked\nrun aborted: the run took longer than its deadline of 1 s\n"
    )
    sim.assert_stopped_and_locked()


@pytest.mark.integration
def test_async_telemetry_and_control_stops_the_robot_on_ctrl_c_over_a_serial_line(
    pty_sim: tuple[SimServer, str],
) -> None:
    arguments = ["--depth", "20", "--leg", "60", "--rate", "20"]
    stops_the_robot_on_ctrl_c(pty_sim, "async_telemetry_and_control", arguments, "pilot: ahead")


def test_async_telemetry_and_control_ends_on_a_leak(
    sim: KeptSim, capsys: pytest.CaptureFixture[str]
) -> None:
    leaked = sim.inject_leak_when(unlocked_at_depth(10))
    status, out = run_example(
        "async_telemetry_and_control", sim.url, "--depth", "60", "--leg", "30", "--rate", "50",
        capsys=capsys,
    )  # fmt: skip
    assert leaked.is_set()
    assert status == 1
    assert re.search(r"motors off and locked\nrun aborted: the leak sensor fired at \d+ cm\n$", out)
    sim.assert_stopped_and_locked()


def test_async_telemetry_and_control_ends_when_the_controller_resets_while_it_drives(
    sim: KeptSim, capsys: pytest.CaptureFixture[str]
) -> None:
    # The controller comes back locked and the hull floats up: the run must not say completed.
    reset = sim.when(
        lambda port: port.controller.state().power_percent == 30,
        lambda port: port.controller.reset(),
    )
    status, out = run_example(
        "async_telemetry_and_control", sim.url, "--depth", "60", "--leg", "0.5", "--rate", "50",
        capsys=capsys,
    )  # fmt: skip
    assert reset.is_set()
    assert status == 1, out
    assert re.search(
        r"motors off and locked\nrun aborted: lost the depth while holding 60 ± 10 cm: at \d+ cm "
        r"for 3 readings \(did the controller reset or stop\?\)\n$",
        out,
    ), out
    sim.assert_stopped_and_locked()


def test_async_telemetry_and_control_watchdog_ends_on_stale_telemetry() -> None:
    import asyncio

    example = load_example("async_telemetry_and_control")

    async def stale() -> str:
        telemetry = example.Telemetry()
        telemetry.received_at -= 10.0  # the last reading came ten seconds ago
        with pytest.raises(example.RunAbortedError) as error:
            await example.watch_telemetry(example.Plan(stale_s=0.05), telemetry)
        return str(error.value)

    assert re.fullmatch(r"no telemetry for \d+\.\d s", asyncio.run(stale()))


# -- frame_logger.py -----------------------------------------------------------------------------


def test_frame_logger_writes_every_event_both_ways_as_json_lines(
    sim: KeptSim, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    output = tmp_path / "session.jsonl"
    status, out = run_example(
        "frame_logger", sim.url, "--output", str(output), "--duration", "0.1", capsys=capsys
    )
    assert status == 0
    records = [json.loads(line) for line in output.read_text().splitlines()]
    assert out == f"{len(records)} events written to {output}\n"
    assert {record["direction"] for record in records} >= {"out", "in"}
    times = [record["t_s"] for record in records]
    assert times[0] == 0.0
    assert times == sorted(times)
    sent = [record["data"] for record in records if record["event"] == "BytesSent"]
    assert sent[-1] == "#stop!"
    assert {"#qsa!", "#start!", "#th.0.20!", "#th.0.0!"} <= set(sent)
    (reply,) = [record for record in records if record["event"] == "ReplyReceived"]
    assert reply["query"] == "#qsa!"
    assert len(reply["responses"]) == 6
    assert reply["responses"][0].startswith("$qd.")
    sim.assert_stopped_and_locked()


def test_frame_logger_keeps_the_event_name_of_what_answered_no_query() -> None:
    # Unsolicited's own field is named "event": it overwrote the line's event name with a repr.
    stream = io.StringIO()
    frame_log = load_example("frame_logger").FrameLog(stream)
    for what in (
        Text("debug: max PWM 200 (was 255)"),
        BadFrame(Reason.MALFORMED, b"$qr\x0e", "byte 0x0e inside a frame"),
        Frame(Response("qd", (12,)), b"$qd.12!"),
    ):
        frame_log(Unsolicited(1.5, what))
    records = [json.loads(line) for line in stream.getvalue().splitlines()]
    assert [record["event"] for record in records] == ["Unsolicited"] * 3
    assert [record["unsolicited"] for record in records] == [
        {"type": "Text", "text": "debug: max PWM 200 (was 255)"},
        {
            "type": "BadFrame",
            "reason": "malformed",
            "raw": "$qr\x0e",
            "detail": "byte 0x0e inside a frame",
        },
        {"type": "Frame", "message": "$qd.12!", "raw": "$qd.12!"},
    ]


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full (Linux)")
def test_frame_logger_stops_the_log_not_the_session_when_the_output_fails(
    sim: KeptSim, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    status, out = run_example(
        "frame_logger", sim.url, "--output", "/dev/full", "--duration", "0.1", capsys=capsys
    )
    assert status == 1
    assert out == ""
    errors = [record.getMessage() for record in caplog.records if record.levelname == "ERROR"]
    assert errors == ["the frame log stopped after 0 lines: [Errno 28] No space left on device"]
    sim.assert_stopped_and_locked()  # the session went on to its #stop!


@pytest.mark.integration
def test_frame_logger_writes_to_standard_output_as_a_script(tmp_path: Path) -> None:
    config = tmp_path / "fast.toml"
    config.write_text("[controller]\nwatchdog_s = 0\n")
    url = f"sim://?realtime=0&seed=1&config={config}"
    result = subprocess.run(
        script_command("frame_logger", url, "--duration", "0"),
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    records = [json.loads(line) for line in result.stdout.splitlines()]
    assert records[-1]["data"] == "#stop!"
    assert all(record["utc"].endswith("+00:00") for record in records)


# -- script_teleop.py ----------------------------------------------------------------------------


def test_script_teleop_runs_a_script_with_the_dead_man(
    sim: KeptSim, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    script = tmp_path / "square.txt"
    script.write_text(
        "# a short run\n"
        "start\n"
        "mvd 30\n"
        "qd\n"
        "th 90 30 for 0.2\n"
        "th 0 20\n"
        "wait 0.6\n"  # th 0 20 is not renewed: the dead-man zeroes it
        "qsa\n"
    )
    status, out = run_example(
        "script_teleop", sim.url, "--script", str(script), "--deadman", "0.1", capsys=capsys
    )
    assert status == 0
    lines = out.splitlines()
    assert lines[0] == "connected to simulated controller; dead-man 0.1 s"
    assert re.fullmatch(r"< \$qd\.\d+!", lines[1])
    assert "dead-man: no thrust command renewed in time, sent #th.0.0!" in lines
    replies = [line for line in lines if line.startswith("< $")]
    assert len(replies) == 1 + 6
    assert lines[-1] == "motors off and locked"
    sim.assert_stopped_and_locked()


def test_script_teleop_drives_the_vertical_thrusters_as_its_docstring_says(
    sim: KeptSim, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    # mvs acts in direct mode only: the docstring once showed it alone, and it did nothing.
    assert "``mvdirect 1`` then ``mvs -20``" in load_example("script_teleop").__doc__
    thrusting = sim.when(lambda port: port.controller.state().vertical_thrust_percent == -20)
    script = tmp_path / "down.txt"
    script.write_text("start\nmvdirect 1\nmvs -20 for 0.5\n")
    status, out = run_example("script_teleop", sim.url, "--script", str(script), capsys=capsys)
    assert status == 0, out
    assert thrusting.wait(CONDITION_TIMEOUT_S)
    sim.assert_stopped_and_locked()


def test_script_teleop_checks_a_whole_script_before_sending_anything(
    sim: KeptSim, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    script = tmp_path / "typos.txt"
    script.write_text("start\nth 400 10\nmvd 50\nqd for 2\nwait soon\n")
    status = load_example("script_teleop").main([sim.url, "--script", str(script)])
    err = capsys.readouterr().err
    assert status == 2
    assert err == (
        f"{script}: nothing sent:\n"
        "line 2: th: direction_deg must be in 0–360, got 400\n"
        "line 4: 'for' renews a thrust command (th, mvs), not qd\n"
        "line 5: 'soon' is not a number of seconds (0–3600)\n"
    )
    assert kept_sim.OPENED == []  # never connected


def test_script_teleop_skips_a_wrong_typed_line_and_goes_on(
    sim: KeptSim, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(sys, "stdin", io.StringIO("start\nthrust 1\nmvs -20\nqd\n"))
    status, out = run_example("script_teleop", sim.url, capsys=capsys)
    assert status == 0
    assert "line 2: unknown command 'thrust'; did you mean th?" in out
    assert re.search(r"^< \$qd\.\d+!$", out, re.M)  # the lines after it were sent
    assert out.endswith("motors off and locked\n")
    sim.assert_stopped_and_locked()


def test_script_teleop_parses_commands_waits_and_renewals() -> None:
    example: ModuleType = load_example("script_teleop")
    assert example.parse_line("  # a comment", 1) is None
    assert example.parse_line("#qd!", 2).command.name == "qd"
    assert example.parse_line("wait 1.5", 3).seconds == 1.5
    step = example.parse_line("mvs -20 for 2", 4)
    assert (str(step.command), step.seconds) == ("#mvs.-20!", 2.0)
    assert str(example.zero_thrust(step.command)) == "#mvs.+0!"
