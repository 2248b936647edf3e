"""``rovlink sim`` as a user runs it: a subprocess, its ready line, signals, options."""

from __future__ import annotations

import os
import re
import select
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import serial

pytestmark = pytest.mark.integration

_SRC = str(Path(__file__).resolve().parents[2] / "src")
_READY = re.compile(r"rovlink sim ready: (?:pty (?P<pty>\S+?))?(?:, )?(?:tcp (?P<tcp>\S+))? ")


RunSim = Callable[..., tuple["subprocess.Popen[str]", "re.Match[str]"]]


def _command(*arguments: str) -> list[str]:
    return [sys.executable, "-c", "from rovlink.cli import main; main()", "sim", *arguments]


def _environment() -> dict[str, str]:
    environment = dict(os.environ)
    environment["PYTHONPATH"] = _SRC + os.pathsep + environment.get("PYTHONPATH", "")
    return environment


@pytest.fixture
def run_sim() -> Iterator[RunSim]:
    processes: list[subprocess.Popen[str]] = []

    def start(*arguments: str) -> tuple[subprocess.Popen[str], re.Match[str]]:
        process = subprocess.Popen(
            _command(*arguments),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=_environment(),
        )
        processes.append(process)
        assert process.stdout is not None
        line = process.stdout.readline()
        match = _READY.match(line)
        assert process.stderr is not None
        assert match, (line, process.stderr.read() if process.poll() is not None else "")
        return process, match

    yield start
    for process in processes:
        if process.poll() is None:
            process.kill()
        process.communicate(timeout=5)


def _query(port: serial.Serial, frame: bytes) -> bytes:
    port.write(frame)
    reply = b""
    deadline = time.monotonic() + 5
    while not reply.endswith(b"!"):
        assert time.monotonic() < deadline, reply
        reply += port.read(64)
    return reply


def test_it_prints_a_ready_line_and_stops_cleanly_on_sigterm(run_sim: RunSim) -> None:
    process, match = run_sim("--pty", "--tcp", "127.0.0.1:0", "--seed", "5")
    assert match["pty"].startswith("/dev/")
    with serial.Serial(match["pty"], timeout=0.1) as port:
        assert _query(port, b"#qd!") == b"$qd.0!"
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=5)
    assert process.returncode == 0
    assert "stopped" in stderr
    assert "Traceback" not in stderr


@pytest.mark.parametrize(
    ("how", "status"),
    [(signal.SIGINT, 130), (signal.SIGTERM, 0), (signal.SIGHUP, 0), (signal.SIGQUIT, 130)],
)
def test_ctrl_c_stops_it_cleanly_with_130_and_a_service_stop_with_0(
    run_sim: RunSim, how: signal.Signals, status: int
) -> None:
    # Ctrl-C ends every command with 130, as shells expect, and so does Ctrl-\ (SIGQUIT);
    # SIGTERM and SIGHUP are how a service manager stops a service, whose normal end is 0.
    process, _ = run_sim("--tcp", "0")
    process.send_signal(how)
    _, stderr = process.communicate(timeout=5)
    assert process.returncode == status, stderr
    # One line says which (before, Ctrl-C said "stopped" and "interrupted").
    assert stderr.strip() == ("rovlink sim stopped" if status == 0 else "rovlink sim: interrupted")
    assert "Traceback" not in stderr


def test_without_an_endpoint_it_opens_a_pty(run_sim: RunSim) -> None:
    _, match = run_sim()
    assert match["pty"]
    assert not match["tcp"]


def test_a_listener_on_every_interface_is_warned_of(run_sim: RunSim) -> None:
    # Regression: `--tcp 0.0.0.0:5760` served a robot with no authentication to every network
    # without a word, where `rovlink controller` refuses it without --allow-remote.
    process, match = run_sim("--tcp", "0.0.0.0:0", "--seed", "1")
    assert match["tcp"].startswith("0.0.0.0:")
    assert "(REMOTE, NO AUTHENTICATION)" in match.string
    assert process.stderr is not None
    warning = process.stderr.readline()  # (logged before the ready line was printed)
    assert "WARNING" in warning
    assert f"listening on {match['tcp']} (every network interface)" in warning
    assert "anyone connected can drive the robot" in warning


def test_a_loopback_listener_is_not_warned_of(run_sim: RunSim) -> None:
    process, match = run_sim("--tcp", "127.0.0.1:0", "--seed", "1")
    assert "REMOTE" not in match.string
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=5)
    assert "WARNING" not in stderr
    assert "anyone connected" not in stderr


def test_leak_at_injects_a_pulse(run_sim: RunSim) -> None:
    _, match = run_sim("--pty", "--leak-at", "0.2", "--seed", "1")
    with serial.Serial(match["pty"], timeout=0.1) as port:
        deadline = time.monotonic() + 5
        while _query(port, b"#q.l!") != b"$q.l.1!":
            assert time.monotonic() < deadline
            time.sleep(0.05)


def test_config_is_applied(run_sim: RunSim, tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_text("[depth]\nzero_raw = 0\n")
    _, match = run_sim("--pty", "--config", str(config))
    with serial.Serial(match["pty"], timeout=0.1) as port:
        assert _query(port, b"#qd!") == b"$qd.40!"  # raw 20 over a zero of 0: 40 cm


def test_a_speed_beyond_the_cpu_answers_and_says_it_is_behind(run_sim: RunSim) -> None:
    # The warning went to no handler: without --verbose, rovlink sim showed no log line at all.
    process, match = run_sim("--tcp", "127.0.0.1:0", "--speed", "1e6", "--seed", "1")
    host, port = match["tcp"].rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=5) as connection:
        connection.sendall(b"#q.l!")
        assert connection.recv(64) == b"$q.l.0!"
    assert process.stderr is not None
    deadline = time.monotonic() + 5
    line = ""
    while "behind the wall clock" not in line:
        assert time.monotonic() < deadline
        ready, _, _ = select.select([process.stderr], [], [], 0.1)
        if ready:
            line = process.stderr.readline()
    assert "WARNING" in line


def test_a_bad_config_is_reported_with_its_key(tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_text("[controller]\nmax_pwm = 300\n")
    result = subprocess.run(
        _command("--config", str(config)),
        capture_output=True,
        text=True,
        env=_environment(),
        timeout=30,
        check=False,
    )
    assert result.returncode == 2
    assert "max_pwm" in result.stderr
    assert "300" in result.stderr


def test_a_busy_tcp_port_is_reported() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = subprocess.run(
            _command("--tcp", str(port)),  # (the port alone: the host is 127.0.0.1)
            capture_output=True,
            text=True,
            env=_environment(),
            timeout=30,
            check=False,
        )
    assert result.returncode == 1
    # Before, "cannot listen on 5760": not which address was busy.
    assert f"rovlink sim: cannot listen on 127.0.0.1:{port}: Address already in use" in (
        result.stderr
    )


def _read_until(port: serial.Serial, wanted: bytes) -> bytes:
    received = b""
    deadline = time.monotonic() + 5
    while wanted not in received:
        assert time.monotonic() < deadline, received
        received += port.read(256)
    return received


def test_watchdog_option_turns_the_failsafe_off_for_typing_by_hand(run_sim: RunSim) -> None:
    # At 100 simulated seconds per wall second, a person "typing" 0.3 s apart leaves the link
    # silent for 30 simulated seconds: far past the default 2 s failsafe.
    _, match = run_sim("--pty", "--speed", "100", "--watchdog", "0", "--seed", "1")
    with serial.Serial(match["pty"], timeout=0.05) as port:
        port.write(b"#debug1!#start!")
        _read_until(port, b"motors unlocked")
        port.write(b"#mvd.100!")
        _read_until(port, b"target depth 100 cm")
        silent_until = time.monotonic() + 0.3
        while time.monotonic() < silent_until:
            assert b"failsafe" not in port.read(256)
        deadline = time.monotonic() + 10
        while True:  # dives and holds 1 m, still unlocked (however slow the machine)
            reply = _query(port, b"#qd!")
            assert b"failsafe" not in reply
            if 90 <= int(reply.split(b"$qd.")[1].rstrip(b"!")) <= 110:
                break
            assert time.monotonic() < deadline, reply


def test_the_default_watchdog_stops_a_silent_link(run_sim: RunSim) -> None:
    _, match = run_sim("--pty", "--speed", "100", "--seed", "1")
    with serial.Serial(match["pty"], timeout=0.05) as port:
        port.write(b"#debug1!#start!")
        assert b"failsafe" in _read_until(port, b"failsafe")


@pytest.mark.parametrize(
    "content",
    [bytes(range(256)) * 4, "[controller]\n# für\n".encode("latin-1")],
    ids=["binary", "latin-1"],
)
def test_a_config_that_is_not_utf8_text_is_a_short_error(tmp_path: Path, content: bytes) -> None:
    config = tmp_path / "robot.toml"
    config.write_bytes(content)
    result = subprocess.run(
        _command("--config", str(config)),
        capture_output=True,
        text=True,
        env=_environment(),
        timeout=30,
        check=False,
    )
    assert result.returncode == 2
    assert result.stderr.startswith(f"rovlink sim: {config}: not UTF-8 text (byte 0x")
    assert result.stderr.count("\n") == 1, result.stderr


def test_a_pty_and_a_tcp_client_at_once_each_get_their_replies(run_sim: RunSim) -> None:
    # Half a frame on the PTY, a whole one on TCP, then the PTY's rest: before, the two lines
    # shared one decoder, and the PTY's query was lost to the TCP client's frame.
    _, match = run_sim("--pty", "--tcp", "127.0.0.1:0", "--seed", "5")
    host, port = match["tcp"].rsplit(":", 1)
    with (
        serial.Serial(match["pty"], timeout=0.1) as pty,
        socket.create_connection((host, int(port)), timeout=5) as tcp,
    ):
        assert _query(pty, b"#qd!") == b"$qd.0!"  # (both lines open and answered)
        pty.write(b"#q")
        pty.flush()
        time.sleep(0.05)  # (only so that the half frame comes first, as it did when it failed)
        tcp.sendall(b"#qr!")
        reply = b""
        while not reply.endswith(b"!"):
            reply += tcp.recv(64)
        assert reply == b"$qr.20!"
        assert _query(pty, b"d!") == b"$qd.0!"


def _ignore_ctrl_c() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a shell starts a background job (&)


def test_sigquit_stops_it_cleanly_in_the_background_too() -> None:
    # A background job ignores SIGINT, which the command line's SIGQUIT handler raised: the
    # KeyboardInterrupt it raised instead was lost in the serving loop, which served on.
    process = subprocess.Popen(
        _command("--tcp", "0"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_environment(),
        preexec_fn=_ignore_ctrl_c,  # noqa: PLW1509 - no threads yet
    )
    try:
        assert process.stdout is not None
        assert _READY.match(process.stdout.readline())
        process.send_signal(signal.SIGQUIT)
        _, stderr = process.communicate(timeout=5)
        assert process.returncode == 130, stderr
        assert stderr.strip() == "rovlink sim: interrupted"
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate(timeout=5)
