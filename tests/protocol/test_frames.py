"""Encoding and body parsing: every example of the seed, ranges, numbers (P1, P6, P15)."""

from __future__ import annotations

import pytest

from rovlink.protocol import (
    COMMANDS,
    RESPONSES,
    ArgumentCountError,
    ArgumentError,
    BadFrame,
    Command,
    Decoder,
    Frame,
    Kind,
    Reason,
    Response,
    UnknownCommandError,
    encode,
    parse_body,
)

# Every literal frame of the original specification, with the name and values it decodes to.
SEED_FRAMES: list[tuple[bytes, str, list[int]]] = [
    (b"#crcon!", "crcon", []),
    (b"#crcoff!", "crcoff", []),
    (b"#stop!", "stop", []),
    (b"#start!", "start", []),
    (b"#debug1!", "debug1", []),
    (b"#debug0!", "debug0", []),
    (b"#mgmp.0!", "mgmp", [0]),
    (b"#mgmp.64!", "mgmp", [64]),
    (b"#mgmp.128!", "mgmp", [128]),
    (b"#mvpdp.7!", "mvpdp", [7]),
    (b"#mvpdp.92!", "mvpdp", [92]),
    (b"#mvpdi.37!", "mvpdi", [37]),
    (b"#mvpdi.4!", "mvpdi", [4]),
    (b"#mvpidd.11!", "mvpidd", [11]),
    (b"#mvpidd.9!", "mvpidd", [9]),
    (b"#mvdirect.1!", "mvdirect", [1]),
    (b"#mvdirect.0!", "mvdirect", [0]),
    (b"#mvs.+100!", "mvs", [100]),
    (b"#mvs.-50!", "mvs", [-50]),
    (b"#mvd.100!", "mvd", [100]),
    (b"#mvd.576!", "mvd", [576]),
    (b"#th.0.100!", "th", [0, 100]),
    (b"#th.180.50!", "th", [180, 50]),
    (b"#th.270.25!", "th", [270, 25]),
    (b"#qd!", "qd", []),
    (b"#qr!", "qr", []),
    (b"#q.l!", "q.l", []),
    (b"$q.l.1!", "q.l", [1]),
    (b"$q.l.0!", "q.l", [0]),
    (b"#slreset!", "slreset", []),
    (b"#qro!", "qro", []),
    (b"$qro.-1!", "qro", [-1]),
    (b"$qro.+15!", "qro", [15]),
    (b"#qpi!", "qpi", []),
    (b"$qpi.-1!", "qpi", [-1]),
    (b"$qpi.+15!", "qpi", [15]),
    (b"#qhe!", "qhe", []),
    (b"#qsa!", "qsa", []),
    (b"#h+!", "h+", []),
    (b"#h-!", "h-", []),
]


def _decode_one(raw: bytes, **options: object) -> Frame:
    events = Decoder(**options).feed(raw)  # type: ignore[arg-type]
    assert len(events) == 1, events
    event = events[0]
    assert isinstance(event, Frame), event
    return event


@pytest.mark.parametrize(("raw", "name", "values"), SEED_FRAMES)
def test_every_seed_frame_decodes(raw: bytes, name: str, values: list[int]) -> None:
    frame = _decode_one(raw)
    assert frame.message.name == name
    assert list(frame.message.values) == values
    assert frame.raw == raw


@pytest.mark.parametrize(("raw", "name", "values"), SEED_FRAMES)
def test_every_seed_frame_encodes_back(raw: bytes, name: str, values: list[int]) -> None:
    cls = Command if raw.startswith(b"#") else Response
    assert encode(cls(name, tuple(values))) == raw


@pytest.mark.parametrize(
    ("raw", "values"),
    [
        (b"$qro.-.1!", [-1]),
        (b"$qpi.-.7!", [-7]),
        (b"$qpi.+.7!", [7]),
        (b"$qro.15!", [15]),
        (b"$qro.+0!", [0]),
        (b"$qro.-0!", [0]),
    ],
)
def test_attitude_accepts_template_and_unsigned_forms(raw: bytes, values: list[int]) -> None:
    assert list(_decode_one(raw).message.values) == values


def test_signed_values_are_written_with_a_sign_and_zero_as_plus_zero() -> None:
    assert encode(Response("qro", (0,))) == b"$qro.+0!"
    assert encode(Response("qpi", (-7,))) == b"$qpi.-7!"
    assert encode(Command("mvs", (5,))) == b"#mvs.+5!"


def test_leading_zeros_are_accepted_and_not_written() -> None:
    frame = _decode_one(b"#mvd.0100!")
    assert frame.message == Command("mvd", (100,))
    assert encode(frame.message) == b"#mvd.100!"


def test_mvs_accepts_a_non_negative_value_without_sign() -> None:
    assert _decode_one(b"#mvs.50!").message == Command("mvs", (50,))


def test_alias_mvpdd_decodes_as_mvpidd_and_is_sent_in_the_original_spelling() -> None:
    message = _decode_one(b"#mvpdd.7!").message
    assert message == Command("mvpidd", (7,))
    assert encode(message) == b"#mvpidd.7!"


def _edges() -> list[tuple[str, Kind, int, int, bool]]:
    """(name, kind, argument index, value, valid) for min, max and one past each, per argument."""
    cases = []
    for spec in (*COMMANDS, *RESPONSES):
        for index, argument in enumerate(spec.arguments):
            for value, valid in (
                (argument.minimum, True),
                (argument.maximum, True),
                (argument.minimum - 1, False),
                (argument.maximum + 1, False),
            ):
                cases.append((spec.name, spec.kind, index, value, valid))
    return cases


def _frame_with(name: str, kind: Kind, index: int, value: int) -> bytes:
    spec = next(s for s in (*COMMANDS, *RESPONSES) if s.name == name and s.kind is kind)
    values = [argument.minimum for argument in spec.arguments]
    values[index] = value
    text = [
        argument.format(v) if v >= 0 or argument.signed else str(v)
        for argument, v in zip(spec.arguments, values, strict=True)
    ]
    return kind.start_byte + ".".join([name, *text]).encode() + b"!"


@pytest.mark.parametrize(("name", "kind", "index", "value", "valid"), _edges())
def test_range_edges_decode(name: str, kind: Kind, index: int, value: int, valid: bool) -> None:
    raw = _frame_with(name, kind, index, value)
    (event,) = Decoder().feed(raw)
    if valid:
        assert isinstance(event, Frame)
        assert event.message.values[index] == value
    else:
        assert isinstance(event, BadFrame)
        spec = next(s for s in (*COMMANDS, *RESPONSES) if s.name == name and s.kind is kind)
        # An unsigned argument written with "-" is a syntax error, not a range error.
        unsigned_negative = value < 0 and not spec.arguments[index].signed
        assert event.reason is (Reason.MALFORMED if unsigned_negative else Reason.RANGE)


@pytest.mark.parametrize(("name", "kind", "index", "value", "valid"), _edges())
def test_range_edges_encode(name: str, kind: Kind, index: int, value: int, valid: bool) -> None:
    spec = next(s for s in (*COMMANDS, *RESPONSES) if s.name == name and s.kind is kind)
    values = [argument.minimum for argument in spec.arguments]
    values[index] = value
    cls = Command if kind is Kind.COMMAND else Response
    if valid:
        assert cls(name, tuple(values)).values[index] == value
    else:
        with pytest.raises(ArgumentError) as info:
            cls(name, tuple(values))
        argument = spec.arguments[index]
        message = str(info.value)
        assert name in message
        assert argument.name in message
        assert argument.range_text() in message


def test_caller_errors_are_value_errors_naming_the_problem() -> None:
    with pytest.raises(ArgumentCountError, match=r"th takes 2 value\(s\) \(direction_deg"):
        Command("th", (90,))
    with pytest.raises(UnknownCommandError, match="'dive'"):
        Command("dive")
    with pytest.raises(ValueError, match=r"mgmp: max_pwm must be in 0–255, got 300"):
        Command("mgmp", (300,))
    with pytest.raises(TypeError, match="must be an int"):
        Command("mgmp", (True,))


@pytest.mark.parametrize(
    ("raw", "reason"),
    [
        (b"#mgmp.+5!", Reason.MALFORMED),  # a sign only where the value is signed
        (b"#mgmp.-5!", Reason.MALFORMED),
        (b"#mgmp!", Reason.MALFORMED),
        (b"#mgmp.5.5!", Reason.MALFORMED),
        (b"#mgmp.!", Reason.MALFORMED),
        (b"#mgmp.x!", Reason.MALFORMED),
        (b"#th.90!", Reason.MALFORMED),
        (b"#stop.1!", Reason.MALFORMED),
        (b"#mvs.++5!", Reason.MALFORMED),
        (b"#!", Reason.MALFORMED),
        (b"$!", Reason.MALFORMED),
        (b"#QD!", Reason.UNKNOWN),  # commands are case-sensitive
        (b"#dive!", Reason.UNKNOWN),
        (b"#qd8C!", Reason.UNKNOWN),  # a checksum while the mode is off
        (b"$stop!", Reason.UNKNOWN),  # a command name as a response
        (b"#mgmp.256!", Reason.RANGE),
        (b"#th.361.0!", Reason.RANGE),
        (b"#mvs.-101!", Reason.RANGE),
    ],
)
def test_bad_frames_are_reported_with_their_reason(raw: bytes, reason: Reason) -> None:
    (event,) = Decoder().feed(raw)
    assert isinstance(event, BadFrame)
    assert event.reason is reason
    assert event.raw == raw


def test_str_of_a_message_is_its_plain_frame() -> None:
    assert str(Command("th", (270, 25))) == "#th.270.25!"
    assert str(Response("q.l", (1,))) == "$q.l.1!"


def test_every_setting_has_both_values_in_the_table() -> None:
    from rovlink.protocol import Setting, setting_command

    for setting in Setting:
        for value in (True, False):
            command = setting_command(setting, value)
            assert command.setting == (setting, value)


@pytest.mark.parametrize(
    ("kind", "body", "values"),
    [
        (Kind.COMMAND, "mgmp.00255", (255,)),
        (Kind.COMMAND, "th.0360.0100", (360, 100)),
        (Kind.COMMAND, "mvs.-0100", (-100,)),
        (Kind.COMMAND, "mvs.+007", (7,)),
        (Kind.COMMAND, "sdk.0010000", (10000,)),
        (Kind.RESPONSE, "qro.-.09", (-9,)),
        (Kind.RESPONSE, "q.l.01", (1,)),
    ],
)
def test_the_full_parser_takes_leading_zeros(
    kind: Kind, body: str, values: tuple[int, ...]
) -> None:
    # P6 for the parser that names problems (the console's frames, the decoder's odd forms),
    # not only for the decoder's fast path.
    assert parse_body(kind, body).values == values
