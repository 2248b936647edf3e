"""The protocol's value classes behave as frozen dataclasses: shown, compared and hashed by their
fields, never changed, copied and pickled whole."""

from __future__ import annotations

import copy
import pickle

import pytest

from rovlink.protocol import (
    ALGORITHMS,
    BadFrame,
    Command,
    Decoder,
    Frame,
    Reason,
    Response,
    Text,
    lookup,
)
from rovlink.protocol.commands import Argument

VALUES = [
    Command("th", (270, 25)),
    Response("qro", (-1,)),
    Command("qd"),
    lookup("th"),
    lookup("th").arguments[0],
    ALGORITHMS["crc8"],
    Frame(Response("qd", (5,)), b"$qd.5!"),
    Text("boot ok"),
    BadFrame(Reason.CHECKSUM, b"$qdAA!", "missing or wrong crc8 checksum"),
]


@pytest.mark.parametrize("value", VALUES, ids=lambda value: type(value).__name__)
def test_equal_to_a_copy_and_a_pickle_with_the_same_hash(value: object) -> None:
    for twin in (copy.copy(value), copy.deepcopy(value), pickle.loads(pickle.dumps(value))):
        assert twin == value
        assert hash(twin) == hash(value)
        assert type(twin) is type(value)


@pytest.mark.parametrize("value", VALUES, ids=lambda value: type(value).__name__)
def test_no_field_can_be_assigned_or_deleted(value: object) -> None:
    for name in type(value).__match_args__:  # type: ignore[attr-defined]
        with pytest.raises(AttributeError, match="cannot assign"):
            setattr(value, name, None)
        with pytest.raises(AttributeError, match="cannot delete"):
            delattr(value, name)
    assert not hasattr(value, "__dict__")


def test_a_message_is_shown_and_compared_by_its_class_name_and_values() -> None:
    assert repr(Command("mvpdd", (5,))) == "Command(name='mvpidd', values=(5,))"
    assert Command("mvpdd", (5,)) == Command("mvpidd", (5,))
    assert Command("qd") != Command("qr")
    assert Response("qd", (1,)) != Response("qd", (2,))
    # The same name and values in another direction are another message.
    assert Command("qd") != Response("qd", (0,))  # type: ignore[comparison-overlap]
    assert len({Command("qd"), Command("qd"), Command("qr")}) == 2


def test_events_are_shown_with_every_field() -> None:
    decoder = Decoder()
    events = decoder.feed(b"boot\r\n$qd.12!#zz!") + decoder.end()
    assert [repr(event) for event in events] == [
        "Text(text='boot')",
        "Frame(message=Response(name='qd', values=(12,)), raw=b'$qd.12!')",
        "BadFrame(reason=<Reason.UNKNOWN: 'unknown'>, raw=b'#zz!', "
        "detail=\"unknown command 'zz'\")",
    ]


def test_fields_match_by_position() -> None:
    match Frame(Command("th", (90, 30)), b"#th.90.30!"):
        case Frame(Command("th", (direction, power))):
            assert (direction, power) == (90, 30)
        case _:
            pytest.fail("no match")
    assert Argument("power_percent", 0, 100) == Argument("power_percent", 0, 100, False, "", "")
