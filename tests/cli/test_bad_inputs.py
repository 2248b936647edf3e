"""Bad input to any command: one line on stderr naming the option or file and the value, a
non-zero exit status, never a traceback, never silent success."""

from __future__ import annotations

from pathlib import Path

import pytest

from rovlink.monitor.app import MonitorApp
from tests.cli.conftest import RunCli

#: A run that the bug would have kept going (serving, or waiting on a prompt) ends here.
_HANG_TIMEOUT_S = 30


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["send", "sim://", "qd", "--record", "x.jsonl", "--max-size", "1e400"],
            "argument --max-size: '1e400' is not a size (a number with k, M or G: 100M)",
        ),
        (
            ["send", "sim://", "qd", "--record", "x.jsonl", "--max-size", "infk"],
            "argument --max-size: 'infk' is not a size (a number with k, M or G: 100M)",
        ),
        (
            ["send", "--baudrate", "99999999999999999999", "sim://", "qd"],
            "argument --baudrate: 99999999999999999999 is more than the maximum, 12000000 baud",
        ),
        (
            ["sim", "--baud", "4294967296"],
            "argument --baud/--baudrate: 4294967296 is more than the maximum, 12000000 baud",
        ),
        (["send", "sim://", "qd", "--record", ""], "argument --record: an empty file name"),
        (["check", "sim://", "--junit", ""], "argument --junit: an empty file name"),
        (["record", "sim://", "-o", ""], "argument -o/--output: an empty file name"),
        (
            ["record", "sim://", "-o", "x.jsonl", "--tap", ""],
            "--tap '': use pty or socket://HOST:PORT",
        ),
        (["console", "--history", ""], "argument --history: an empty file name"),
        (["tune", "sim://", "--yes", "--plot", ""], "argument --plot: an empty file name"),
        (["plot", "x.mcap", "-o", ""], "argument -o/--output: an empty file name"),
        (["sim", "--config", ""], "argument --config: an empty file name"),
        (["mavlink", "--params", ""], "argument --params: an empty file name"),
        (
            ["fleet", "--broker", "mqtt://127.0.0.1", "--password-file", ""],
            "argument --password-file: an empty file name",
        ),
        (
            ["tune", "sim://", "--yes", "--restore", "1,2,nan"],
            "argument --restore: expected three integers 0–99 as KP,KI,KD, got '1,2,nan'",
        ),
        (
            ["tune", "sim://", "--yes", "--restore", "100,1,1"],
            "argument --restore: expected three integers 0–99 as KP,KI,KD, got '100,1,1'",
        ),
        (
            ["tune", "sim://", "--yes", "--restore", "1.5,1,1"],
            "argument --restore: expected three integers 0–99 as KP,KI,KD, got '1.5,1,1'",
        ),
        (
            ["tune", "sim://", "--yes", "--depth", "300"],
            "--depth 300 must lie strictly between --min-depth 20 and --max-depth 300",
        ),
        (
            ["tune", "sim://", "--yes", "--depth", "0"],
            "--depth 0 must lie strictly between --min-depth 20 and --max-depth 300",
        ),
        (
            ["tune", "sim://", "--yes", "--depth", "50", "--min-depth", "50"],
            "--depth 50 must lie strictly between --min-depth 50 and --max-depth 300",
        ),
        (
            ["tune", "sim://", "--yes", "--scales", "0,0.1,0.1"],
            "argument --scales: expected three numbers > 0 as KP,KI,KD, got '0,0.1,0.1'",
        ),
        (
            ["tune", "sim://", "--yes", "--scales", "0.1,0.1,inf"],
            "argument --scales: expected three numbers > 0 as KP,KI,KD, got '0.1,0.1,inf'",
        ),
        (
            ["fault", "--listen", "socket://127.0.0.1:1", "--to", ""],
            "--to: connection URL must be a non-empty string, got ''",
        ),
        (
            ["fault", "--listen", "socket://127.0.0.1:65536", "--to", "sim://"],
            "--listen: 'socket://127.0.0.1:65536': expected socket://HOST:PORT with a port in "
            "0–65535 (0: a free one)",
        ),
        (
            ["fault", "--listen", "socket://127.0.0.1:1", "--to", "sim://", "--jitter-ms", "5"],
            "--jitter-ms 5 is more than --delay-ms 0",
        ),
        (
            ["fleet", "--broker", "mqtt://127.0.0.1:0", "--snapshot", "0.1"],
            "broker 'mqtt://127.0.0.1:0': the port must be 1–65535",
        ),
        (["web", "--host", ""], "argument --host: an empty address"),
        (["web", "--recordings", ""], "argument --recordings: an empty file name"),
    ],
)
@pytest.mark.timeout(_HANG_TIMEOUT_S)
def test_bad_values_are_one_line_usage_errors(
    run_cli: RunCli,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    argv: list[str],
    message: str,
) -> None:
    monkeypatch.chdir(tmp_path)  # a command that took its bad value would write x.jsonl here
    result = run_cli(*argv)
    assert "Traceback" not in result.err
    assert result.status == 2
    assert result.err.splitlines()[-1] == f"rovlink {argv[0]}: error: {message}"


def test_a_read_error_in_the_middle_of_a_capture(run_cli: RunCli) -> None:
    # /proc/self/mem opens, and its first read fails (EIO): a disk or device error.
    result = run_cli("decode", "/proc/self/mem")
    assert result.status == 1
    assert result.err == "rovlink decode: cannot read /proc/self/mem: Input/output error\n"


def test_vehicle_table_errors_name_the_file_and_table(run_cli: RunCli, tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_text("[vehicle]\nmass_kg = -1\n")
    result = run_cli("sim", "--config", str(config))
    assert result.status == 2
    assert result.err == f"rovlink sim: {config} [vehicle]: mass_kg must be > 0, got -1.0\n"


def _recording_with_telemetry(run_cli: RunCli, tmp_path: Path) -> Path:
    recording = tmp_path / "dive.jsonl"
    result = run_cli("send", "sim://?seed=1", "qsa", "--record", str(recording))
    assert result.status == 0, result.err
    return recording


@pytest.mark.parametrize("name", ["dive", "dive.txt", "dive.mcap/"])
def test_plot_output_needs_an_image_suffix(run_cli: RunCli, tmp_path: Path, name: str) -> None:
    # Regression: '-o dive' wrote dive.png and said "plotted … to dive", exit status 0.
    recording = _recording_with_telemetry(run_cli, tmp_path)
    output = str(tmp_path / name)
    result = run_cli("plot", str(recording), "-o", output)
    assert result.status == 2
    assert result.err.splitlines()[-1].startswith(
        f"rovlink plot: error: -o {output}: name the image format by its suffix: .png, "
    )
    assert list(tmp_path.glob("*.png")) == []


def test_plot_output_that_is_a_directory(run_cli: RunCli, tmp_path: Path) -> None:
    recording = _recording_with_telemetry(run_cli, tmp_path)
    directory = tmp_path / "plots.png"
    directory.mkdir()
    result = run_cli("plot", str(recording), "-o", str(directory))
    assert result.status == 1
    assert result.err == f"rovlink plot: cannot write {directory}: Is a directory\n"


def test_a_telemetry_csv_that_is_not_text(run_cli: RunCli, tmp_path: Path) -> None:
    table = tmp_path / "dive.csv"
    table.write_bytes(b"\xff\xfe\x00elapsed_s\n")
    result = run_cli("plot", str(table), "-o", str(tmp_path / "dive.png"))
    assert result.status == 1
    assert result.err == f"rovlink plot: {table}: not UTF-8 text, so not a rovlink telemetry CSV\n"


@pytest.mark.parametrize("suffix", [".jsonl", ".mcap"])
@pytest.mark.parametrize(
    ("command", "status"), [(["replay"], 0), (["decode"], 0), (["plot", "-o", "dive.png"], 1)]
)
def test_an_empty_recording_says_its_recorder_stopped_before_writing(
    run_cli: RunCli, tmp_path: Path, suffix: str, command: list[str], status: int
) -> None:
    # A recorder killed in its first second leaves an empty file, whatever its format: read
    # as a recording that ends early with nothing in it (an empty .jsonl was "not a
    # recording", status 1, while an empty .mcap ended early). Never silent: an empty .jsonl
    # once printed nothing and exited 0, as if it held a session.
    recording = tmp_path / f"dive{suffix}"
    recording.write_bytes(b"")
    result = run_cli(command[0], str(recording), *command[1:])
    assert result.status == status, result.err
    assert result.err.startswith(
        f"rovlink {command[0]}: {recording}: empty: its recorder was stopped before its first "
        "second was written; read 0 entries"
    )


@pytest.mark.timeout(_HANG_TIMEOUT_S)
def test_a_history_file_that_cannot_be_written(run_cli: RunCli, tmp_path: Path) -> None:
    # Regression: a directory as --history crashed prompt_toolkit's thread at the first line
    # typed (a traceback), and the console hung.
    result = run_cli("console", "sim://", "--history", str(tmp_path), stdin=b"qd\nquit\n")
    assert result.status == 1
    assert result.err == f"rovlink console: cannot keep the history in {tmp_path}: Is a directory\n"


@pytest.mark.timeout(_HANG_TIMEOUT_S)
def test_a_history_file_in_a_missing_directory(run_cli: RunCli, tmp_path: Path) -> None:
    # Regression: the missing directories were made, as for the default history file.
    history = tmp_path / "missing" / "dir" / "history"
    result = run_cli("console", "sim://", "--history", str(history), stdin=b"quit\n")
    assert result.status == 1
    assert result.err == (
        f"rovlink console: cannot keep the history in {history}: No such file or directory\n"
    )
    assert list(tmp_path.iterdir()) == []


@pytest.mark.timeout(_HANG_TIMEOUT_S)
def test_a_default_history_that_cannot_be_kept_does_not_keep_the_console_from_the_robot(
    run_cli: RunCli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, a user state directory that could not be made (a read-only home, a service
    # user's home that is not there) refused the console altogether, status 1.
    not_a_directory = tmp_path / "state"
    not_a_directory.write_text("")
    monkeypatch.setenv("XDG_STATE_HOME", str(not_a_directory))
    result = run_cli("console", "sim://", stdin=b"quit\n")
    assert result.status == 0, result.err
    assert result.err.startswith(
        f"rovlink console: cannot keep the history in {not_a_directory}/rovlink/console_history: "
    )
    assert "; kept for this session only\n" in result.err
    assert "connected to simulated controller" in result.err  # (the output: replies alone)


@pytest.mark.timeout(_HANG_TIMEOUT_S)
@pytest.mark.usefixtures("monitor_on_a_terminal")
def test_monitor_on_a_port_that_cannot_be_opened(
    run_cli: RunCli, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Regression: the dashboard showed "could not connect" and stayed, whatever the URL; then
    # it was drawn whole and taken down before the error: the port is opened first now.
    started: list[str] = []

    def start(self: MonitorApp, *args: object, **kwargs: object) -> None:
        started.append("dashboard")

    async def start_async(self: MonitorApp, *args: object, **kwargs: object) -> None:
        start(self)

    monkeypatch.setattr(MonitorApp, "run", start)
    monkeypatch.setattr(MonitorApp, "run_async", start_async)
    result = run_cli("monitor", "/dev/ttyUSB_rovlink_none")
    assert result.status == 1
    assert result.err == (
        "rovlink monitor: cannot open /dev/ttyUSB_rovlink_none: No such file or directory\n"
    )
    assert started == []


def test_the_fleets_live_table_without_a_terminal_is_refused(run_cli: RunCli) -> None:
    # `rovlink fleet | head`, `rovlink fleet > fleet.txt`: rich draws a live table on a terminal
    # alone, so before, nothing was written until the command was stopped (`head` waited for
    # ever); nobody listens at this broker, which it tried to reach.
    result = run_cli("fleet", "--broker", "mqtt://127.0.0.1:1")
    assert (result.status, result.out) == (2, "")
    assert result.err == (
        "rovlink fleet: the live table needs a terminal, but standard output is not one; "
        "--snapshot SECONDS prints the table once\n"
    )


@pytest.mark.integration
@pytest.mark.parametrize(
    ("broker", "why"),
    [
        ("mqtt://127.0.0.1:1", "connection refused (is the broker running"),
        ("mqtt://nonexistent.invalid", "name not resolved: the host 'nonexistent.invalid'"),
    ],
    ids=["refused", "no such host"],
)
@pytest.mark.timeout(_HANG_TIMEOUT_S)
def test_a_broker_that_cannot_be_reached_is_said_as_the_bridge_says_it(
    run_cli: RunCli, broker: str, why: str
) -> None:
    # Before, "broker mqtt://127.0.0.1:1: [Errno 111] Connection refused". Now in the words
    # the bridge's log uses for the same broker (docs/bridges.md).
    pytest.importorskip("aiomqtt", reason="aiomqtt is in the test extra (mqtt)")
    result = run_cli("fleet", "--broker", broker, "--snapshot", "0.1")
    assert result.status == 1
    assert result.err.startswith(f"rovlink fleet: broker {broker}")
    assert f": cannot connect: {why}" in result.err
    assert "Errno" not in result.err


@pytest.mark.integration
@pytest.mark.timeout(_HANG_TIMEOUT_S)
def test_tls_files_that_are_not_pem(run_cli: RunCli, tmp_path: Path) -> None:
    # Regression: fleet blamed the broker; mqtt retried the handshake for ever.
    garbage = tmp_path / "ca.pem"
    garbage.write_bytes(b"\xff not a certificate")
    for argv in (
        ["fleet", "--snapshot", "0.1"],
        ["mqtt", "sim://", "--robot", "rov-1"],
    ):
        result = run_cli(*argv, "--broker", "mqtts://127.0.0.1:1", "--cafile", str(garbage))
        assert result.status == 2
        assert result.err.startswith(
            f"rovlink {argv[0]}: --cafile {garbage}: not PEM certificates ("
        )
        assert len(result.err.splitlines()) == 1


@pytest.mark.integration
@pytest.mark.timeout(_HANG_TIMEOUT_S)
def test_mavlink_to_a_host_that_does_not_resolve(run_cli: RunCli) -> None:
    # Regression: the bridge said it was ready and sent every message nowhere.
    result = run_cli("mavlink", "sim://", "--out", "udpout:rovlink.invalid:14550")
    assert result.status == 1
    assert result.err.startswith("rovlink mavlink: cannot open udpout:rovlink.invalid:14550: ")
    assert len(result.err.splitlines()) == 1


@pytest.mark.integration
@pytest.mark.timeout(_HANG_TIMEOUT_S)
def test_web_recordings_must_be_a_directory(run_cli: RunCli, tmp_path: Path) -> None:
    # Regression: a file as --recordings was taken, and the record button failed later.
    not_a_directory = tmp_path / "recordings"
    not_a_directory.write_text("")
    result = run_cli("web", "--port", "0", "--recordings", str(not_a_directory))
    assert result.status == 2
    assert result.err.splitlines()[-1] == (
        f"rovlink web: error: --recordings {not_a_directory}: not a directory"
    )


@pytest.mark.parametrize(
    "argv",
    [
        ["mavlink", "sim://", "--params", "{missing}"],
        [
            *["mqtt", "sim://", "--broker", "mqtt://127.0.0.1:1", "--robot", "rov-1"],
            *["--username", "u", "--password-file", "{missing}"],
        ],
    ],
)
@pytest.mark.timeout(_HANG_TIMEOUT_S)
def test_a_missing_input_file_is_named_once_with_the_system_reason(
    run_cli: RunCli, tmp_path: Path, argv: list[str]
) -> None:
    # Regression: "cannot read: [Errno 2] No such file or directory: '…'" (the path twice).
    missing = tmp_path / "missing"
    result = run_cli(*(word.format(missing=missing) for word in argv))
    assert result.status == 2
    assert result.err == f"rovlink {argv[0]}: {missing}: cannot read: No such file or directory\n"


def test_an_input_file_that_is_not_text(run_cli: RunCli, tmp_path: Path) -> None:
    params = tmp_path / "robot.param"
    params.write_bytes(b"\xff RL_MAX_PWM 90\n")
    result = run_cli("mavlink", "sim://", "--params", str(params))
    assert result.status == 2
    assert result.err == f"rovlink mavlink: {params}: not UTF-8 text\n"


def test_a_directory_as_the_port_is_said_once(run_cli: RunCli, tmp_path: Path) -> None:
    # Regression: pyserial's own text came through: "could not open port …: [Errno 21] …".
    result = run_cli("send", str(tmp_path), "qd")
    assert result.status == 1
    assert result.err == f"rovlink send: cannot open {tmp_path}: Is a directory\n"


_UNKNOWN_SCHEME = "unknown URL scheme nosuch:// (known: "


@pytest.mark.parametrize(
    "command",
    [
        ("send", "nosuch://", "qd"),
        ("monitor", "nosuch://"),
        ("console", "nosuch://"),
        ("check", "nosuch://"),
        ("mavlink", "nosuch://"),
        ("mqtt", "nosuch://", "--broker", "mqtt://127.0.0.1:1", "--robot", "r1"),
        ("web", "nosuch://", "--port", "0"),
        ("tune", "nosuch://", "--yes"),
        (
            "calibrate",
            "nosuch://",
            "--surface-raw",
            "1",
            "--depth-raw",
            "90",
            "--depth",
            "9",
            "--yes",
        ),
        ("demo", "nosuch://"),
        ("fault", "--to", "nosuch://", "--listen", "socket://127.0.0.1:0"),
    ],
    ids=lambda command: command[0],
)
def test_a_mistyped_url_scheme_is_a_usage_error_naming_the_known_ones(
    run_cli: RunCli, command: tuple[str, ...]
) -> None:
    # Before, the command tried to open it and exited 1: "cannot open nosuch://: invalid URL,
    # protocol 'nosuch' not known".
    result = run_cli(*command)
    assert result.status == 2
    assert _UNKNOWN_SCHEME in result.err
    assert "sim://" in result.err
    assert "cannot open" not in result.err


def test_record_with_a_mistyped_url_scheme_makes_no_file(run_cli: RunCli, tmp_path: Path) -> None:
    output = tmp_path / "dive.csv"
    result = run_cli("record", "nosuch://", "-o", str(output))
    assert result.status == 2
    assert _UNKNOWN_SCHEME in result.err
    assert not output.exists()
