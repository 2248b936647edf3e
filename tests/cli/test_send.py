"""``rovlink send``: commands through the driver, replies printed; bad commands send nothing."""

from __future__ import annotations

import json
import re
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from rovlink.cli.send import group_words
from rovlink.client import CommandTextError, parse_command_text
from rovlink.protocol import get_algorithm
from tests.cli.closed_pipe import run_into_a_closed_pipe
from tests.cli.conftest import RunCli
from tests.cli.silent_controller import SilentController
from tests.client.conftest import REPLY_TIMEOUT_S, wait_until
from tests.client.fake_controller import FakeControllerServer

#: ``--timeout`` where replies are expected: long enough for a loaded machine.
REPLY_TIMEOUT = str(REPLY_TIMEOUT_S)


def test_send_prints_decoded_replies(run_cli: RunCli) -> None:
    result = run_cli(
        "send",
        "sim://?seed=1",
        "start",
        "th",
        "270",
        "25",
        "qsa",
        "mvs -50",
        "#qd!",
        "stop",
        "--timeout",
        REPLY_TIMEOUT,
    )
    assert result.status == 0, result.err
    lines = result.out.splitlines()
    assert lines[:3] == ["> #start!", "> #th.270.25!", "> #qsa!"]
    replies = [line for line in lines if line.startswith("<")]
    assert [line.split()[1].split(".")[0] for line in replies] == [
        "$qd",
        "$qr",
        "$q",
        "$qro",
        "$qpi",
        "$qhe",
        "$qd",
    ]
    assert "depth_cm=" in replies[0]
    assert lines[-1] == "> #stop!"


def test_send_json(run_cli: RunCli) -> None:
    result = run_cli("send", "sim://", "qhe", "--json", "--checksum", "--timeout", REPLY_TIMEOUT)
    assert result.status == 0, result.err
    (line,) = result.out.splitlines()
    record = json.loads(line)
    assert record["command"] == "#qhe" + get_algorithm("crc8").digits(b"qhe").decode() + "!"
    assert record["replies"][0]["name"] == "qhe"
    assert 0 <= record["replies"][0]["values"]["heading_deg"] <= 360


def test_replies_are_shown_as_they_came_with_their_checksums(run_cli: RunCli) -> None:
    # Before, a reply was shown without the checksum it came with ('$qd.0!' for '$qd.0A2!').
    arguments = ("sim://", "--checksum", "--timeout", REPLY_TIMEOUT)
    result = run_cli("send", *arguments, "qd", "crcoff", "qd")
    assert result.status == 0, result.err
    crc = get_algorithm("crc8").digits(b"qd.0").decode()
    assert result.out.splitlines()[1] == f"< $qd.0{crc}!  depth_cm=0"
    assert result.out.splitlines()[-1] == "< $qd.0!  depth_cm=0"  # checksums off by then
    result = run_cli("send", *arguments, "--json", "qd")
    assert json.loads(result.out)["replies"][0]["frame"] == f"$qd.0{crc}!"


def test_raw_frames_are_sent_exactly_as_given(run_cli: RunCli) -> None:
    # In checksum mode a raw frame keeps the checksum it was typed with; a friendly command
    # gets one; both are shown as they went on the wire.
    result = run_cli("send", "--checksum", "--timeout", REPLY_TIMEOUT, "sim://", "#qd8C!", "qr")
    assert result.status == 0, result.err
    lines = result.out.splitlines()
    assert lines[0] == "> #qd8C!"
    assert lines[1].startswith("< $qd.")
    assert lines[2] == "> #qr" + get_algorithm("crc8").digits(b"qr").decode() + "!"
    assert lines[3].startswith("< $qr.")


def test_a_raw_frame_must_be_a_whole_frame(run_cli: RunCli) -> None:
    result = run_cli("send", "sim://", "#qd")
    assert result.status == 2
    assert "a raw frame is" in result.err


def test_a_bad_command_is_reported_before_anything_is_sent(run_cli: RunCli) -> None:
    result = run_cli("send", "sim://", "qd", "th 400 25")
    assert result.status == 2
    assert "direction_deg must be in 0–360, got 400" in result.err
    assert "> #qd!" not in result.out


def test_unknown_commands_and_urls(run_cli: RunCli) -> None:
    result = run_cli("send", "sim://", "thrust 1")
    assert result.status == 2
    assert "did you mean th" in result.err
    result = run_cli("send", "sim://?bogus=1", "qd")
    assert result.status == 2
    assert "unknown sim option" in result.err


@pytest.mark.integration
def test_nothing_listening_is_an_error_exit(run_cli: RunCli) -> None:
    result = run_cli("send", "socket://127.0.0.1:1", "qd")
    assert result.status == 1
    assert result.err == "rovlink send: cannot open socket://127.0.0.1:1: Connection refused\n"


def test_a_raw_frame_without_its_checksum_gets_it_in_checksum_mode(run_cli: RunCli) -> None:
    # Regression: '#qd!' in checksum mode printed nothing and exited 0.
    result = run_cli("send", "--checksum", "--timeout", REPLY_TIMEOUT, "sim://", "#qd!")
    assert result.status == 0, result.err
    crc = get_algorithm("crc8").digits(b"qd").decode()
    lines = result.out.splitlines()
    assert lines[0] == f"> #qd{crc}!"
    assert lines[1].startswith("< $qd.")


def test_a_raw_frame_the_controller_would_drop_is_refused(run_cli: RunCli) -> None:
    result = run_cli("send", "--checksum", "sim://", "#qd00!")
    assert result.status == 2
    assert "command 1 ('#qd00!'): the controller would drop it" in result.err
    assert "crc8" in result.err
    assert result.out == ""


@pytest.mark.integration
def test_the_help_gives_the_statuses_the_command_ends_with(run_cli: RunCli) -> None:
    # Before, the help said a frame the controller would drop exits with status 1, as a failure
    # while sending does; it is refused before anything is sent, as a usage error (2).
    refused = run_cli("send", "--checksum", "sim://", "#qd00!").status
    failed = run_cli("send", "socket://127.0.0.1:1", "qd").status
    help_text = " ".join(run_cli("send", "--help").out.split())
    assert f"a raw frame the controller would drop, is refused (status {refused})" in help_text
    assert f"a lost link) exits with status {failed}" in help_text


@pytest.mark.parametrize(
    ("word", "why"),
    [
        # Before, "the controller would drop it: not a command frame", where it takes both.
        ("#qd!#qr!", "more than one frame in one word: give each as a word of its own "
         "('#qd!' '#qr!')"),
        # Before, sent as typed: #qd! and then "x!" on the line, unsaid.
        ("#qd!x!", "a raw frame is '#', a body and '!', with nothing after the '!'"),
        ("#qd!!", "a raw frame is '#', a body and '!', with nothing after the '!'"),
    ],
)  # fmt: skip
def test_more_than_a_frame_in_one_word_is_refused(run_cli: RunCli, word: str, why: str) -> None:
    result = run_cli("send", "sim://", word)
    assert (result.status, result.out) == (2, "")
    assert result.err.splitlines()[-1] == f"rovlink send: error: command 1 ({word!r}): {why}"


def test_raw_shows_the_exact_bytes_both_ways(run_cli: RunCli) -> None:
    result = run_cli("send", "--raw", "--checksum", "--timeout", REPLY_TIMEOUT, "sim://", "qd")
    assert result.status == 0, result.err
    xor = get_algorithm("crc8")
    lines = result.out.splitlines()
    assert lines[0] == ">> #crcoff!#qd!"  # the readiness probe (P21)
    assert ">> #crcon!" in lines
    assert f">> #qd{xor.digits(b'qd').decode()}!" in lines
    # (The first replies answer the readiness probe, plainly.)
    received = [
        line
        for line in lines
        if line.startswith("<< ") and not line.endswith(".0!") and "$qd." in line
    ][-1:]
    assert received
    assert received[0].startswith("<< $qd.")
    body = received[0][4 : received[0].index("!") - 2]  # "qd.12" of "<< $qd.12XX!"
    assert received[0].endswith(xor.digits(body.encode()).decode() + "!")


def test_raw_with_json_keeps_every_line_json(run_cli: RunCli) -> None:
    # `send URL --json --raw qd | jq`: before, the ">> #qd!" lines came among the JSON objects
    # and the first of them stopped the parser.
    result = run_cli("send", "--raw", "--json", "--timeout", REPLY_TIMEOUT, "sim://", "qd")
    assert result.status == 0, result.err
    objects = [json.loads(line) for line in result.out.splitlines()]
    assert objects[0] == {"written": "#crcoff!#qd!"}  # the readiness probe (P21)
    assert {"written": "#qd!"} in objects
    assert objects[-1]["command"] == "#qd!"
    read = "".join(str(item["read"]) for item in objects if "read" in item)
    assert read.endswith(objects[-1]["replies"][0]["frame"])


def test_an_unknown_raw_frame_is_refused_before_anything_is_sent(run_cli: RunCli) -> None:
    result = run_cli("send", "sim://", "qd", "#zz!")
    assert result.status == 2
    assert "command 2 ('#zz!'): the controller would drop it" in result.err
    assert result.out == ""


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (["--timeout", "1e10"], "argument --timeout: 1e10 s is more than the maximum, 3600 s"),
        (["--timeout", "nan"], "argument --timeout: 'nan' is not a number"),
        (["--timeout", "0"], "argument --timeout: 0 s is less than the minimum, 0.001 s"),
        (
            ["--retries", "99999999999999999999"],
            "argument --retries: 99999999999999999999 is not in 0–100",
        ),
        (
            ["--algorithm", "md5"],
            "argument --algorithm: unknown checksum algorithm 'md5'; known: crc8, sum8, xor",
        ),
        (["--baudrate", "fast"], "argument --baudrate: 'fast' is not an integer"),
    ],
)
def test_bad_link_options_are_one_line_usage_errors(
    run_cli: RunCli, option: list[str], message: str
) -> None:
    result = run_cli("send", *option, "sim://", "qd")
    assert result.status == 2
    assert result.err.splitlines()[-1] == f"rovlink send: error: {message}"
    assert "Traceback" not in result.err


def test_an_algorithm_is_named_in_any_case(run_cli: RunCli) -> None:
    # (Before, "CRC8" as a datasheet writes it was refused as unknown.)
    result = run_cli(
        "send",
        "--checksum",
        "--algorithm",
        "SUM8",
        "sim://?algorithm=sum8",
        "qd",
        "--timeout",
        REPLY_TIMEOUT,
    )
    assert result.status == 0, result.err
    assert "depth_cm=" in result.out


def test_a_device_that_is_not_a_serial_port(run_cli: RunCli) -> None:
    result = run_cli("send", "/dev/null", "qd")
    assert result.status == 1
    assert result.err == "rovlink send: /dev/null: not a serial port\n"


def test_a_missing_device_is_said_once(run_cli: RunCli) -> None:
    result = run_cli("send", "/dev/ttyUSB_rovlink_none", "qd")
    assert result.status == 1
    assert result.err == (
        "rovlink send: cannot open /dev/ttyUSB_rovlink_none: No such file or directory\n"
    )


@pytest.mark.parametrize(
    ("words", "texts"),
    [
        (["qd"], ["qd"]),
        (["th", "270", "25", "qd"], ["th 270 25", "qd"]),
        (["mvs", "-50", "mvs", "+20"], ["mvs -50", "mvs +20"]),
        (["#th.1.2!", "3"], ["#th.1.2!", "3"]),
        # A word that is not a number stays with the command that wants a value (before, it
        # was split off, and the error said "takes 1 value(s), got 0").
        (["mvd", "abc"], ["mvd abc"]),
        (["mvd", "1e3", "qd"], ["mvd 1e3", "qd"]),
        (["th", "90", "x"], ["th 90 x"]),
        (["th", "x", "90", "qd"], ["th x 90", "qd"]),
        (["th", "90", "50", "x"], ["th 90 50", "x"]),  # (th has its values: x starts the next one)
        (["mvd", "qd"], ["mvd", "qd"]),  # (a command's name is never taken as a value)
        (["th", "1", "2", "3"], ["th 1 2 3"]),  # (too many numbers: said so by th)
    ],
)
def test_word_grouping(words: list[str], texts: list[str]) -> None:
    assert group_words(words) == texts


@pytest.mark.parametrize(
    ("words", "position", "text", "message"),
    [
        (["mvd", "abc"], 1, "mvd abc", "target_depth_cm must be an integer in 0–9999, got 'abc'"),
        (
            ["qd", "mvd", "1e3"],
            2,
            "mvd 1e3",
            "target_depth_cm must be an integer in 0–9999, got '1e3'",
        ),
        (["th", "90", "x"], 1, "th 90 x", "power_percent must be an integer in 0–100, got 'x'"),
        (
            ["th", "9.5", "10"],
            1,
            "th 9.5 10",
            "direction_deg must be an integer in 0–360, got '9.5'",
        ),
    ],
)
def test_a_value_that_is_not_a_number_is_named_with_its_argument(
    run_cli: RunCli, words: list[str], position: int, text: str, message: str
) -> None:
    result = run_cli("send", "sim://", *words)
    assert result.status == 2
    name = text.split(maxsplit=1)[0]
    assert f"command {position} ({text!r}): {name}: {message}" in result.err
    assert result.out == ""
    # The console, which reads its line with the same parser, says the same.
    with pytest.raises(CommandTextError, match=re.escape(f"{name}: {message}")):
        parse_command_text(text)


class NoisyController:
    """Accepts one connection; answers ``#qd!`` after a line of terminal escapes and a bell."""

    NOISE = b"\x1b[31mRED\x07\r\n"

    def __init__(self) -> None:
        self._server = socket.create_server(("127.0.0.1", 0))
        self.url = f"socket://127.0.0.1:{self._server.getsockname()[1]}"
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        connection, _ = self._server.accept()
        with connection:
            received = b""
            while data := connection.recv(4096):
                received += data
                while b"#qd!" in received:
                    _, _, received = received.partition(b"#qd!")
                    connection.sendall(self.NOISE + b"$qd.5!\r\n")

    def close(self) -> None:
        self._server.close()


@pytest.fixture
def noisy() -> Iterator[NoisyController]:
    controller = NoisyController()
    yield controller
    controller.close()


@pytest.mark.integration
def test_controller_text_is_printed_with_its_control_characters_escaped(
    run_cli: RunCli, noisy: NoisyController, tmp_path: Path
) -> None:
    # Regression: "controller: ^[[31mRED^G": line noise could drive the user's terminal.
    recording = tmp_path / "noisy.jsonl"
    result = run_cli("send", noisy.url, "qd", "--boot-timeout", "0", "--record", str(recording))
    assert result.status == 0, result.err
    assert "controller: \\x1b[31mRED\\x07\n" in result.err
    assert "\x1b" not in result.err + result.out
    replayed = run_cli("replay", str(recording))
    assert replayed.status == 0, replayed.err
    assert "text: \\x1b[31mRED\\x07\n" in replayed.out
    assert "\x1b" not in replayed.out


@pytest.mark.integration
@pytest.mark.parametrize(
    ("line", "stopped"),
    [(["start", "th 270 25", "qsa", "stop"], True), (["qd", "start"], False)],
    ids=["after motion", "before any"],
)
def test_a_failed_query_after_motion_ends_the_line_with_stop(
    run_cli: RunCli, silent: SilentController, line: list[str], stopped: bool
) -> None:
    # Before, the line ended at the failed #qsa! and the robot was left at 25 % thrust: its
    # own `stop` was never sent.
    link = ["--boot-timeout", "0", "--timeout", "0.05", "--retries", "0"]
    result = run_cli("send", silent.url, *link, *line)
    assert result.status == 1
    if stopped:
        assert "(sent #stop!)" in result.err
        assert silent.wait_until(lambda received: received.endswith(b"#qsa!#stop!"))
    else:
        assert "#stop!" not in result.err
        assert b"#start!" not in silent.received  # the rest of the line is not sent


@pytest.mark.integration
def test_an_output_closed_after_motion_still_ends_the_line_with_stop() -> None:
    # `send URL start "th 270 25" qd … stop | head -1`: before, the closed output ended the
    # line quietly, status 0, and the robot drove on at 25 % (its own `stop` never sent).
    port = FakeControllerServer(script=("reply", "late"))  # (the probe's #qd!, then the line's)
    try:
        line = ["start", "th 270 25", "qd", "qd", "stop"]
        process = subprocess.Popen(
            [sys.executable, "-m", "rovlink", "send", port.url, *line],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        assert process.stdout is not None
        assert process.stdout.readline() == b"> #start!\n"
        process.stdout.close()  # as `head -1` does, while the #qd! waits for its late reply
        _, stderr = process.communicate(timeout=15)
        assert "rovlink send: sent #stop!" in stderr.decode(), stderr
        assert wait_until(lambda: port.fakes[0].frames()[-1:] == ["#stop!"])
        assert port.fakes[0].frames().count("#stop!") == 1
    finally:
        port.close()


@pytest.mark.integration
def test_raw_output_closed_after_motion_still_ends_the_line_with_stop() -> None:
    # `send URL --raw start "th 270 25" … | head -4`: before, the closed output was raised by
    # the shown bytes of the next frame before it was written, and then by those of #stop!,
    # which never went ("could not send #stop!: [Errno 32] Broken pipe", status 1).
    port = FakeControllerServer(script=("reply", "late"))  # (the probe's #qd!, then the line's)
    try:
        line = ["start", "th 270 25", "qd", "qd", "stop"]
        process = subprocess.Popen(
            [sys.executable, "-m", "rovlink", "send", port.url, "--raw", *line],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        assert process.stdout is not None
        while process.stdout.readline() not in (b"> #start!\n", b""):
            pass
        process.stdout.close()  # as `head` does, once it has the lines it wanted
        _, stderr = process.communicate(timeout=15)
        assert (process.returncode, stderr.decode()) == (0, "rovlink send: sent #stop!\n")
        assert wait_until(lambda: port.fakes[0].frames()[-1:] == ["#stop!"])
        assert port.fakes[0].frames().count("#stop!") == 1
    finally:
        port.close()


@pytest.mark.integration
def test_raw_output_closed_before_the_first_line_ends_quietly() -> None:
    # `send sim:// --raw qd | head -0`: before, "cannot open sim://: Broken pipe", status 1:
    # the probe's bytes, shown as the link opened, were taken for the link's failure.
    result = run_into_a_closed_pipe("send", "sim://", "--raw", "qd")
    assert (result.returncode, result.stderr) == (0, "")


def test_commands_that_leave_the_robot_moving_are_followed_by_stop_as_the_link_closes(
    run_cli: RunCli,
) -> None:
    # `rovlink send URL start "th 0 50"`: the command ends at once, and the robot is not left
    # driving until the controller's watchdog (or for good, with it off).
    result = run_cli("send", "sim://?seed=3", "start", "th 0 50", "--raw")
    assert result.status == 0, result.err
    sent = [line for line in result.out.splitlines() if line.startswith(">> ")]
    assert sent[-2:] == [">> #th.0.50!", ">> #stop!"]


@pytest.mark.integration
def test_a_noisy_line_on_connecting_asks_for_more_retries_as_the_option(
    run_cli: RunCli,
) -> None:
    # The driver asks a program for `retries=N`; the command line names its own option.
    port = FakeControllerServer(script=("reply", *["corrupt"] * 10))  # (the probe answered)
    try:
        result = run_cli("send", port.url, "--checksum", "--retries", "1", "--timeout", "0.2", "qd")
    finally:
        port.close()
    assert result.status == 1
    assert "(a noisy line? more attempts: --retries N;" in result.err
    assert "retries=" not in result.err
