"""P4 (no acknowledgements), P12 (qsa), P15 (attitude), P19 (a query is answered on receipt)."""

from __future__ import annotations

import pytest

from rovlink.controller import Attitude
from rovlink.protocol import COMMANDS, Decoder, Frame, Kind, Spec, Text, VerticalMode
from tests.controller.controller_rig import Rig


def _valid_frame(spec: Spec) -> bytes:
    values = ".".join(str(argument.minimum) for argument in spec.arguments)
    return f"#{spec.name}{'.' + values if values else ''}!".encode()


def _replies(output: bytes) -> list[str]:
    events = Decoder().feed(output)
    assert all(isinstance(event, Frame) for event in events), events
    return [event.message.name for event in events if isinstance(event, Frame)]


SETTINGS = [spec for spec in COMMANDS if not spec.is_query]
QUERIES = [spec for spec in COMMANDS if spec.is_query]


@pytest.mark.parametrize("spec", SETTINGS, ids=lambda spec: spec.name)
def test_commands_that_set_something_produce_no_response(rig: Rig, spec: Spec) -> None:
    rig.send(b"#start!")
    if spec.mode is VerticalMode.DIRECT:
        rig.send(b"#mvdirect.1!")
    output = rig.send(_valid_frame(spec)) + rig.tick()
    # debug1 announces itself in a debug line; no command produces a frame.
    assert not [event for event in Decoder().feed(output) if not isinstance(event, Text)]
    assert output in (b"", b"debug: debug output on\r\n")


@pytest.mark.parametrize("spec", QUERIES, ids=lambda spec: spec.name)
def test_each_query_is_answered_at_once_with_its_replies(rig: Rig, spec: Spec) -> None:
    # The reply is written inside receive(): no tick is needed (P19).
    assert _replies(rig.send(_valid_frame(spec))) == list(spec.replies)


def test_queries_are_answered_while_locked_and_in_either_mode(rig: Rig) -> None:
    assert rig.controller.locked
    assert rig.send(b"#qd!") == b"$qd.0!"
    rig.send(b"#mvdirect.1!")
    assert rig.send(b"#qd!") == b"$qd.0!"


def test_qsa_is_the_six_sensor_replies_in_order(rig: Rig) -> None:
    rig.pressure.raw = 70
    rig.imu.attitude = Attitude(15.4, -1.2, 359.6)
    assert rig.send(b"#qsa!") == b"$qd.100!$qr.70!$q.l.0!$qro.+15!$qpi.-1!$qhe.0!"


def test_qsa_reports_the_leak_latch(rig: Rig) -> None:
    rig.leak.pulse()
    rig.tick()
    assert b"$q.l.1!" in rig.send(b"#qsa!")


@pytest.mark.parametrize(
    ("roll_deg", "frame"),
    [
        (15.4, b"$qro.+15!"),
        (-1.2, b"$qro.-1!"),
        (0.0, b"$qro.+0!"),
        (-0.4, b"$qro.+0!"),
        (0.6, b"$qro.+1!"),
        (2.5, b"$qro.+3!"),  # halves go up, not to the even neighbour
        (1.5, b"$qro.+2!"),
        (-2.5, b"$qro.-2!"),
        (-89.6, b"$qro.-90!"),
        (120.0, b"$qro.+90!"),
        (-95.2, b"$qro.-90!"),
    ],
)
def test_roll_is_rounded_clamped_and_signed(rig: Rig, roll_deg: float, frame: bytes) -> None:
    rig.imu.attitude = Attitude(roll_deg, 0.0, 0.0)
    assert rig.send(b"#qro!") == frame


def test_pitch_is_formatted_like_roll(rig: Rig) -> None:
    rig.imu.attitude = Attitude(0.0, -7.7, 0.0)
    assert rig.send(b"#qpi!") == b"$qpi.-8!"
    rig.imu.attitude = Attitude(0.0, 91.0, 0.0)
    assert rig.send(b"#qpi!") == b"$qpi.+90!"


@pytest.mark.parametrize(
    ("heading_deg", "frame"),
    [
        (0.0, b"$qhe.0!"),
        (359.4, b"$qhe.359!"),
        (359.6, b"$qhe.0!"),
        (360.0, b"$qhe.0!"),
        (90.2, b"$qhe.90!"),
        (-0.4, b"$qhe.0!"),
        (-1.0, b"$qhe.359!"),
    ],
)
def test_heading_is_written_0_to_359(rig: Rig, heading_deg: float, frame: bytes) -> None:
    rig.imu.attitude = Attitude(0.0, 0.0, heading_deg)
    assert rig.send(b"#qhe!") == frame


def test_a_reply_is_never_taken_as_a_command(debug_rig: Rig) -> None:
    output = debug_rig.send(b"$qd.100!")
    assert output.startswith(b"debug: dropped <qd.100>: a reply, not a command")
    assert _replies(debug_rig.send(b"#qd!")) == ["qd"]


def test_responses_use_the_response_table(rig: Rig) -> None:
    # Every reply the controller writes decodes as a response frame of the table.
    rig.pressure.raw = 1024
    events = Decoder().feed(rig.send(b"#qsa!"))
    assert [event.message.kind for event in events if isinstance(event, Frame)] == [
        Kind.RESPONSE
    ] * 6
