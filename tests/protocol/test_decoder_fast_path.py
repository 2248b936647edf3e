"""The decoder's fast path for whole frames gives exactly the events of its byte-level states.

Frames that stand whole in a chunk are taken by table lookups (cached numbers, interned messages,
CRC-8 continued across known pieces); a frame split across chunks goes through the full parser.
Fed byte by byte, every frame takes the full parser: the two must always agree.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovlink.protocol import Decoder, Event, Frame, Kind, Response, encode, get_algorithm
from rovlink.protocol.commands import SPELLINGS, Spec
from rovlink.protocol.frames import FAST_ENTRIES, MAX_FRAME_BYTES

_SPELLINGS = sorted(
    {kind.start_byte + spelling.encode() for kind in Kind for spelling in SPELLINGS[kind]}
)
_NUMBER_TEXTS = st.one_of(
    st.integers(0, 100).map(lambda value: b"%d" % value),  # in every unsigned range
    st.integers(-10_500, 10_500).map(lambda value: b"%d" % value),
    st.integers(-120, 120).map(lambda value: b"%+d" % value),
    st.integers(0, 400).map(lambda value: b"00%d" % value),  # leading zeros: valid, not canonical
    st.sampled_from([b"", b"+", b"-", b"-0", b"+0", b"1a", b"x", b"l", b" 5", b"99999999999"]),
)


_VALUED = sorted(
    (kind.start_byte + spelling.encode(), spec)
    for kind in Kind
    for spelling, spec in SPELLINGS[kind].items()
    if spec.arguments
)


@st.composite
def _values(draw: st.DrawFn, spec: Spec) -> list[bytes]:
    """Mostly the spec's own count of in-range values, canonical or not; sometimes anything."""
    if draw(st.integers(0, 4)) == 0:
        return draw(st.lists(_NUMBER_TEXTS, max_size=3))
    texts = []
    for argument in spec.arguments:
        value = draw(st.integers(argument.minimum, argument.maximum))
        texts.append(
            draw(
                st.sampled_from(
                    [
                        argument.format(value).encode(),
                        b"%d" % value,
                        b"0%d" % value,
                    ]
                )
            )
            if draw(st.integers(0, 5))
            else draw(_NUMBER_TEXTS)
        )
    return texts


@st.composite
def frames(draw: st.DrawFn) -> bytes:
    """A frame of the table's vocabulary with right, wrong, odd or missing values and checksum."""
    if draw(st.booleans()):
        prefix, spec = draw(st.sampled_from(_VALUED))
        texts = draw(_values(spec))
    else:
        prefix = draw(st.sampled_from(_SPELLINGS))
        texts = draw(st.lists(_NUMBER_TEXTS, max_size=3))
    return _framed(draw, prefix, texts)


def _framed(draw: st.DrawFn, prefix: bytes, texts: list[bytes]) -> bytes:
    """The frame of ``prefix`` (start byte and name) and ``texts`` with any kind of tail."""
    body = b".".join([prefix[1:], *texts])
    tail = draw(st.sampled_from(["none", "upper", "lower", "wrong"]))
    digits = get_algorithm("crc8").digits(body)
    if tail == "upper":
        body += digits
    elif tail == "lower":
        body += digits.lower()
    elif tail == "wrong":
        body += b"%02X" % ((int(digits, 16) + 1) % 256)
    return prefix[:1] + body + b"!"


streams = st.lists(frames() | st.sampled_from([b"#crcon!", b"#crcoff!"]), max_size=40).map(b"".join)


def _decode(chunks: list[bytes], checksum: bool) -> list[Event]:
    decoder = Decoder(checksum_enabled=checksum)
    events: list[Event] = []
    for chunk in chunks:
        events += decoder.feed(chunk)
    return events + decoder.end()


@settings(max_examples=600)
@given(streams, st.booleans())
def test_whole_frames_decode_as_the_byte_level_states_do(stream: bytes, checksum: bool) -> None:
    byte_by_byte = _decode([stream[i : i + 1] for i in range(len(stream))], checksum)
    whole = _decode([stream], checksum)
    again = _decode([stream], checksum)  # every number and message now remembered
    assert whole == byte_by_byte == again


def test_a_leading_zero_value_decodes_and_is_not_remembered_as_a_spelling() -> None:
    events = _decode([b"$qd.0042!$qd.42!"], checksum=False)
    assert [event.message for event in events if isinstance(event, Frame)] == [
        Response("qd", (42,)),
        Response("qd", (42,)),
    ]
    assert [event.raw for event in events if isinstance(event, Frame)] == [b"$qd.0042!", b"$qd.42!"]


def test_a_wrong_checksum_on_a_known_value_is_still_dropped() -> None:
    good = b"$qd.42" + get_algorithm("crc8").digits(b"qd.42") + b"!"
    bad = good[:-3] + (b"00" if good[-3:-1] != b"00" else b"01") + b"!"
    events = _decode([good + bad], checksum=True)
    assert isinstance(events[0], Frame)
    assert not isinstance(events[1], Frame)


@settings(max_examples=100)
@given(
    st.lists(
        st.lists(frames(), min_size=1, max_size=90).map(b"".join)
        | st.sampled_from([b"debug line\r\n", b"\x00noise", b"#broken", b"$qd.", b"!"]),
        min_size=1,
        max_size=12,
    ).map(b"".join),
    st.booleans(),
)
def test_gaps_anywhere_among_many_frames(stream: bytes, checksum: bool) -> None:
    # More frames than one block of the gap search, with gaps at any place in any block.
    byte_by_byte = _decode([stream[i : i + 1] for i in range(len(stream))], checksum)
    assert _decode([stream], checksum) == byte_by_byte


def test_only_in_range_canonical_numbers_are_remembered() -> None:
    entry = FAST_ENTRIES[b"$qd"]
    numbers, ended = entry[5], entry[6]
    noise = b"".join(
        b"$qd.%s!" % text
        for text in (
            b"0" * 20 + b"7",
            b"00123",
            b"010000",
            b"-1",
            b"+5",
            b"1e3",
            b"\xff",
            b"",
        )
    )
    for checksum in (False, True):
        _decode([noise * 3], checksum)
    # Whatever the stream, a table holds canonical spellings of in-range values only.
    assert all(text == b"%d" % int(text) and 0 <= int(text) <= 9999 for text in numbers)
    assert all(text.endswith(b"!") and text[:-1] in numbers for text in ended)
    assert not {b"00123", b"010000", b"0" * 20 + b"7"} & set(numbers)
    _decode([b"$qd.4321!"], checksum=False)
    assert b"4321" in numbers
    assert b"4321!" in ended


@settings(max_examples=300)
@given(
    st.lists(
        frames() | st.sampled_from([b"#crcon!", b"#crcoff!", b"debug\r\n", b"$qd.", b"12!"]),
        max_size=30,
    ),
    st.booleans(),
)
def test_chunks_that_are_one_frame_each_decode_as_bytes_do(
    pieces: list[bytes], checksum: bool
) -> None:
    # A driver reads a reply as it arrives: a chunk is then often exactly one frame, which the
    # decoder takes from its cache without scanning. Twice over, so that the second pass hits.
    twice = b"".join(pieces) * 2
    byte_by_byte = _decode([twice[i : i + 1] for i in range(len(twice))], checksum)
    assert _decode(pieces + pieces, checksum) == byte_by_byte


def test_frame_message_reads_only_one_whole_frame_of_values_with_nothing_buffered() -> None:
    decoder = Decoder()
    (event,) = decoder.feed(b"$qd.5!")
    assert isinstance(event, Frame)
    assert decoder.frame_message(b"$qd.5!") is event.message  # from the cache
    assert decoder.frame_message(b"$qd.6!") == Response("qd", (6,))  # by table lookups
    for chunk in (
        b"$qd.5!$qd.6!",  # two frames
        b"$qd.5",  # half a frame
        b"boot\r\n",
        b"$qd.5!\r\n",
        b"",
        b"$qd.10000!",  # out of range: feed() names the problem
        b"#crcon!",  # a mode frame: feed() switches the mode
        b"$qsa!",  # no values
    ):
        assert decoder.frame_message(chunk) is None, chunk  # left unread
    assert not decoder.checksum_enabled
    decoder.feed(b"$qd.")  # half a frame waits for its end
    assert decoder.frame_message(b"$qd.5!") is None
    assert decoder.feed(b"6!") == [Frame(Response("qd", (6,)), b"$qd.6!")]


def test_frame_message_leaves_other_algorithms_to_feed() -> None:
    frame = b"$qd.5" + get_algorithm("xor").digits(b"qd.5") + b"!"
    decoder = Decoder(checksum_enabled=True, algorithm="xor")
    assert decoder.frame_message(frame) is None
    assert decoder.feed(frame) == [Frame(Response("qd", (5,)), frame)]


@settings(max_examples=300)
@given(st.lists(frames() | st.sampled_from([b"#crcon!", b"#crcoff!"]), max_size=30))
def test_frame_message_decodes_as_feed_does(pieces: list[bytes]) -> None:
    """Where frame_message reads a chunk, feed gives exactly that frame; where it does not,
    the chunk is left unread (the decoder's state unchanged) and feed reads it as ever."""
    one_by_one, fed = Decoder(), Decoder()
    for piece in pieces * 2:
        expected = fed.feed(piece)
        message = one_by_one.frame_message(piece)
        if message is None:
            assert one_by_one.feed(piece) == expected
        else:
            assert [Frame(message, piece)] == expected


def _overlong_reply(checked: bool) -> bytes:
    """A qd reply of 67 bytes: in range, canonical apart from its leading zeros (P6)."""
    if checked:
        body = b"qd." + b"0" * 58 + b"12"
        frame = b"$" + body + get_algorithm("crc8").digits(body) + b"!"
    else:
        frame = b"$qd." + b"0" * 60 + b"12!"
    assert len(frame) > MAX_FRAME_BYTES
    return frame


@pytest.mark.parametrize("checked", [False, True])
def test_frame_message_leaves_a_frame_longer_than_64_bytes_to_feed(checked: bool) -> None:
    """A frame longer than MAX_FRAME_BYTES whose pieces are all valid (leading zeros) is not
    read by frame_message: feed drops it (P1)."""
    frame = _overlong_reply(checked)
    expected = Decoder(checksum_enabled=checked).feed(frame)
    assert not any(isinstance(event, Frame) for event in expected)  # TOO_LONG (P1)
    decoder = Decoder(checksum_enabled=checked)
    assert decoder.frame_message(frame) is None
    assert decoder.feed(frame) == expected


_REPLY_NAMES = sorted(
    spec.name for spec in SPELLINGS[Kind.RESPONSE].values() if len(spec.arguments) == 1
)


@st.composite
def _replies_of(draw: st.DrawFn, name: str) -> bytes:
    """A reply of ``name`` with right, wrong, odd or missing values and checksum."""
    spec = SPELLINGS[Kind.RESPONSE][name]
    return _framed(draw, b"$" + name.encode(), draw(_values(spec)))


@settings(max_examples=400)
@given(st.data(), st.sampled_from(_REPLY_NAMES), st.booleans())
def test_reply_message_reads_a_reply_as_feed_does(
    data: st.DataObject, name: str, checksum: bool
) -> None:
    """Where reply_message reads a chunk, it is one frame of that reply that feed decodes to
    that very message; where it does not, the chunk is left unread and feed reads it as ever."""
    pieces = data.draw(
        st.lists(
            _replies_of(name) | frames() | st.sampled_from([b"#crcon!", b"#crcoff!"]),
            max_size=30,
        )
    )
    one_by_one, fed = Decoder(checksum_enabled=checksum), Decoder(checksum_enabled=checksum)
    for piece in pieces * 2:
        expected = fed.feed(piece)
        message = one_by_one.reply_message(piece, name)
        if message is None:
            assert one_by_one.feed(piece) == expected
        else:
            assert message.name == name
            assert [Frame(message, piece)] == expected


@pytest.mark.parametrize("checked", [False, True])
def test_reply_message_reads_every_one_value_reply_and_no_other_name(checked: bool) -> None:
    algorithm = "crc8" if checked else None
    for name in _REPLY_NAMES:
        decoder = Decoder(checksum_enabled=checked)
        reply = encode(Response(name, (1,)), algorithm)
        assert decoder.reply_message(reply, name) == Response(name, (1,))
        others = [other for other in _REPLY_NAMES if other != name]
        assert all(decoder.reply_message(reply, other) is None for other in others)


def test_reply_message_leaves_the_rest_to_feed() -> None:
    decoder = Decoder()
    assert decoder.reply_message(b"$qd.5!$qd.6!", "qd") is None  # two frames
    assert decoder.reply_message(b"$qsa!", "qsa") is None  # no value
    assert decoder.reply_message(_overlong_reply(False), "qd") is None  # P1
    checked = Decoder(checksum_enabled=True, algorithm="xor")
    assert (
        checked.reply_message(b"$qd.5" + get_algorithm("xor").digits(b"qd.5") + b"!", "qd") is None
    )
    assert decoder.feed(b"$qd.") == []
    assert decoder.reply_message(b"5!", "qd") is None  # a frame begun in an earlier chunk
