"""What a page may send: every refusal is a MessageError naming what was wrong, never a crash."""

from __future__ import annotations

import contextlib
import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rovlink.protocol import COMMANDS
from rovlink.station.messages import (
    PAGE_COMMANDS,
    CommandRequest,
    InputMessage,
    MessageError,
    StopRequest,
    parse_message,
)


def test_a_valid_input():
    message = parse_message(
        '{"type": "input", "deadman": true, "direction_deg": 90, "power_percent": 40,'
        ' "vertical_percent": -20, "pad_timestamp_ms": 1234.5}'
    )
    assert isinstance(message, InputMessage)
    assert message.pilot.direction_deg == 90
    assert message.pilot.pad_timestamp_ms == 1234.5


def test_keyboard_input_has_no_pad_timestamp():
    message = parse_message(
        '{"type": "input", "source": "keyboard", "deadman": true, "direction_deg": 0,'
        ' "power_percent": 40, "vertical_percent": 0}'
    )
    assert isinstance(message, InputMessage)
    assert message.pilot.pad_timestamp_ms is None
    assert message.sent_ms is None  # (not said: how late it arrives is not measured)


def test_an_input_may_say_when_it_was_sent():
    message = parse_message(
        '{"type": "input", "source": "keyboard", "deadman": false, "direction_deg": 0,'
        ' "power_percent": 0, "vertical_percent": 0, "sent_ms": 5678.5}'
    )
    assert isinstance(message, InputMessage)
    assert message.sent_ms == 5678.5


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("nope", "not JSON"),
        ("[]", "JSON object"),
        ('{"kind": 1}', "'type'"),
        ('{"type": "dance"}', "unknown message type"),
        ('{"type": "command", "name": "th", "values": [90, 10]}', "motion comes from"),
        ('{"type": "command", "name": "crcoff"}', "cannot be sent as a command"),
        ('{"type": "command", "name": "mgmp", "values": [300]}', "max_pwm must be in 0–255"),
        ('{"type": "command", "name": "mgmp", "values": [1, 2]}', "mgmp"),
        ('{"type": "visibility"}', "'hidden' must be true or false"),
        ('{"type": "input", "deadman": 1}', "'deadman' must be true or false"),
        ('{"type": "input", "deadman": true, "direction_deg": 1.5}', "'direction_deg' must be"),
        ('{"type": "input", "deadman": true, "pad_timestamp_ms": Infinity}', "not JSON"),
        (
            '{"type": "input", "source": "keyboard", "deadman": true, "direction_deg": 0,'
            ' "power_percent": 0, "vertical_percent": 0, "sent_ms": "now"}',
            "'sent_ms' must be a number",
        ),
    ],
)
def test_refusals_say_what_was_wrong(text, says):
    with pytest.raises(MessageError, match=says):
        parse_message(text)


def test_binary_and_oversized_messages_are_refused():
    with pytest.raises(MessageError, match="binary"):
        parse_message(b'{"type": "stop"}')
    with pytest.raises(MessageError, match="limit"):
        parse_message('{"type": "stop", "x": "' + "y" * 5000 + '"}')


def test_every_page_command_is_in_the_command_table_and_none_is_motion_relayed():
    names = {spec.name for spec in COMMANDS}
    assert set(PAGE_COMMANDS) <= names
    assert not {"th", "mvs", "crcon", "crcoff", "debug1", "debug0"} & set(PAGE_COMMANDS)
    assert isinstance(parse_message('{"type": "stop"}'), StopRequest)
    assert isinstance(
        parse_message('{"type": "command", "name": "mvd", "values": [150]}'), CommandRequest
    )


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=15), children, max_size=4)
    ),
    max_leaves=20,
)
MESSAGE_LIKE = st.fixed_dictionaries(
    {"type": st.sampled_from(["input", "command", "visibility", "stop", "take_control", "x"])},
    optional={
        "deadman": JSON_VALUES,
        "direction_deg": JSON_VALUES | st.integers(-1000, 1000),
        "power_percent": JSON_VALUES | st.integers(-10, 200),
        "vertical_percent": JSON_VALUES,
        "pad_timestamp_ms": JSON_VALUES,
        "source": JSON_VALUES,
        "name": st.sampled_from([*PAGE_COMMANDS, "th", "qd", "zz"]) | JSON_VALUES,
        "values": st.lists(st.integers(-20000, 20000), max_size=3) | JSON_VALUES,
        "hidden": JSON_VALUES,
    },
)


@given(st.one_of(MESSAGE_LIKE, JSON_VALUES))
def test_any_json_is_a_message_or_a_message_error(data):
    try:
        text = json.dumps(data)
    except ValueError:
        return
    with contextlib.suppress(MessageError):
        parse_message(text)


@given(st.text(max_size=200))
def test_any_text_is_a_message_or_a_message_error(text):
    with contextlib.suppress(MessageError):
        parse_message(text)
