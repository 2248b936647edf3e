"""Ctrl-C ends a command at once, after ``#stop!`` where the robot may have moved; a query with
no reply fails. Against a controller that never answers: a TCP listener that only reads (or,
for a command that waits for the controller on connect, one that answers ``#qd!`` alone)."""

from __future__ import annotations

import errno
import io
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, cast

import pytest

from rovlink.cli.interrupt import say_ready, suspension_refused_by
from rovlink.recorder import FrameEntry, HeaderEntry, read_entries
from rovlink.recorder.formats import open_sink
from tests.board.rig import fake_toml
from tests.cli.conftest import RunCli
from tests.cli.silent_controller import WAIT_S, SilentController
from tests.terminals import Terminal

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer

pytestmark = pytest.mark.integration

#: Generous: the command should exit in a few milliseconds; a loaded machine is slower.
EXIT_BOUND_S = 1.5


class DepthAnsweringController(SilentController):
    """Answers each ``#qd!`` (the readiness probe, the keep-alive, a query) with ``$qd.0!``, so
    that a command connects with its default readiness wait, and each ``#q.l!`` with
    ``$q.l.0!`` (no leak: the demo asks before it dives); never answers anything else.
    With ``hang_up_after``, closes the connection once that frame has arrived."""

    def __init__(self, hang_up_after: bytes | None = None) -> None:
        self._hang_up_after = hang_up_after
        super().__init__()

    def _serve(self) -> None:
        connection, _ = self._server.accept()
        with connection:
            while data := connection.recv(4096):
                with self._changed:
                    asked = self._asked()
                    self.received += data
                    self._changed.notify_all()
                    # Counted over everything received: a frame split between reads counts too.
                    answers = self._asked()[len(asked) :]
                    hang_up = self._hang_up_after is not None and self._hang_up_after in data
                connection.sendall(b"".join(_ANSWERS[query] for query in answers))
                if hang_up:
                    return

    def _asked(self) -> list[bytes]:
        """The queries answered, in the order received."""
        return re.findall(rb"#qd!|#q\.l!", self.received)


_ANSWERS = {b"#qd!": b"$qd.0!", b"#q.l!": b"$q.l.0!"}


@pytest.fixture
def answering() -> Iterator[DepthAnsweringController]:
    controller = DepthAnsweringController()
    yield controller
    controller.close()


def _ignore_ctrl_c() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a shell starts a background job (&)


def _rovlink(
    *arguments: str, background: bool = False, silent_controller: bool = True
) -> subprocess.Popen[bytes]:
    source = str(Path(__file__).resolve().parents[2] / "src")
    environment = {**os.environ, "PYTHONPATH": source}
    if silent_controller:
        # --boot-timeout 0 lets the command reach its own wait (not the readiness probe's)
        # before the test interrupts it.
        arguments = (arguments[0], "--boot-timeout", "0", *arguments[1:])
    return subprocess.Popen(
        [sys.executable, "-m", "rovlink", *arguments],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=environment,
        preexec_fn=_ignore_ctrl_c if background else None,  # noqa: PLW1509 - no threads yet
    )


def _interrupt(
    process: subprocess.Popen[bytes], how: signal.Signals = signal.SIGINT
) -> tuple[float, bytes]:
    started = time.monotonic()
    process.send_signal(how)
    _, stderr = process.communicate(timeout=WAIT_S)
    return time.monotonic() - started, stderr


#: Ctrl-C, and what ends a program otherwise: kill and service managers (SIGTERM), a closed
#: terminal or SSH session (SIGHUP), the Ctrl-\ key of a terminal not in raw mode (SIGQUIT).
#: Each ends a command as Ctrl-C does.
ENDING_SIGNALS = [signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT]


@pytest.mark.realtime
def test_ctrl_c_ends_send_waiting_for_a_silent_controller_at_once(silent: SilentController) -> None:
    process = _rovlink("send", silent.url, "qd", "--timeout", "60")
    assert silent.wait_for(b"#qd!")
    elapsed_s, stderr = _interrupt(process)
    assert process.returncode == 130
    assert elapsed_s < EXIT_BOUND_S
    assert stderr.decode().splitlines()[-1] == "rovlink send: interrupted"
    assert b"#stop!" not in silent.received  # only a query was sent: nothing moved


@pytest.mark.parametrize("how", ENDING_SIGNALS, ids=lambda how: how.name)
@pytest.mark.realtime
def test_a_signal_after_a_motion_command_sends_stop_first(
    silent: SilentController, how: signal.Signals
) -> None:
    process = _rovlink("send", silent.url, "start", "th 0 30", "qd", "--timeout", "60")
    assert silent.wait_for(b"#qd!")
    elapsed_s, stderr = _interrupt(process, how)
    assert process.returncode == 130
    assert elapsed_s < EXIT_BOUND_S
    assert stderr.decode().splitlines()[-1] == "rovlink send: interrupted"
    assert silent.wait_for(b"#stop!")
    assert silent.received.index(b"#stop!") > silent.received.index(b"#th.0.30!")


@pytest.mark.parametrize("how", ENDING_SIGNALS, ids=lambda how: how.name)
@pytest.mark.realtime
def test_a_signal_ends_the_demo_with_stop_and_its_recording_finished(
    answering: DepthAnsweringController, how: signal.Signals, tmp_path: Path
) -> None:
    recording = tmp_path / "dive.jsonl"
    process = _rovlink("demo", answering.url, "--timeout", "60", "--record", str(recording))
    assert answering.wait_for(b"#qsa!")  # unlocked, diving, polling the sensors
    elapsed_s, stderr = _interrupt(process, how)
    assert process.returncode == 130
    assert elapsed_s < EXIT_BOUND_S
    assert answering.wait_for(b"#stop!")
    assert "recorded" in stderr.decode()  # the summary line of a finished recording
    entries = [json.loads(line) for line in recording.read_text(encoding="utf-8").splitlines()]
    sent = [
        entry["name"]
        for entry in entries
        if entry["channel"] == "frames" and entry["direction"] == "out"
    ]
    assert sent[-1] == "stop"


def _write_cut_dive(path: Path, *, query_at_s: float) -> None:
    """A recording of ``start``, ``th 0 50`` and, ``query_at_s`` later, ``qd``, without its
    end (a ``--split`` part, a killed recorder): it leaves the robot unlocked and moving."""
    sink = open_sink(str(path))
    sink.write(HeaderEntry(1.0, 1, "socket://", False, "crc8", "test", "0"))
    sink.write(FrameEntry(2.0, 2, "out", "command", "start", ()))
    sink.write(FrameEntry(2.1, 3, "out", "command", "th", (0, 50)))
    sink.write(FrameEntry(2.1 + query_at_s, 4, "out", "command", "qd", ()))
    sink.close()


@pytest.mark.parametrize("how", ENDING_SIGNALS, ids=lambda how: how.name)
@pytest.mark.realtime
def test_a_signal_ends_a_replay_to_a_controller_with_stop(
    answering: DepthAnsweringController, how: signal.Signals, tmp_path: Path
) -> None:
    recording = tmp_path / "cut.jsonl"
    _write_cut_dive(recording, query_at_s=60.0)  # the replay waits for its time
    process = _rovlink("replay", str(recording), "--to", answering.url, silent_controller=False)
    assert answering.wait_for(b"#th.0.50!")
    elapsed_s, stderr = _interrupt(process, how)
    assert process.returncode == 130, stderr
    assert elapsed_s < EXIT_BOUND_S
    assert stderr.decode().splitlines()[-2:] == [
        "rovlink replay: sent #stop!",
        "rovlink replay: interrupted",
    ]
    assert answering.wait_for(b"#stop!")
    assert answering.received.index(b"#stop!") > answering.received.index(b"#th.0.50!")


def test_a_replay_whose_controller_hangs_up_fails_in_one_line(
    run_cli: RunCli, tmp_path: Path
) -> None:
    recording = tmp_path / "cut.jsonl"
    _write_cut_dive(recording, query_at_s=0.2)
    controller = DepthAnsweringController(hang_up_after=b"#th.0.50!")
    try:
        result = run_cli("replay", str(recording), "--to", controller.url)
    finally:
        controller.close()
    assert result.status == 1
    lines = result.err.splitlines()
    assert lines[0].startswith("replaying 3 commands of")
    # The robot may move on: said so (its controller's link-loss watchdog stops it).
    assert lines[1].startswith("rovlink replay: could not send #stop!: ")
    assert lines[2].startswith(f"rovlink replay: {controller.url}: ")
    assert len(lines) == 3


def test_a_demo_whose_link_is_lost_says_stop_could_not_be_sent(run_cli: RunCli) -> None:
    # The controller hangs up at the first sensor poll: nothing more can be sent, and the
    # demo says so (it claimed "the robot was sent #stop!").
    controller = DepthAnsweringController(hang_up_after=b"#qsa!")
    try:
        result = run_cli("demo", controller.url, "--timeout", "5")
    finally:
        controller.close()
    assert result.status == 1
    lines = result.err.splitlines()
    assert lines[-2].startswith("rovlink demo: could not send #stop!: ")
    assert lines[-1].startswith("rovlink demo: ")
    assert "sent #stop!" not in lines[-1]


def _drive_ahead_in_the_console(terminal: Terminal, silent: SilentController) -> None:
    """Once the console is connected: unlock and thrust ahead at 50 %, as a pilot types it."""
    assert silent.wait_for(b"#crcoff!")
    terminal.type("start\r")
    assert silent.wait_for(b"#start!")
    terminal.type("th 0 50\r")
    assert silent.wait_for(b"#th.0.50!")


@pytest.mark.parametrize("how", ENDING_SIGNALS, ids=lambda how: how.name)
@pytest.mark.realtime
def test_a_signal_ends_the_console_with_stop(silent: SilentController, how: signal.Signals) -> None:
    # kill -INT is no Ctrl-C key (the terminal is in raw mode, the key only drops the line):
    # it, kill and a closed terminal end the console, #stop! first.
    # (Leaving waits for the queries on the wire, up to --timeout: a short one.)
    terminal = Terminal("console", silent.url, "--boot-timeout", "0", "--timeout", "0.2")
    try:
        _drive_ahead_in_the_console(terminal, silent)
        elapsed_s, stderr = _interrupt(terminal.process, how)
        assert terminal.process.returncode == 130, stderr
        assert elapsed_s < EXIT_BOUND_S
        assert silent.wait_for(b"#stop!")
        assert silent.received.index(b"#stop!") > silent.received.index(b"#th.0.50!")
    finally:
        terminal.close()


def _drive_ahead_in_the_monitor(terminal: Terminal, silent: SilentController) -> None:
    """Once the dashboard polls: unlock (``s``) and thrust ahead (up), as a pilot does."""
    assert silent.wait_for(b"#qsa!")
    terminal.type("s")
    assert silent.wait_for(b"#start!")
    terminal.type("\x1b[A")
    assert silent.wait_for(b"#th.0.")


@pytest.mark.parametrize("how", ENDING_SIGNALS, ids=lambda how: how.name)
def test_a_signal_ends_the_monitor_with_stop(silent: SilentController, how: signal.Signals) -> None:
    terminal = Terminal(
        "monitor", silent.url, "--boot-timeout", "0", "--timeout", "0.2", stderr_on_terminal=True
    )
    try:
        _drive_ahead_in_the_monitor(terminal, silent)
        _interrupt(terminal.process, how)
        assert terminal.process.returncode == 130, terminal.shown  # (before: 0, as after `q`)
        assert silent.wait_for(b"#stop!")
        assert silent.received.rindex(b"#stop!") > silent.received.index(b"#th.0.")
    finally:
        terminal.close()


def test_the_ctrl_c_key_quits_the_monitor_as_q_does(silent: SilentController) -> None:
    # In the dashboard's raw terminal Ctrl-C is a key, not SIGINT: #stop! then status 0, as
    # after q (a SIGINT ends it with 130: above). docs/tools.md says so.
    terminal = Terminal(
        "monitor", silent.url, "--boot-timeout", "0", "--timeout", "0.2", stderr_on_terminal=True
    )
    try:
        _drive_ahead_in_the_monitor(terminal, silent)
        terminal.type("\x03")
        assert terminal.process.wait(timeout=WAIT_S) == 0, terminal.shown
        assert silent.wait_for(b"#stop!")
        assert silent.received.rindex(b"#stop!") > silent.received.index(b"#th.0.")
    finally:
        terminal.close()


#: The monitor with a defect: its power keys fail once they have sent their frame.
_FAILING_MONITOR = """\
import sys

from rovlink.cli import main
from rovlink.monitor.app import MonitorApp

power = MonitorApp.action_power


async def failing_power(self: MonitorApp, step_percent: int) -> None:
    await power(self, step_percent)
    raise RuntimeError("a defect of the dashboard's")


MonitorApp.action_power = failing_power
sys.exit(main(sys.argv[1:]))
"""


def test_a_monitor_that_fails_stops_the_robot_and_exits_1(
    silent: SilentController, tmp_path: Path
) -> None:
    # Before, an error inside the dashboard (textual shows it and ends the app) stopped the
    # robot but ended the command with status 0, as if the pilot had quit.
    script = tmp_path / "failing_monitor.py"
    script.write_text(_FAILING_MONITOR, encoding="utf-8")
    terminal = Terminal(
        "monitor",
        silent.url,
        "--boot-timeout",
        "0",
        "--timeout",
        "0.2",
        script=script,
        stderr_on_terminal=True,
    )
    try:
        _drive_ahead_in_the_monitor(terminal, silent)  # (the up key fails)
        assert terminal.process.wait(timeout=WAIT_S) == 1, terminal.shown
        assert terminal.wait_shown(b"a defect of the dashboard's")
        assert silent.wait_for(b"#stop!")
        assert silent.received.rindex(b"#stop!") > silent.received.index(b"#th.0.")
    finally:
        terminal.close()


def test_sigtstp_does_not_suspend_the_monitor(silent: SilentController) -> None:
    # Before, textual's handler stopped the process on SIGTSTP (a Ctrl-Z where the terminal's
    # signal keys are on, a `kill -TSTP`): the dashboard, its keys and its keep-alives stopped
    # with the robot moving, as the console refuses to.
    terminal = Terminal(
        "monitor",
        silent.url,
        "--boot-timeout",
        "0",
        "--timeout",
        "0.2",
        job_control=True,
        stderr_on_terminal=True,
    )
    try:
        _drive_ahead_in_the_monitor(terminal, silent)
        terminal.signal_keys_on()
        terminal.type("\x1a")  # (sends SIGTSTP to the monitor's process group)
        assert terminal.wait_until(lambda shown: b"does not suspend" in shown or b"job" in shown)
        assert b"[job ended" not in terminal.shown
        terminal.type("q")  # still at the helm
        assert terminal.process.wait(timeout=WAIT_S) == 0
        assert silent.received.rindex(b"#stop!") > silent.received.index(b"#th.0.")
    finally:
        terminal.close()


def test_ctrl_z_does_not_suspend_send_that_has_moved_the_robot(silent: SilentController) -> None:
    # Before, Ctrl-Z stopped `send` while it waited for a reply after a motion command: the
    # robot went on with it unattended, and the #stop! that ends such a line never came.
    terminal = Terminal(
        "send",
        silent.url,
        "start",
        "th 0 30",
        "qd",
        "--boot-timeout",
        "0",
        "--timeout",
        "60",
        job_control=True,
        stderr_on_terminal=True,
    )
    try:
        assert silent.wait_for(b"#qd!")  # moving, waiting for the reply
        terminal.type("\x1a")  # (its terminal is in cooked mode: SIGTSTP to its group)
        assert terminal.wait_until(lambda shown: b"does not suspend" in shown or b"job" in shown)
        assert b"[job ended" not in terminal.shown
        terminal.type("\x03")  # still running: Ctrl-C ends it, with #stop!
        assert terminal.wait_shown(b"[job ended: 130]")
        assert silent.wait_for(b"#stop!")
        assert silent.received.rindex(b"#stop!") > silent.received.index(b"#th.0.30!")
    finally:
        terminal.close()


def test_ctrl_z_does_not_suspend_the_demo(answering: DepthAnsweringController) -> None:
    # Before, Ctrl-Z stopped the demo mid-dive: the robot went on unattended with what it was
    # last sent, and back in the foreground the dive called each step done though the
    # controller's watchdog had locked the motors meanwhile.
    terminal = Terminal(
        "demo",
        answering.url,
        "--boot-timeout",
        "0",
        "--timeout",
        "60",
        job_control=True,
        stderr_on_terminal=True,
    )
    try:
        assert answering.wait_for(b"#qsa!")  # unlocked, diving, polling the sensors
        terminal.type("\x1a")  # (its terminal is in cooked mode: SIGTSTP to the demo's group)
        assert terminal.wait_until(lambda shown: b"does not suspend" in shown or b"job" in shown)
        assert b"[job ended" not in terminal.shown
        terminal.type("\x03")  # still running: Ctrl-C ends it, with #stop!
        assert terminal.wait_shown(b"[job ended: 130]")
        assert answering.wait_for(b"#stop!")
        assert answering.received.rindex(b"#stop!") > answering.received.index(b"#mvd.")
    finally:
        terminal.close()


def _refuses_ctrl_z(terminal: Terminal) -> None:
    """Type Ctrl-Z at a command that has set the robot moving (its terminal is in cooked mode:
    SIGTSTP to its group): it goes on, saying so, and Ctrl-C then ends it (status 130)."""
    terminal.type("\x1a")
    assert terminal.wait_until(lambda shown: b"does not suspend" in shown or b"job" in shown)
    assert b"[job ended" not in terminal.shown
    terminal.type("\x03")
    assert terminal.wait_shown(b"[job ended: 130]")


def test_ctrl_z_does_not_suspend_a_replay_that_moves_the_robot(
    answering: DepthAnsweringController, tmp_path: Path
) -> None:
    # Before, Ctrl-Z stopped a replay that had unlocked the robot and set it moving: it went
    # on with the replayed thrust unattended, and the #stop! that ends a replay never came.
    recording = tmp_path / "cut.jsonl"
    _write_cut_dive(recording, query_at_s=60.0)  # the replay waits for its time
    terminal = Terminal(
        "replay", str(recording), "--to", answering.url, job_control=True, stderr_on_terminal=True
    )
    try:
        assert answering.wait_for(b"#th.0.50!")
        _refuses_ctrl_z(terminal)
        assert answering.wait_for(b"#stop!")
        assert answering.received.rindex(b"#stop!") > answering.received.index(b"#th.0.50!")
    finally:
        terminal.close()


def test_ctrl_z_does_not_suspend_a_motion_check(answering: DepthAnsweringController) -> None:
    # Before, Ctrl-Z stopped `check --motion` with the vertical thrusters running (here while
    # the check waits for the #qr! it is never answered).
    terminal = Terminal(
        "check",
        answering.url,
        "--motion",
        "--yes",
        "--only",
        "motion-stop-halts",
        "--timeout",
        "10",  # (its most)
        job_control=True,
        stderr_on_terminal=True,
    )
    try:
        assert answering.wait_for(b"#mvs.-30!#qr!")  # unlocked, diving, waiting
        _refuses_ctrl_z(terminal)
        assert answering.wait_for(b"#stop!")
        assert answering.received.rindex(b"#stop!") > answering.received.index(b"#mvs.-30!")
    finally:
        terminal.close()


def test_ctrl_z_does_not_suspend_the_tune() -> None:
    # Before, Ctrl-Z stopped the tune's relay experiment with its thrust on: the vehicle went
    # on diving or rising unattended, past the depth limits the tune watches.
    terminal = Terminal("tune", "sim://", "--yes", job_control=True, stderr_on_terminal=True)
    try:
        assert terminal.wait_shown(b"motors unlocked: relay")
        _refuses_ctrl_z(terminal)
        assert b"#stop! sent" in terminal.shown
    finally:
        terminal.close()


def _end_of(terminal: Terminal) -> str:
    """What the command said on stderr once it has ended (within WAIT_S)."""
    _, stderr = terminal.process.communicate(timeout=WAIT_S)
    return stderr.decode()


def test_closing_the_terminal_ends_the_demo_with_stop(answering: DepthAnsweringController) -> None:
    # The live table cannot be taken down on a closed terminal: #stop! goes first all the same.
    terminal = Terminal("demo", answering.url, "--boot-timeout", "0", "--timeout", "60")
    try:
        assert answering.wait_for(b"#qsa!")  # unlocked, diving, polling the sensors
        terminal.hang_up()
        stderr = _end_of(terminal)
        assert terminal.process.returncode == 130, stderr
        assert answering.wait_for(b"#stop!")
        assert stderr.splitlines()[-2:] == [
            "rovlink demo: sent #stop!",
            "rovlink demo: interrupted",
        ]
    finally:
        terminal.close()


def test_closing_the_terminal_ends_the_console_as_interrupted(silent: SilentController) -> None:
    terminal = Terminal("console", silent.url, "--boot-timeout", "0", "--timeout", "0.2")
    try:
        _drive_ahead_in_the_console(terminal, silent)
        terminal.hang_up()
        stderr = _end_of(terminal)
        assert terminal.process.returncode == 130, stderr
        assert stderr.splitlines()[-1] == "rovlink console: interrupted"
        assert silent.wait_for(b"#stop!")
        assert silent.received.index(b"#stop!") > silent.received.index(b"#th.0.50!")
    finally:
        terminal.close()


@pytest.mark.parametrize("command", ["console", "demo"])
def test_a_closed_terminal_that_was_stderr_too_still_ends_with_130(
    answering: DepthAnsweringController, command: str
) -> None:
    # As a user runs them, stderr is the terminal: its last line cannot be written once it is
    # closed, and that write's error made the status 1.
    terminal = Terminal(
        command, answering.url, "--boot-timeout", "0", "--timeout", "60", stderr_on_terminal=True
    )
    try:
        if command == "console":
            assert answering.wait_for(b"#crcoff!")
            terminal.type("start\r")
            assert answering.wait_for(b"#start!")
        else:
            assert answering.wait_for(b"#qsa!")  # unlocked, diving, polling the sensors
        terminal.hang_up()
        assert terminal.process.wait(timeout=WAIT_S) == 130
        assert answering.wait_for(b"#stop!")
    finally:
        terminal.close()


def test_closing_the_terminal_ends_the_monitor_with_stop(silent: SilentController) -> None:
    # The dashboard draws on stderr: that is the terminal too, as a user runs it.
    terminal = Terminal(
        "monitor", silent.url, "--boot-timeout", "0", "--timeout", "0.2", stderr_on_terminal=True
    )
    try:
        _drive_ahead_in_the_monitor(terminal, silent)
        terminal.hang_up()
        assert terminal.process.wait(timeout=WAIT_S) == 130  # (was 1: "cannot write")
        assert silent.wait_for(b"#stop!")
        assert silent.received.rindex(b"#stop!") > silent.received.index(b"#th.0.")
    finally:
        terminal.close()


def _shown(terminal: Terminal, text: bytes) -> bool:
    """Whether ``text`` appeared on the terminal within the tests' wait (polled: the terminal
    is drained by a thread of its own)."""
    deadline = time.monotonic() + WAIT_S
    while text not in terminal.shown:
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_a_closed_terminal_ends_a_recording_command_with_130_and_its_file_finished(
    answering: DepthAnsweringController, tmp_path: Path
) -> None:
    # The recording's summary line could not be written on the closed terminal, and that
    # write's error made the status 1 (the file was finished first).
    recording = tmp_path / "dive.jsonl"
    terminal = Terminal(
        "demo",
        answering.url,
        "--boot-timeout",
        "0",
        "--timeout",
        "60",
        "--record",
        str(recording),
        stderr_on_terminal=True,
    )
    try:
        assert answering.wait_for(b"#qsa!")  # unlocked, diving, polling the sensors
        terminal.hang_up()
        assert terminal.process.wait(timeout=WAIT_S) == 130
        assert answering.wait_for(b"#stop!")
    finally:
        terminal.close()
    sent = [
        entry.name
        for entry in read_entries(str(recording))  # read to its end: finished, undamaged
        if isinstance(entry, FrameEntry) and entry.direction == "out"
    ]
    assert sent[-1] == "stop"


@pytest.mark.parametrize("command", ["record", "fault"])
def test_a_closed_terminal_ends_a_serving_command_with_0_and_stop(
    silent: SilentController, tmp_path: Path, command: str
) -> None:
    # As for a service stopped (SIGTERM): status 0, documented. Their last lines (what was
    # recorded, the fault counters) could not be written on the closed terminal, and that
    # write's error made the status 1.
    port = _free_port()
    program_side = f"socket://127.0.0.1:{port}"
    recording = tmp_path / "tapped.jsonl"
    arguments = (
        ("record", silent.url, "-o", str(recording), "--tap", program_side)
        if command == "record"
        else ("fault", "--listen", program_side, "--to", silent.url)
    )
    terminal = Terminal(*arguments, stderr_on_terminal=True)
    try:
        assert _shown(terminal, b"Ctrl-C stops")
        with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as program:
            program.sendall(b"#start!#th.0.50!")
            assert silent.wait_for(b"#th.0.50!")
            terminal.hang_up()
            assert terminal.process.wait(timeout=WAIT_S) == 0
        assert silent.wait_for(b"#stop!")
    finally:
        terminal.close()
    if command == "record":
        names = [e.name for e in read_entries(str(recording)) if isinstance(e, FrameEntry)]
        assert names[-1] == "stop"


class _TerminalClosingAfterOneWrite(io.RawIOBase):
    """A terminal closed as soon as the first thing written shows: later writes fail (EIO)."""

    def __init__(self) -> None:
        self.written: list[bytes] = []

    def writable(self) -> bool:
        return True

    def write(self, data: ReadableBuffer, /) -> int:
        if self.written:
            raise OSError(errno.EIO, "Input/output error")
        self.written.append(bytes(data))
        return len(self.written[0])


@pytest.mark.parametrize("unbuffered", [True, False], ids=["PYTHONUNBUFFERED", "buffered"])
def test_a_ready_line_goes_to_the_terminal_in_one_write(unbuffered: bool) -> None:
    # Standard output as Python sets it up for a terminal, with PYTHONUNBUFFERED=1 (as many
    # services and containers run) or without. print writes a line and its end apart when
    # unbuffered: a terminal closed as soon as the line showed failed the end's write.
    terminal = _TerminalClosingAfterOneWrite()
    # (with -u Python wraps the raw file itself, which typeshed's TextIOWrapper does not allow)
    buffer = cast("io.BufferedWriter", terminal) if unbuffered else io.BufferedWriter(terminal)
    stdout = io.TextIOWrapper(buffer, line_buffering=not unbuffered, write_through=unbuffered)
    line = "rovlink sim ready: tcp 127.0.0.1:5760 (seed 1, unpaced); Ctrl-C stops"
    say_ready(line, stream=stdout)
    assert terminal.written == [f"{line}\n".encode()]


def test_a_closed_terminal_ends_the_simulator_with_0() -> None:
    terminal = Terminal("sim", "--tcp", "0", stderr_on_terminal=True)
    try:
        assert _shown(terminal, b"Ctrl-C stops")
        terminal.hang_up()
        assert terminal.process.wait(timeout=WAIT_S) == 0  # (was 1: "rovlink sim stopped")
    finally:
        terminal.close()


@pytest.mark.parametrize("board", ["sim", "pi"])
def test_a_closed_terminal_ends_the_controller_with_0(board: str, tmp_path: Path) -> None:
    arguments = ["controller", "--board", board, "--tcp", "127.0.0.1:0"]
    if board == "pi":  # the example rov.toml on fake devices
        arguments += ["--config", str(fake_toml(tmp_path, tmp_path / "i2c.log"))]
    terminal = Terminal(*arguments, stderr_on_terminal=True)
    try:
        assert _shown(terminal, b"Ctrl-C stops")
        terminal.hang_up()
        assert terminal.process.wait(timeout=WAIT_S) == 0  # (was 1: "rovlink controller stopped")
    finally:
        terminal.close()


def test_a_query_without_a_reply_fails_in_one_line(
    run_cli: RunCli, silent: SilentController
) -> None:
    result = run_cli(
        "send", silent.url, "qd", "--timeout", "0.05", "--retries", "0", "--boot-timeout", "0"
    )
    assert result.status == 1
    assert result.err == (
        "rovlink send: #qd! got no valid reply within 0.05 s (1 attempt: timeout) on "
        f"tcp 127.0.0.1:{silent.port}\n"
    )


@pytest.mark.parametrize("how", [signal.SIGTERM, signal.SIGHUP], ids=lambda how: how.name)
@pytest.mark.parametrize(
    "bridge",
    [
        ("mavlink", "--out", "udpout:127.0.0.1:9"),  # (nobody listens: the bridge sends on)
        # (the broker retried meanwhile; a bridge that takes commands locks the robot at exit)
        ("mqtt", "--broker", "mqtt://127.0.0.1:9", "--robot", "r1", "--allow-commands"),
    ],
    ids=lambda bridge: bridge[0],
)
def test_a_signal_ends_a_bridge_with_its_final_stop(
    silent: SilentController, how: signal.Signals, bridge: tuple[str, ...]
) -> None:
    command, *options = bridge
    process = _rovlink(command, silent.url, *options)
    assert silent.wait_for(b"#qsa!")  # past the #stop! it sends on start, polling
    stops_before = silent.received.count(b"#stop!")
    _, stderr = _interrupt(process, how)
    # A service stopped (systemctl stop, a closed SSH session): a clean end, status 0, as for
    # the other serving commands (before: 130, and systemd marked the bridge failed).
    assert process.returncode == 0, stderr
    assert stderr.decode().splitlines()[-1] == f"rovlink {command} stopped"
    assert silent.wait_until(lambda received: received.count(b"#stop!") > stops_before)


@pytest.mark.parametrize("how", ENDING_SIGNALS, ids=lambda how: how.name)
def test_a_signal_ends_a_telemetry_bridge_without_a_stop(
    silent: SilentController, how: signal.Signals
) -> None:
    # Before, `rovlink mqtt` without --allow-commands sent #stop! as it started and again as it
    # ended (the client's own way out on an error): restarting the deck's telemetry stopped the
    # robot the pilot flew on another line.
    process = _rovlink("mqtt", silent.url, "--broker", "mqtt://127.0.0.1:9", "--robot", "r1")
    assert silent.wait_for(b"#qsa!")
    _, stderr = _interrupt(process, how)
    assert process.returncode == (0 if how in (signal.SIGTERM, signal.SIGHUP) else 130), stderr
    assert silent.wait_closed()
    assert b"#stop!" not in silent.received


@pytest.mark.parametrize("how", [signal.SIGINT, signal.SIGQUIT], ids=lambda how: how.name)
@pytest.mark.parametrize(
    "bridge",
    [
        ("mavlink", "--out", "udpout:127.0.0.1:9"),
        ("mqtt", "--broker", "mqtt://127.0.0.1:9", "--robot", "r1", "--allow-commands"),
    ],
    ids=lambda bridge: bridge[0],
)
def test_ctrl_c_ends_a_bridge_as_interrupted_with_its_final_stop(
    silent: SilentController, how: signal.Signals, bridge: tuple[str, ...]
) -> None:
    command, *options = bridge
    process = _rovlink(command, silent.url, *options)
    assert silent.wait_for(b"#qsa!")
    stops_before = silent.received.count(b"#stop!")
    _, stderr = _interrupt(process, how)
    assert process.returncode == 130, stderr
    assert stderr.decode().splitlines()[-1] == f"rovlink {command}: interrupted"
    assert silent.wait_until(lambda received: received.count(b"#stop!") > stops_before)


@pytest.mark.parametrize("how", [signal.SIGTERM, signal.SIGHUP], ids=lambda how: how.name)
def test_a_signal_ends_a_background_bridge_with_its_final_stop(
    silent: SilentController, how: signal.Signals
) -> None:
    # A background job ignores SIGINT, so SIGTERM cannot be taken as Ctrl-C there.
    process = _rovlink("mavlink", silent.url, "--out", "udpout:127.0.0.1:9", background=True)
    assert silent.wait_for(b"#qsa!")
    stops_before = silent.received.count(b"#stop!")
    _, stderr = _interrupt(process, how)
    assert process.returncode == 0, stderr
    assert stderr.decode().splitlines()[-1] == "rovlink mavlink stopped"
    assert silent.wait_until(lambda received: received.count(b"#stop!") > stops_before)


class _StderrWritingAlready(io.StringIO):
    """A stderr that is in the middle of a write when the signal comes, as a buffered stream
    says it: ``RuntimeError: reentrant call``."""

    def write(self, text: str) -> int:
        raise RuntimeError("reentrant call inside <_io.BufferedWriter name='<stderr>'>")


@pytest.mark.skipif(not hasattr(signal, "SIGTSTP"), reason="no SIGTSTP on this system")
def test_ctrl_z_refused_while_stderr_is_being_written_does_not_end_the_command(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The refusal is said from the signal handler in the command's own thread (tune, check): a
    # Ctrl-Z that came while that thread was writing a progress line raised out of the line
    # and ended the command mid-motion.
    monkeypatch.setattr(sys, "stderr", _StderrWritingAlready())
    with suspension_refused_by("rovlink tune"):
        os.kill(os.getpid(), signal.SIGTSTP)  # (the handler runs before kill returns: no raise)
