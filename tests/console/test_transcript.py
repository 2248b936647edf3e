"""The console's output lines: sent frames, replies with their frames, debug text."""

from __future__ import annotations

from rovlink.console.transcript import (
    error_line,
    event_line,
    plain_text,
    reply_line,
    sent_lines,
)
from rovlink.piloting import SentFrame
from rovlink.protocol import BadFrame, Command, Frame, Reason, Response, Text


def test_a_reply_shows_its_words_and_frame() -> None:
    line = reply_line(Response("qd", (123,)))
    assert plain_text(line).split() == ["qd", "→", "123", "cm", "$qd.123!"]
    assert line[0][0] == "class:reply"
    assert line[1] == ("class:frame", "$qd.123!")


def test_a_reply_in_checksum_mode_shows_the_checksummed_frame() -> None:
    assert plain_text(reply_line(Response("qro", (-1,)), "crc8")).endswith("$qro.-198!")


def test_a_leak_reply_is_an_alarm() -> None:
    line = reply_line(Response("q.l", (1,)))
    assert line[0][0] == "class:alarm"
    assert "LEAK" in plain_text(line)


def test_words_longer_than_the_column_never_run_into_the_frame() -> None:
    # Before, the leak reply read "q.l → LEAK: the sensor fired since the last reset$q.l.1!".
    words, frame = reply_line(Response("q.l", (1,)))
    assert words[1].endswith("reset  ")
    assert frame[1] == "$q.l.1!"
    short_words, _ = reply_line(Response("qd", (123,)))
    assert len(short_words[1]) == len(plain_text(reply_line(Response("qd", (5,))))) - len("$qd.5!")


def test_sent_frames_and_their_warnings() -> None:
    (line,) = sent_lines(SentFrame(b"#qd8C!", Command("qd")))
    assert plain_text(line) == "  → #qd8C!"
    _first, warning = sent_lines(SentFrame(b"#mvd.5!", Command("mvd", (5,)), "dropped: locked"))
    assert warning == [("class:warning", "  ! dropped: locked")]
    (raw,) = sent_lines(SentFrame(b"#bogus!", None))
    assert "not a command" in plain_text(raw)


def test_events_from_the_controller_have_their_own_styles() -> None:
    assert event_line(Text("debug: motors unlocked")) == [
        ("class:debug", "  ⋯ debug: motors unlocked")
    ]
    dropped = event_line(BadFrame(Reason.CHECKSUM, b"$qd.1200!", "checksum mismatch"))
    assert dropped[0][0] == "class:warning"
    assert "$qd.1200!" in plain_text(dropped)
    assert "checksum mismatch" in plain_text(dropped)
    stray = event_line(Frame(Response("qd", (5,)), b"$qd.5!"))
    assert "$qd.5!" in plain_text(stray)
    assert plain_text(error_line("no reply")) == "  ✗ no reply"


def test_control_characters_from_the_controller_are_shown_not_sent_to_the_terminal() -> None:
    # Regression: line noise such as an escape sequence or a bell reached the terminal as is.
    text = plain_text(event_line(Text("\x1b[31mRED\x07\tend")))
    assert text == "  ⋯ \\x1b[31mRED\\x07\tend"
    dropped = plain_text(event_line(BadFrame(Reason.MALFORMED, b"$q\x1b]0;x\x07!", "malformed")))
    assert "$q\\x1b]0;x\\x07!" in dropped
