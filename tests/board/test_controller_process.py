"""``rovlink controller --board pi`` as a real process on the fake I²C bus, and a host driving
it over a real pseudo-terminal, a serial device and TCP."""

from __future__ import annotations

import contextlib
import os
import re
import shlex
import signal
import socket
import subprocess
import tty
from collections.abc import Iterator
from pathlib import Path

import pytest

import rovlink
from rovlink.board.watchdog_bounds import MAX_BOARD_WATCHDOG_S
from rovlink.client.blocking import Client
from tests.board.controller_process import (
    ControllerProcess,
    controller_command,
    environment,
    running_controller,
)
from tests.board.rig import COUNT_US, EXAMPLE, is_neutral, pulses, read_log, wait_until
from tests.board.rig import fake_toml as make_fake_toml
from tests.client.conftest import REPLY_TIMEOUT_S
from tests.client.sim_scenario import DebugLines, run_every_method
from tests.rovlink_process import rovlink_command
from tests.terminals import open_as_another_user

pytestmark = pytest.mark.integration

_MOVING_US = 1500 + 400 * 128 / 255  # front_left on `#th.90.50!` (see test_board_loop)


def _moving(log: Path) -> bool:
    value = pulses(read_log(log), [0])[0]
    return value is not None and abs(value - _MOVING_US) <= COUNT_US


@contextlib.contextmanager
def _moving_robot(controller: ControllerProcess, log: Path) -> Iterator[Client]:
    """The robot unlocked and moving (``#th.90.50!``) through ``controller``: the client.

    No motion timeout: the pulses stay the motion's however slow the machine (the driver's 2 s
    expiry wrote zero thrust to the chip while a loaded machine ran the test's next steps).
    """
    assert controller.pty_path is not None
    with rovlink.connect(
        controller.pty_path, keepalive=None, timeout=REPLY_TIMEOUT_S, motion_timeout=None
    ) as rov:
        rov.start()
        rov.move(90, 50)
        assert wait_until(lambda: _moving(log))
        yield rov


@pytest.mark.parametrize(
    ("signum", "status"),
    [(signal.SIGTERM, 0), (signal.SIGINT, 130), (signal.SIGHUP, 0), (signal.SIGQUIT, 130)],
)
def test_a_signal_ends_the_process_with_the_thrusters_at_neutral(
    tmp_path: Path, signum: int, status: int
) -> None:
    log = tmp_path / "i2c.jsonl"
    config = make_fake_toml(tmp_path, log, watchdog_s=MAX_BOARD_WATCHDOG_S)
    with running_controller(tmp_path, "--config", str(config), "--pty") as controller:
        assert controller.pty_path is not None
        assert "board pi" in controller.ready_line
        assert is_neutral(pulses(read_log(log)))  # armed before the ready line
        with _moving_robot(controller, log):
            controller.process.send_signal(signum)
            assert controller.process.wait(10) == status  # (Ctrl-C: 130, as every command)
        transactions = read_log(log)
        assert is_neutral(pulses(transactions))
        assert "thrusters at neutral" in controller.stderr()
        # One line says how it ended (before, Ctrl-C said "stopped" and "interrupted").
        said = "rovlink controller stopped: " if status == 0 else "rovlink controller: "
        assert re.search(
            rf"^{said}thrusters at neutral; \d+ control periods, \d+ overrun\(s\), "
            r"0 device fault\(s\)$",
            controller.stderr(),
            re.MULTILINE,
        )
        assert ("rovlink controller: interrupted" in controller.stderr()) is (status == 130)


def _bench_failsafe_step_command(pty_path: str) -> list[str]:
    """The command docs/hardware.md's bench test has a user run to try the link-loss failsafe
    (its step 7), for the controller's PTY at ``pty_path``."""
    text = (EXAMPLE.parents[1] / "docs" / "hardware.md").read_text(encoding="utf-8")
    step = re.search(r"^7\. \*\*The failsafes\*\*(.*?)^8\. ", text, re.MULTILINE | re.DOTALL)
    assert step, "no step 7 in docs/hardware.md's bench test"
    command = re.search(r"`([^`]*/dev/pts/N[^`]*)`", step.group(1))
    assert command, "no command on /dev/pts/N in step 7 of the bench test"
    line = command.group(1).replace("/dev/pts/N", shlex.quote(pty_path))
    if line.startswith("rovlink "):
        return rovlink_command(*shlex.split(line)[1:])
    return ["sh", "-c", line]


def test_the_bench_tests_failsafe_step_leaves_the_robot_to_the_watchdog(tmp_path: Path) -> None:
    # The step ran `rovlink send`, which sends #stop! as it ends after moving the robot: the
    # thrusters stopped at once, and the watchdog the step is there to try never acted.
    log = tmp_path / "i2c.jsonl"
    config = make_fake_toml(tmp_path, log, watchdog_s=0.5)
    with running_controller(tmp_path, "--config", str(config), "--pty") as controller:
        assert controller.pty_path is not None
        result = subprocess.run(
            _bench_failsafe_step_command(controller.pty_path),
            capture_output=True,
            text=True,
            env=environment(),
            timeout=60,
            check=False,
        )
        assert result.returncode == 0, result.stderr
        assert wait_until(lambda: "failsafe: no valid frame for 0.5 s" in controller.stderr()), (
            controller.stderr()
        )
        assert is_neutral(pulses(read_log(log)))


def _unit_line(key: str) -> list[str]:
    """The arguments after ``rovlink`` of the ``key=`` line of docs/hardware.md's unit file."""
    text = (EXAMPLE.parents[1] / "docs" / "hardware.md").read_text(encoding="utf-8")
    found = re.search(rf"^{key}=\S*/rovlink (.+)$", text, flags=re.MULTILINE)
    assert found, f"no {key}= line in the unit file of docs/hardware.md"
    return found.group(1).split()


def test_a_killed_controller_is_set_to_neutral_by_the_units_exec_stop_post(
    tmp_path: Path,
) -> None:
    log = tmp_path / "i2c.jsonl"
    config = make_fake_toml(tmp_path, log, watchdog_s=MAX_BOARD_WATCHDOG_S)
    stop_post = [
        str(config) if a == "/etc/rovlink/rov.toml" else a for a in _unit_line("ExecStopPost")
    ]
    assert stop_post[0] == "controller"
    assert str(config) in stop_post
    with running_controller(tmp_path, "--config", str(config), "--pty") as controller:
        with _moving_robot(controller, log):
            controller.process.kill()  # SIGKILL: nothing of the process runs again
            assert controller.process.wait(10) == -signal.SIGKILL
        assert _moving(log)  # the PCA9685 goes on making the last pulses
        result = _run(*stop_post[1:])
        assert result.returncode == 0, result.stderr
        assert "neutral pulses on channels 0, 1, 2, 3, 4, 5, 8" in result.stderr
        transactions = read_log(log)
        assert is_neutral(pulses(transactions))


def test_neutral_after_a_killed_controller_needs_only_the_pwm_boards_tables(
    tmp_path: Path,
) -> None:
    # rov.toml was edited while the controller ran (a wrong gain, the failsafe turned off to
    # try something): the controller would refuse it at its next start, and ExecStopPost must
    # still set neutral after the controller is killed.
    log = tmp_path / "i2c.jsonl"
    config = make_fake_toml(tmp_path, log)
    with running_controller(tmp_path, "--config", str(config), "--pty") as controller:
        with _moving_robot(controller, log):
            controller.process.kill()
            assert controller.process.wait(10) == -signal.SIGKILL
        text = config.read_text(encoding="utf-8")
        text = text.replace("kp = 40", "kp = 400").replace("watchdog_s = 2.0", "watchdog_s = 0")
        config.write_text(text.replace("poll_hz = 20.0", "poll_hz = 500.0"), encoding="utf-8")
        assert "[depth_pid]: kp must be in 0–99" in _run("--config", str(config), "--pty").stderr
        assert _moving(log)
        result = _run("--config", str(config), "--neutral")
        assert result.returncode == 0, result.stderr
        assert "neutral pulses on channels 0, 1, 2, 3, 4, 5, 8" in result.stderr
        assert is_neutral(pulses(read_log(log)))


def test_neutral_with_a_wrong_pwm_board_table_says_it_could_not_set_neutral(
    tmp_path: Path,
) -> None:
    path = tmp_path / "rov.toml"
    text = EXAMPLE.read_text(encoding="utf-8").replace("channel = 3", "channel = 2")
    path.write_text(text, encoding="utf-8")
    result = _run("--config", str(path), "--neutral")
    assert result.returncode == 2
    assert "[esc.rear_right] channel: 2 is already used by [esc.rear_left]" in result.stderr
    assert "NEUTRAL COULD NOT BE SET: cut the thruster power" in result.stderr


def test_the_unit_has_systemd_kill_a_controller_that_hangs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    text = (EXAMPLE.parents[1] / "docs" / "hardware.md").read_text(encoding="utf-8")
    assert re.search(r"^Type=notify$", text, flags=re.MULTILINE)
    assert re.search(r"^WatchdogSec=5$", text, flags=re.MULTILINE)
    assert re.search(r"^NotifyAccess=main$", text, flags=re.MULTILINE)
    # What systemd gives a service with WatchdogSec=5 (its NOTIFY_SOCKET, here a test's).
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    listener.bind(str(tmp_path / "notify"))
    listener.settimeout(REPLY_TIMEOUT_S)
    monkeypatch.setenv("NOTIFY_SOCKET", str(tmp_path / "notify"))
    monkeypatch.setenv("WATCHDOG_USEC", "200000")
    monkeypatch.delenv("WATCHDOG_PID", raising=False)
    config = make_fake_toml(tmp_path, tmp_path / "i2c.jsonl")
    try:
        with running_controller(tmp_path, "--config", str(config), "--pty"):
            told = [listener.recv(100) for _ in range(6)]
    finally:
        listener.close()
    assert b"READY=1" in told
    assert told.count(b"WATCHDOG=1") >= 4  # every 0.1 s, half of WATCHDOG_USEC


def test_a_second_controller_on_the_same_pwm_board_is_refused_before_touching_it(
    tmp_path: Path,
) -> None:
    # The service runs; someone starts another controller for the bench test. Two controllers
    # on one PCA9685 each write only what they believe changed: `#stop!` sent to one would not
    # stop what the other set running. The second refuses before a single transaction.
    log = tmp_path / "i2c.jsonl"
    config = make_fake_toml(tmp_path, log, watchdog_s=MAX_BOARD_WATCHDOG_S)
    with (
        running_controller(tmp_path, "--config", str(config), "--pty") as controller,
        _moving_robot(controller, log) as rov,
    ):
        chip_writes = [t for t in read_log(log) if t.address == 0x40 and not t.read]
        for arguments in (("--pty",), ("--neutral",)):
            result = _run("--config", str(config), *arguments, timeout_s=20.0)
            assert result.returncode == 1, result.stderr
            assert (
                "PWM board PCA9685 at 0x40 on I²C bus 1 is in use by another rovlink "
                "controller" in result.stderr
            )
        assert [t for t in read_log(log) if t.address == 0x40 and not t.read] == chip_writes
        assert _moving(log)
        assert rov.sensors().pressure_raw == 20  # the first goes on undisturbed


def test_neutral_serves_nothing_and_is_for_the_pi_board() -> None:
    assert "--neutral serves nothing" in _run("--config", str(EXAMPLE), "--neutral", "--pty").stderr
    assert "--neutral is for --board pi" in _run("--board", "sim", "--neutral").stderr


def test_neutral_that_cannot_reach_the_pwm_board_says_so(tmp_path: Path) -> None:
    path = tmp_path / "rov.toml"
    path.write_text(
        EXAMPLE.read_text(encoding="utf-8").replace("bus = 1", "bus = 250", 1), encoding="utf-8"
    )
    result = _run("--config", str(path), "--neutral")
    assert result.returncode == 1
    assert "cannot open I²C bus 250" in result.stderr


def test_the_watchdog_of_a_real_process_gives_neutral(tmp_path: Path) -> None:
    log = tmp_path / "i2c.jsonl"
    config = make_fake_toml(tmp_path, log, watchdog_s=0.5)
    with running_controller(tmp_path, "--config", str(config), "--pty") as controller:
        assert controller.pty_path is not None
        with rovlink.connect(controller.pty_path, keepalive=None, timeout=REPLY_TIMEOUT_S) as rov:
            rov.start()
            rov.move(90, 50)
            assert wait_until(lambda: _moving(log))
            # No keep-alive: the controller's own watchdog stops the thrusters.
            assert wait_until(lambda: is_neutral(pulses(read_log(log))))
            assert "failsafe: no valid frame" in controller.stderr()


def test_a_tcp_host_that_dies_while_driving_is_stopped_though_a_monitor_keeps_talking(
    tmp_path: Path,
) -> None:
    # A pilot's station drives over TCP while a monitor on the pseudo-terminal polls the
    # sensors. The station hangs: its motion must not run on, fed by the monitor's queries.
    log = tmp_path / "i2c.jsonl"
    config = make_fake_toml(tmp_path, log, watchdog_s=0.3)
    with running_controller(tmp_path, "--config", str(config), "--pty", "--tcp", "0") as controller:
        assert controller.pty_path is not None
        assert controller.tcp_url is not None
        host, port = controller.tcp_url.removeprefix("socket://").rsplit(":", 1)
        monitor = os.open(controller.pty_path, os.O_RDWR | os.O_NOCTTY)
        try:
            tty.setraw(monitor)
            with socket.create_connection((host, int(port)), timeout=5) as station:
                station.sendall(b"#start!#th.90.50!")

                def moving_while_alive() -> bool:  # (its queries keep its motion alive)
                    station.sendall(b"#qd!")
                    return _moving(log)

                assert wait_until(moving_while_alive)
                # The station hangs, its connection left open (one that closes it is
                # stopped at once); the monitor keeps asking for the sensors.

                def stopped_while_polled() -> bool:
                    os.write(monitor, b"#qsa!")
                    return is_neutral(pulses(read_log(log)))

                assert wait_until(stopped_while_polled, timeout_s=5.0), pulses(read_log(log))
        finally:
            os.close(monitor)
        assert "failsafe: no valid frame" in controller.stderr()


@pytest.mark.parametrize("transport", ["pty", "tcp"])
def test_the_driver_passes_the_simulators_tests_against_the_pi_board(
    tmp_path: Path, transport: str
) -> None:
    log = tmp_path / "i2c.jsonl"
    config = make_fake_toml(tmp_path, log)
    with running_controller(tmp_path, "--config", str(config), "--pty", "--tcp", "0") as controller:
        url = controller.pty_path if transport == "pty" else controller.tcp_url
        assert url is not None
        debug = DebugLines()
        with rovlink.connect(url, keepalive=None, on_stray=debug, timeout=REPLY_TIMEOUT_S) as rov:
            run_every_method(rov, debug)
            sensors = rov.sensors()
            # The fake Bar02 sits at rov.toml's surface_mbar: zero_raw.
            assert sensors.pressure_raw == 20
            assert (sensors.roll_deg, sensors.pitch_deg, sensors.heading_deg) == (2, -1, 90)
        assert is_neutral(pulses(read_log(log)))  # the scenario ends with stop


def test_serving_a_serial_device_exclusively(tmp_path: Path) -> None:
    log = tmp_path / "i2c.jsonl"
    config = make_fake_toml(tmp_path, log, watchdog_s=MAX_BOARD_WATCHDOG_S)
    master, slave = os.openpty()
    tty.setraw(slave)
    device = os.ttyname(slave)
    os.set_blocking(master, False)
    try:
        with running_controller(
            tmp_path, "--config", str(config), "--port", device, "--baud", "115200"
        ) as controller:
            assert f"serial {device} 115200 baud" in controller.ready_line
            os.write(master, b"#qd!")
            received = bytearray()

            def answered() -> bool:
                with contextlib.suppress(BlockingIOError):
                    received.extend(os.read(master, 100))
                return b"$qd." in received

            assert wait_until(answered)
            # A second controller on the same device is refused (P22), at neutral. (On a
            # board of its own: on the same board it would be refused before the device.)
            other = tmp_path / "other"
            other.mkdir()
            other_config = make_fake_toml(
                other, other / "i2c.jsonl", watchdog_s=MAX_BOARD_WATCHDOG_S
            )
            second = subprocess.run(
                controller_command("--config", str(other_config), "--port", device),
                capture_output=True,
                text=True,
                env=environment(),
                timeout=60,
                check=False,
            )
            assert second.returncode == 1
            assert f"cannot open {device}" in second.stderr
    finally:
        os.close(master)
        os.close(slave)


def _run(*arguments: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        controller_command(*arguments),
        capture_output=True,
        text=True,
        env=environment(),
        timeout=timeout_s,
        check=False,
    )


def test_tcp_on_a_reachable_address_needs_allow_remote(tmp_path: Path) -> None:
    config = make_fake_toml(tmp_path, tmp_path / "i2c.jsonl")
    refused = _run("--config", str(config), "--tcp", "0.0.0.0:0")
    assert refused.returncode == 2
    assert "0.0.0.0 is not a loopback address" in refused.stderr
    assert "--allow-remote" in refused.stderr
    with running_controller(
        tmp_path, "--config", str(config), "--tcp", "0.0.0.0:0", "--allow-remote"
    ) as controller:
        assert "tcp 0.0.0.0:" in controller.ready_line
        assert "(REMOTE, NO AUTHENTICATION)" in controller.ready_line
        assert wait_until(lambda: "anyone connected can drive the robot" in controller.stderr())


def test_a_wrong_config_is_one_line_naming_the_key(tmp_path: Path) -> None:
    path = tmp_path / "rov.toml"
    path.write_text(
        EXAMPLE.read_text(encoding="utf-8").replace("channel = 3", "channel = 2"), encoding="utf-8"
    )
    result = _run("--config", str(path), "--pty")
    assert result.returncode == 2
    assert result.stderr.strip().count("\n") == 0
    assert "[esc.rear_right] channel: 2 is already used by [esc.rear_left]" in result.stderr


@pytest.mark.parametrize("watchdog", ["0", "3600"])
def test_a_robot_is_never_served_without_a_link_loss_failsafe(watchdog: str) -> None:
    result = _run("--config", str(EXAMPLE), "--pty", "--watchdog", watchdog)
    assert result.returncode == 2
    assert f"--watchdog must be 0.1–10 s on a robot, got {watchdog}" in result.stderr


def test_usage_errors() -> None:
    assert "--board pi needs --config" in _run("--pty").stderr
    assert "give --port DEVICE, --pty and/or --tcp" in _run("--config", str(EXAMPLE)).stderr
    assert (
        "the simulator serves a pseudo-terminal or TCP"
        in _run("--board", "sim", "--port", "/dev/null").stderr
    )
    # (Before, a --baud without a serial device was silently unused.)
    assert (
        "--baud is the rate of --port's serial device; rovlink sim --baud paces a simulated line"
        in _run("--board", "sim", "--baud", "9600").stderr
    )


def test_the_same_rov_toml_runs_the_simulator(tmp_path: Path) -> None:
    with running_controller(tmp_path, "--board", "sim", "--config", str(EXAMPLE)) as controller:
        assert controller.pty_path is not None
        assert "board sim" in controller.ready_line
        debug = DebugLines()
        with rovlink.connect(
            controller.pty_path, keepalive=None, on_stray=debug, timeout=REPLY_TIMEOUT_S
        ) as rov:
            run_every_method(rov, debug)


def test_no_other_program_opens_the_serial_device_while_the_controller_has_it(
    tmp_path: Path,
) -> None:
    config = make_fake_toml(tmp_path, tmp_path / "i2c.jsonl")
    master, slave = os.openpty()
    device = os.ttyname(slave)
    os.chmod(device, 0o666)  # any user may open it: only the exclusive mode keeps them out
    try:
        assert "opened" in open_as_another_user(device)
        with running_controller(tmp_path, "--config", str(config), "--port", device):
            assert "busy" in open_as_another_user(device).lower()
    finally:
        os.close(master)
        os.close(slave)
