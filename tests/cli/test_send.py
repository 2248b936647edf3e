"""``rovlink send``: commands through the driver, replies printed; bad commands send nothing."""

from __future__ import annotations

import json
import re

import pytest
from typer.testing import CliRunner

from rovlink.cli import app
from rovlink.cli.send import group_words
from rovlink.protocol import get_algorithm
from tests.client.conftest import REPLY_TIMEOUT_S

runner = CliRunner()
#: ``--timeout`` where replies are expected: long enough for a loaded machine.
REPLY_TIMEOUT = str(REPLY_TIMEOUT_S)


def _flat(output: str) -> str:
    """The output with rich's error panel borders and line wrapping taken out."""
    return " ".join(re.sub(r"[│╭╮╰╯─]", " ", output).split())


def test_send_prints_decoded_replies() -> None:
    result = runner.invoke(app, ["send", "sim://?seed=1", "start", "th", "270", "25", "qsa",
                                 "mvs -50", "#qd!", "stop", "--timeout", REPLY_TIMEOUT])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[:3] == ["> #start!", "> #th.270.25!", "> #qsa!"]
    replies = [line for line in lines if line.startswith("<")]
    assert [line.split()[1].split(".")[0] for line in replies] == [
        "$qd", "$qr", "$q", "$qro", "$qpi", "$qhe", "$qd",
    ]
    assert "depth_cm=" in replies[0]
    assert lines[-1] == "> #stop!"


def test_send_json() -> None:
    result = runner.invoke(app, ["send", "sim://", "qhe", "--json", "--checksum",
                                 "--timeout", REPLY_TIMEOUT])
    assert result.exit_code == 0, result.output
    (line,) = result.output.splitlines()
    record = json.loads(line)
    assert record["command"] == "#qhe" + get_algorithm("crc8").digits(b"qhe").decode() + "!"
    assert record["replies"][0]["name"] == "qhe"
    assert 0 <= record["replies"][0]["values"]["heading_deg"] <= 360


def test_raw_frames_are_sent_exactly_as_given() -> None:
    # In checksum mode a raw frame keeps the checksum it was typed with; a friendly command
    # gets one; both are shown as they went on the wire.
    result = runner.invoke(
        app, ["send", "--checksum", "--timeout", REPLY_TIMEOUT, "sim://", "#qd8C!", "qr"]
    )
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0] == "> #qd8C!"
    assert lines[1].startswith("< $qd.")
    assert lines[2] == "> #qr" + get_algorithm("crc8").digits(b"qr").decode() + "!"
    assert lines[3].startswith("< $qr.")


def test_a_raw_frame_must_be_a_whole_frame() -> None:
    result = runner.invoke(app, ["send", "sim://", "#qd"])
    assert result.exit_code == 2
    assert "a raw frame is" in _flat(result.output)


def test_a_bad_command_is_reported_before_anything_is_sent() -> None:
    result = runner.invoke(app, ["send", "sim://", "qd", "th 400 25"])
    assert result.exit_code == 2
    assert "direction_deg must be in 0–360, got 400" in _flat(result.output)
    assert "> #qd!" not in result.output


def test_unknown_commands_and_urls() -> None:
    result = runner.invoke(app, ["send", "sim://", "thrust 1"])
    assert result.exit_code == 2
    assert "did you mean th" in _flat(result.output)
    result = runner.invoke(app, ["send", "sim://?bogus=1", "qd"])
    assert result.exit_code == 2
    assert "unknown sim option" in _flat(result.output)


@pytest.mark.integration
def test_nothing_listening_is_an_error_exit() -> None:
    result = runner.invoke(app, ["send", "socket://127.0.0.1:1", "qd"])
    assert result.exit_code == 1
    assert "could not connect" in result.output


@pytest.mark.parametrize(
    ("words", "texts"),
    [
        (["qd"], ["qd"]),
        (["th", "270", "25", "qd"], ["th 270 25", "qd"]),
        (["mvs", "-50", "mvs", "+20"], ["mvs -50", "mvs +20"]),
        (["#th.1.2!", "3"], ["#th.1.2!", "3"]),
    ],
)
def test_word_grouping(words: list[str], texts: list[str]) -> None:
    assert group_words(words) == texts
