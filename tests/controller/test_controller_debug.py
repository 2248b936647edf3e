"""P5: debug lines for dropped frames, changes and failsafe actions; never mistaken for frames."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovlink.controller import LeakAction
from rovlink.protocol import BadFrame, Decoder, Frame, Text
from tests.controller.controller_rig import Rig, make_rig


def _lines(output: bytes) -> list[bytes]:
    assert output.endswith(b"\r\n")
    return output[:-2].split(b"\r\n")


def test_debug_is_off_after_reset(rig: Rig) -> None:
    assert rig.send(b"#mgmp.999!#qx!#mvd.100!") == b""


def test_debug_lines_end_in_crlf_and_name_the_frame_and_reason(debug_rig: Rig) -> None:
    lines = _lines(debug_rig.send(b"#mgmp.999!"))
    assert len(lines) == 1
    assert lines[0].startswith(b"debug: dropped <mgmp.999>: range:")
    assert lines[0].endswith(b"max_pwm must be in 0-255, got 999")


@pytest.mark.parametrize(
    ("frame", "words"),
    [
        (b"#qx!", b"unknown"),
        (b"#" + b"a" * 80 + b"!", b"too_long"),
        (b"#mvd.1a!", b"malformed"),
        (b"#mvd.100!", b"locked"),
        (b"#mvs.+10!", b"locked"),
        (b"#q\x01d!", b"malformed"),
    ],
)
def test_every_dropped_frame_gets_a_line_with_its_reason(
    debug_rig: Rig, frame: bytes, words: bytes
) -> None:
    lines = _lines(debug_rig.send(frame))
    assert len(lines) == 1
    assert words in lines[0]


def test_a_frame_in_the_wrong_mode_gets_a_line(debug_rig: Rig) -> None:
    debug_rig.send(b"#start!")
    debug_rig.controller.read_output()
    assert b"needs direct mode" in debug_rig.send(b"#mvs.+10!")
    debug_rig.send(b"#mvdirect.1!")
    assert b"needs depth mode" in debug_rig.send(b"#mvd.100!")


@pytest.mark.parametrize(
    "frame",
    [
        b"#mgmp.100!",
        b"#mvpdp.1!",
        b"#mvpdi.1!",
        b"#mvpidd.1!",
        b"#mvdirect.1!",
        b"#sdz.10!",
        b"#sdk.100!",
        b"#slreset!",
        b"#crcon!",
        b"#start!",
        b"#stop!",
        b"#debug0!",
    ],
)
def test_every_change_of_mode_or_setting_gets_a_line(debug_rig: Rig, frame: bytes) -> None:
    assert len(_lines(debug_rig.send(frame))) == 1


@pytest.mark.parametrize("frame", [b"#mvd.100!", b"#th.90.10!", b"#h+!", b"#h-!"])
def test_every_set_point_gets_a_line(debug_rig: Rig, frame: bytes) -> None:
    debug_rig.send(b"#start!")
    assert len(_lines(debug_rig.send(frame))) == 1


def test_failsafe_actions_get_a_line() -> None:
    rig = make_rig()
    rig.send(b"#debug1!#start!")
    output = rig.run(2.5)
    assert b"failsafe" in output
    assert b"stopped and locked" in output


def test_debug0_silences_and_debug1_announces(debug_rig: Rig) -> None:
    assert debug_rig.send(b"#debug0!") == b"debug: debug output off\r\n"
    assert debug_rig.send(b"#qx!") == b""
    assert debug_rig.send(b"#debug1!") == b"debug: debug output on\r\n"


def test_debug_lines_never_contain_frame_characters(debug_rig: Rig) -> None:
    output = debug_rig.send(b"#m!gmp.1#$!##qx$!#z.-1!")
    assert output
    assert not set(output) & set(b"#$!")


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200))
def test_no_decoder_mistakes_debug_output_for_a_frame(data: bytes) -> None:
    rig = make_rig()
    rig.send(b"#debug1!")
    output = rig.send(data)
    for event in Decoder().feed(output) + Decoder().end():
        # Replies to queries hidden in the noise are frames; everything else is text.
        assert isinstance(event, Frame | Text), event
        assert not isinstance(event, BadFrame)
        if isinstance(event, Text):
            assert event.text.startswith("debug: ")


def test_text_between_frames_is_reported_without_its_frame_characters(debug_rig: Rig) -> None:
    # An "!" outside a frame is text (P1); the line that reports it must not carry it (P5).
    output = debug_rig.send(b"boot ok!\r\nv1.2!!\r\n")
    assert output.count(b"ignored text between frames") == 2, output
    assert b"!" not in output


@pytest.mark.parametrize(
    ("frame", "words"),
    [(b"#qd!", b"checksum"), (b"#qdFF!", b"checksum"), (b"#qd8C!", b"")],
)
def test_a_frame_dropped_in_checksum_mode_gets_a_line_naming_the_checksum(
    debug_rig: Rig, frame: bytes, words: bytes
) -> None:
    # P3, P4, P5: a frame whose checksum is missing or wrong is dropped, and debug says why.
    debug_rig.send(b"#crcon!")
    output = debug_rig.send(frame)
    if words:
        lines = _lines(output)
        assert len(lines) == 1
        assert lines[0].startswith(b"debug: dropped <" + frame[1:-1] + b">: " + words)
    else:
        assert output.startswith(b"$qd.")


def test_a_reply_sent_to_the_controller_gets_a_line(debug_rig: Rig) -> None:
    assert _lines(debug_rig.send(b"$qd.1!")) == [b"debug: dropped <qd.1>: a reply, not a command"]


@pytest.mark.parametrize(
    ("setup", "frame"), [(b"#crcon!", b"#crcoff!"), (b"#mvdirect.1!", b"#mvdirect.0!")]
)
def test_switching_a_mode_back_gets_a_line_too(debug_rig: Rig, setup: bytes, frame: bytes) -> None:
    debug_rig.send(setup)
    assert len(_lines(debug_rig.send(frame))) == 1


def test_a_vertical_thrust_set_point_gets_a_line(debug_rig: Rig) -> None:
    debug_rig.send(b"#start!#mvdirect.1!")
    assert _lines(debug_rig.send(b"#mvs.-50!")) == [b"debug: vertical thrust -50 %"]


@pytest.mark.parametrize(
    ("action", "words"),
    [
        (LeakAction.NONE, [b"leak detected, action none"]),
        (LeakAction.STOP, [b"leak detected, action stop", b"leak: motors stopped and locked"]),
        (LeakAction.SURFACE, [b"leak detected, action surface", b"leak: surfacing"]),
    ],
)
def test_a_leak_and_its_action_get_a_line_each(action: LeakAction, words: list[bytes]) -> None:
    # P5: every failsafe action gets a line; P14: the leak action is one.
    rig = make_rig(leak_action=action, watchdog_s=0.0)
    rig.send(b"#debug1!#start!#th.0.50!")
    rig.controller.read_output()
    rig.leak.pulse()
    lines = _lines(rig.tick())
    assert len(lines) == len(words)
    for line, word in zip(lines, words, strict=True):
        assert word in line
