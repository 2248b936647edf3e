"""Command text as people type it, to commands, with errors naming argument and range."""

from __future__ import annotations

import pytest

from rovlink.client.command_text import (
    CommandTextError,
    complete_names,
    parse_command_text,
    usage,
)
from rovlink.protocol import COMMANDS


@pytest.mark.parametrize(
    ("text", "frame"),
    [
        ("qd", "#qd!"),
        ("  th 270 25 ", "#th.270.25!"),
        ("th 270, 25", "#th.270.25!"),
        ("th.270.25", "#th.270.25!"),
        ("#th.270.25!", "#th.270.25!"),
        ("mvs -50", "#mvs.-50!"),
        ("mvs +100", "#mvs.+100!"),
        ("mvs 30", "#mvs.+30!"),
        ("mvs.-50", "#mvs.-50!"),
        ("q.l", "#q.l!"),
        ("#q.l!", "#q.l!"),
        ("mvpdd 7", "#mvpidd.7!"),
        ("h+", "#h+!"),
        ("mgmp 007", "#mgmp.7!"),
        ("crcon", "#crcon!"),
    ],
)
def test_friendly_text_and_frames(text: str, frame: str) -> None:
    assert str(parse_command_text(text)) == frame


def test_every_command_of_the_table_parses_from_its_usage_with_the_minimum_values() -> None:
    for spec in COMMANDS:
        words = [spec.name, *(str(argument.minimum) for argument in spec.arguments)]
        assert parse_command_text(" ".join(words)).name == spec.name


@pytest.mark.parametrize(
    ("text", "message", "argument"),
    [
        ("th 400 25", "th: direction_deg must be in 0–360, got 400", "direction_deg"),
        ("th 270 101", "th: power_percent must be in 0–100, got 101", "power_percent"),
        ("mvs -101", "mvs: thrust_percent must be in -100…+100, got -101", "thrust_percent"),
        ("th 270 x", "th: power_percent must be an integer in 0–100, got 'x'", "power_percent"),
        ("#th.400.25!", "th: direction_deg must be in 0–360, got 400", "direction_deg"),
        (
            "th 270",
            "th takes 2 value(s), got 1: th <direction_deg 0–360> <power_percent 0–100>",
            None,
        ),
        ("qd 5", "qd takes 0 value(s), got 1", None),
    ],
)
def test_errors_name_the_argument_and_its_range(
    text: str, message: str, argument: str | None
) -> None:
    with pytest.raises(CommandTextError) as caught:
        parse_command_text(text)
    assert message in str(caught.value)
    assert caught.value.argument == argument


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "empty command"),
        ("#qd", "must end with '!'"),
        ("#!", "empty frame"),
        ("thrust 1", "unknown command 'thrust'; did you mean th"),
        ("#stpo!", "unknown command 'stpo'; did you mean stop"),
        ("STOP", r"unknown command 'STOP': commands are lower-case, did you mean stop\?"),
        ("#STOP!", r"unknown command 'STOP': commands are lower-case, did you mean stop\?"),
        ("TH 90 30", r"unknown command 'TH': commands are lower-case, did you mean th\?"),
        ("zzzz", "unknown command 'zzzz'"),
        # Before: "unknown command 'qd!#qd'; did you mean qd?", and no hint for "QD".
        ("#qd!#qd!", "one frame at a time: '#qd!#qd!' holds more than one"),
        ("#start!#th.0.50!", "one frame at a time"),
        ("QD", r"unknown command 'QD': commands are lower-case, did you mean qd\?"),
        ("#Stop!", r"unknown command 'Stop': commands are lower-case, did you mean stop\?"),
    ],
)
def test_malformed_and_unknown_text(text: str, message: str) -> None:
    with pytest.raises(CommandTextError, match=message):
        parse_command_text(text)


def test_usage_and_completion_come_from_the_table() -> None:
    assert usage("mvpdd") == "mvpidd <gain 0–99>"
    assert usage("qsa") == "qsa"
    assert complete_names("q") == ["qd", "qr", "q.l", "qro", "qpi", "qhe", "qsa"]
    assert complete_names("") == [spec.name for spec in COMMANDS]


@pytest.mark.parametrize(
    ("text", "message", "argument"),
    [
        # A "+" only where the argument is signed (P6), as the frame form "#mgmp.+5!" says.
        ("mgmp +5", "mgmp: max_pwm must be an integer in 0–255, got '+5'", "max_pwm"),
        ("th +90 10", "th: direction_deg must be an integer in 0–360, got '+90'", "direction_deg"),
        # Decimal digits of other scripts are not the protocol's digits.
        ("mgmp \u0663", "mgmp: max_pwm must be an integer in 0–255, got '\u0663'", "max_pwm"),
        (
            "mvs \uff15",
            "mvs: thrust_percent must be an integer in -100…+100, got '\uff15'",
            "thrust_percent",
        ),
    ],
)
def test_values_are_ascii_digits_with_a_sign_only_where_signed(
    text: str, message: str, argument: str
) -> None:
    with pytest.raises(CommandTextError) as caught:
        parse_command_text(text)
    assert str(caught.value) == message
    assert caught.value.argument == argument


@pytest.mark.parametrize(
    ("text", "frame"),
    [("mvs +5", "#mvs.+5!"), ("mvs -0", "#mvs.+0!"), ("mgmp 0255", "#mgmp.255!")],
)
def test_signed_values_keep_their_sign_and_leading_zeros_are_taken(text: str, frame: str) -> None:
    assert str(parse_command_text(text)) == frame
