"""Properties of the decoder on line noise, for each checksum mode and algorithm (P1, P2, P3).

Arbitrary bytes never raise; a stream cut at any byte boundary gives the events of the stream
whole; valid frames with noise before, between and after them all come out, in order; and every
command and reply of the table survives an encode and decode at the edges of its ranges.
"""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovlink.protocol import (
    ALGORITHMS,
    COMMANDS,
    MAX_FRAME_BYTES,
    RESPONSES,
    BadFrame,
    Command,
    Decoder,
    Event,
    Frame,
    Kind,
    Message,
    Reason,
    Response,
    Spec,
    encode,
)

from .strategies import messages, noisy_bytes

_ALGORITHMS = sorted(ALGORITHMS)
_MODES = [(checksum, algorithm) for checksum in (False, True) for algorithm in _ALGORITHMS]


def _decode(chunks: list[bytes], checksum: bool, algorithm: str) -> list[Event]:
    decoder = Decoder(checksum_enabled=checksum, algorithm=algorithm)
    events: list[Event] = []
    for chunk in chunks:
        events += decoder.feed(chunk)
    return events + decoder.end()


@settings(max_examples=300)
@given(noisy_bytes | st.binary(max_size=400), st.booleans(), st.sampled_from(_ALGORITHMS))
def test_every_cut_of_a_stream_gives_the_events_of_the_whole(
    data: bytes, checksum: bool, algorithm: str
) -> None:
    whole = _decode([data], checksum, algorithm)
    assert _decode([data[i : i + 1] for i in range(len(data))], checksum, algorithm) == whole
    for cut in range(len(data) + 1):
        assert _decode([data[:cut], data[cut:]], checksum, algorithm) == whole, cut


#: Noise that cannot make a mode frame (which would change how the frames after it read).
_noise = (noisy_bytes | st.binary(max_size=120)).filter(lambda data: b"crc" not in data)
_sent = st.lists(
    messages.filter(lambda message: not message.spec.exact_match), min_size=1, max_size=10
)


@settings(max_examples=300)
@given(_sent, st.lists(_noise, min_size=11, max_size=11), st.sampled_from(_MODES), st.data())
def test_valid_frames_embedded_in_noise_are_all_recovered(
    sent: list[Message],
    noise: list[bytes],
    mode: tuple[bool, str],
    data: st.DataObject,
) -> None:
    # No line breaks needed: a start character ends any text and abandons any unfinished frame.
    checksum, algorithm = mode
    raws = [encode(message, algorithm if checksum else None) for message in sent]
    stream = b"".join(n + raw for n, raw in zip(noise, raws, strict=False)) + noise[-1]
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=8)))
    chunks = [stream[a:b] for a, b in itertools.pairwise([0, *cuts, len(stream)])]
    received = iter(
        (event.message, event.raw)
        for event in _decode(chunks, checksum, algorithm)
        if isinstance(event, Frame)
    )
    # The noise may make frames of its own, but every sent frame comes out whole, in order.
    for message, raw in zip(sent, raws, strict=True):
        assert any(found == (message, raw) for found in received), (message, raw)


#: The bytes a frame's body may hold (P1): printable, but for the start and end characters.
_BODY_BYTES = bytes(byte for byte in range(0x21, 0x7F) if byte not in b"#$!")


@settings(max_examples=200)
@given(
    st.binary(min_size=MAX_FRAME_BYTES, max_size=3 * MAX_FRAME_BYTES).map(
        lambda noise: b"#" + bytes(_BODY_BYTES[byte % len(_BODY_BYTES)] for byte in noise)
    ),
    messages.filter(lambda message: not message.spec.exact_match),
    st.sampled_from(_MODES),
)
def test_an_overlong_frame_is_dropped_and_the_next_frame_decodes(
    overlong: bytes, message: Message, mode: tuple[bool, str]
) -> None:
    checksum, algorithm = mode
    raw = encode(message, algorithm if checksum else None)
    events = _decode([overlong + b"!" + raw], checksum, algorithm)
    assert isinstance(events[0], BadFrame)
    assert events[0].reason is Reason.TOO_LONG
    assert events[-1] == Frame(message, raw)


@settings(max_examples=300)
@given(st.binary(max_size=1000), st.sampled_from(_MODES))
def test_arbitrary_bytes_never_raise_and_leave_nothing_buffered_at_the_end(
    data: bytes, mode: tuple[bool, str]
) -> None:
    checksum, algorithm = mode
    decoder = Decoder(checksum_enabled=checksum, algorithm=algorithm)
    for start in range(0, len(data), 5):
        decoder.feed(data[start : start + 5])
        decoder.frame_message(data[start : start + 5])
    decoder.end()
    assert decoder.buffered_bytes == decoder.buffered_text_bytes == 0


def _edge_values(spec: Spec) -> list[tuple[int, ...]]:
    """Each argument at its minimum, maximum, and zero and ±1 where in range, the others at
    their own minimum and maximum."""
    per_argument = [
        sorted(
            {a.minimum, a.maximum}
            | {value for value in (-1, 0, 1) if a.minimum <= value <= a.maximum}
        )
        for a in spec.arguments
    ]
    return list(itertools.product(*per_argument))


_EDGES = [
    pytest.param(spec, values, id=f"{spec.kind.value}-{spec.name}-{values}")
    for spec in (*COMMANDS, *RESPONSES)
    for values in _edge_values(spec)
]


@pytest.mark.parametrize(("spec", "values"), _EDGES)
@pytest.mark.parametrize(("checksum", "algorithm"), _MODES)
def test_every_command_and_reply_round_trips_at_its_range_edges(
    spec: Spec, values: tuple[int, ...], checksum: bool, algorithm: str
) -> None:
    message = (Command if spec.kind is Kind.COMMAND else Response)(spec.name, values)
    raw = encode(message, algorithm if checksum else None)
    assert len(raw) <= MAX_FRAME_BYTES
    expected = [Frame(message, raw)]
    assert _decode([raw], checksum, algorithm) == expected
    assert _decode([raw[i : i + 1] for i in range(len(raw))], checksum, algorithm) == expected
    # Twice in one chunk: the second from the decoder's cache of frames.
    assert _decode([raw + raw], checksum, algorithm) == expected * 2
