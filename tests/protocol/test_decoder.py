"""The streaming decoder: chunking, noise, resynchronisation, limits, checksum mode (P1, P3, P5)."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovlink.protocol import (
    MAX_FRAME_BYTES,
    MAX_TEXT_BYTES,
    BadFrame,
    Command,
    Decoder,
    Event,
    Frame,
    Message,
    Reason,
    Response,
    Text,
    encode,
    get_algorithm,
)

from .strategies import line_noise, messages, noisy_bytes, split_points


def decode_all(data: bytes, chunks: list[bytes] | None = None, **options: object) -> list[Event]:
    decoder = Decoder(**options)  # type: ignore[arg-type]
    events: list[Event] = []
    for chunk in chunks if chunks is not None else [data]:
        events += decoder.feed(chunk)
    return events + decoder.end()


def frames(events: list[Event]) -> list[Message]:
    return [event.message for event in events if isinstance(event, Frame)]


@given(messages, st.booleans(), st.sampled_from(["crc8", "xor", "sum8"]))
def test_round_trip_every_message(message: Message, checksum: bool, algorithm: str) -> None:
    raw = encode(message, checksum=algorithm if checksum else None)
    assert len(raw) <= MAX_FRAME_BYTES
    events = decode_all(raw, checksum_enabled=checksum, algorithm=algorithm)
    assert events == [Frame(message, raw)]


@settings(max_examples=400)
@given(noisy_bytes, st.data())
def test_chunking_never_changes_the_events(data: bytes, draw: st.DataObject) -> None:
    whole = decode_all(data)
    byte_by_byte = decode_all(data, [data[i : i + 1] for i in range(len(data))])
    cuts = [0, *draw.draw(split_points(data)), len(data)]
    random_chunks = decode_all(data, [data[a:b] for a, b in itertools.pairwise(cuts)])
    assert whole == byte_by_byte == random_chunks


@given(st.binary(max_size=2000), st.booleans())
def test_arbitrary_bytes_never_raise_or_grow_the_buffers(data: bytes, checksum: bool) -> None:
    decoder = Decoder(checksum_enabled=checksum)
    for start in range(0, len(data), 7):
        decoder.feed(data[start : start + 7])
        assert decoder.buffered_bytes < MAX_FRAME_BYTES
        assert decoder.buffered_text_bytes < MAX_TEXT_BYTES
    decoder.end()
    assert decoder.buffered_bytes == decoder.buffered_text_bytes == 0


@given(
    st.lists(messages.filter(lambda m: m.name != "crcon"), min_size=1, max_size=8),
    st.lists(line_noise, min_size=9, max_size=9),
)
def test_frames_survive_garbage_before_between_and_after(
    sent: list[Message], garbage: list[bytes]
) -> None:
    # Each piece of garbage is followed by a line break, as on a real line; the received frames
    # may include frames made by the garbage itself, but every sent one must come out in order.
    stream = b"".join(g + b"\r\n" + encode(m) for g, m in zip(garbage, sent, strict=False))
    stream += garbage[-1]
    received = frames(decode_all(stream))
    assert _contains_in_order(received, sent)


def _contains_in_order(received: list[Message], sent: list[Message]) -> bool:
    iterator = iter(received)
    return all(any(r == m for r in iterator) for m in sent)


def test_pending_text_ends_at_a_frame_that_opens_a_chunk_with_gaps() -> None:
    # Text left from one chunk, then a chunk that starts with a frame and has a gap later.
    chunks = [b"\x00" * 16, b"#!\x00#!"]
    assert decode_all(b"".join(chunks), chunks) == decode_all(b"".join(chunks))
    assert isinstance(decode_all(b"".join(chunks), chunks)[0], Text)


def test_garbage_between_frames_is_text_one_event_per_line() -> None:
    events = decode_all(b"boot v1.2\r\n\r\n  \r\nready\r\n#qd!$qd.42!depth mode\r\n")
    assert events == [
        Text("boot v1.2"),
        Text("ready"),
        Frame(Command("qd"), b"#qd!"),
        Frame(Response("qd", (42,)), b"$qd.42!"),
        Text("depth mode"),
    ]


def test_unfinished_text_is_flushed_at_end_of_input() -> None:
    decoder = Decoder()
    assert decoder.feed(b"partial line") == []
    assert decoder.end() == [Text("partial line")]


def test_long_text_is_reported_in_pieces() -> None:
    events = decode_all(b"x" * (2 * MAX_TEXT_BYTES + 10) + b"\n")
    assert [len(e.text) for e in events if isinstance(e, Text)] == [MAX_TEXT_BYTES] * 2 + [10]


def test_a_start_character_abandons_an_unfinished_frame() -> None:
    events = decode_all(b"#mvd.10#qd!")
    assert events[0] == BadFrame(
        Reason.MALFORMED, b"#mvd.10", "frame interrupted by a new start character"
    )
    assert events[1] == Frame(Command("qd"), b"#qd!")


def test_a_non_printable_byte_discards_the_frame() -> None:
    events = decode_all(b"#q d!#qd\r\n#qr!")
    reasons = [(e.reason, e.raw) for e in events if isinstance(e, BadFrame)]
    assert reasons == [(Reason.MALFORMED, b"#q"), (Reason.MALFORMED, b"#qd")]
    assert frames(events) == [Command("qr")]
    assert Text("d!") in events


def test_too_long_frame_is_discarded_and_the_next_one_decodes() -> None:
    overlong = b"#mvd." + b"0" * 70 + b"1!"
    events = decode_all(overlong + b"#qd!")
    assert isinstance(events[0], BadFrame)
    assert events[0].reason is Reason.TOO_LONG
    assert len(events[0].raw) == MAX_FRAME_BYTES
    assert events[1:] == [Frame(Command("qd"), b"#qd!")]


def test_a_frame_of_exactly_the_limit_is_accepted_and_one_more_byte_is_not() -> None:
    # "#mvd." + zeros + "1!" padded with leading zeros to 64 and 65 bytes.
    at_limit = b"#mvd." + b"0" * (MAX_FRAME_BYTES - 7) + b"1!"
    assert len(at_limit) == MAX_FRAME_BYTES
    assert frames(decode_all(at_limit)) == [Command("mvd", (1,))]
    over = b"#mvd." + b"0" * (MAX_FRAME_BYTES - 6) + b"1!"
    (event,) = decode_all(over)
    assert isinstance(event, BadFrame)
    assert event.reason is Reason.TOO_LONG


def test_truncated_frame_is_reported_at_end_of_input() -> None:
    decoder = Decoder()
    assert decoder.feed(b"#th.90") == []
    assert decoder.end() == [BadFrame(Reason.TRUNCATED, b"#th.90", "input ended inside a frame")]


# -- checksum mode (P3) ------------------------------------------------------------------------


def test_crcon_and_crcoff_switch_the_mode_by_exact_match() -> None:
    decoder = Decoder()
    events = decoder.feed(b"#crcon!")
    assert frames(events) == [Command("crcon")]
    assert decoder.checksum_enabled
    # "crcoff" ends in valid hex "ff": it must still be taken as the exact frame.
    assert frames(decoder.feed(b"#crcoff!")) == [Command("crcoff")]
    assert not decoder.checksum_enabled


def test_crcon_is_recognised_in_checksum_mode_too() -> None:
    decoder = Decoder(checksum_enabled=True)
    assert frames(decoder.feed(b"#crcon!")) == [Command("crcon")]
    assert decoder.checksum_enabled


def test_checksum_mode_drops_missing_and_wrong_checksums() -> None:
    events = decode_all(b"#qd!#qd8D!#qd8c!$qd.12313!$qd.123!", checksum_enabled=True)
    assert [type(e).__name__ for e in events] == [
        "BadFrame",
        "BadFrame",
        "Frame",
        "Frame",
        "BadFrame",
    ]
    assert all(e.reason is Reason.CHECKSUM for e in events if isinstance(e, BadFrame))
    assert frames(events) == [Command("qd"), Response("qd", (123,))]


def test_bare_stop_is_honoured_in_checksum_mode() -> None:
    events = decode_all(b"#stop!#stopA5!", checksum_enabled=True)
    assert frames(events) == [Command("stop"), Command("stop")]


def test_bare_stop_exception_is_for_the_command_only() -> None:
    events = decode_all(b"#start!", checksum_enabled=True)
    assert isinstance(events[0], BadFrame)
    assert events[0].reason is Reason.CHECKSUM


def test_checksum_off_takes_a_checksummed_frame_as_it_is() -> None:
    (event,) = decode_all(b"#qd8C!")
    assert isinstance(event, BadFrame)
    assert event.reason is Reason.UNKNOWN


def test_mode_followed_within_one_stream() -> None:
    stream = b"#qd!#crcon!#qd!#qd8C!#crcoff!#qd!"
    assert frames(decode_all(stream)) == [
        Command("qd"),
        Command("crcon"),
        Command("qd"),
        Command("crcoff"),
        Command("qd"),
    ]


@pytest.mark.parametrize("algorithm", ["xor", "sum8"])
def test_other_algorithms(algorithm: str) -> None:
    raw = encode(Command("th", (90, 50)), checksum=algorithm)
    assert frames(decode_all(raw, checksum_enabled=True, algorithm=algorithm)) == [
        Command("th", (90, 50))
    ]
    # The crc8 decoder rejects it (the two differ on this body).
    events = decode_all(raw, checksum_enabled=True, algorithm="crc8")
    assert isinstance(events[0], BadFrame)


def test_crcon_never_carries_a_checksum_when_encoded() -> None:
    assert encode(Command("crcon"), checksum="crc8") == b"#crcon!"
    assert encode(Command("crcoff"), checksum="crc8") == b"#crcoff!"


def test_reset_forgets_partial_input_but_keeps_the_mode() -> None:
    decoder = Decoder(checksum_enabled=True)
    decoder.feed(b"noise#qd")
    decoder.reset()
    assert decoder.buffered_bytes == decoder.buffered_text_bytes == 0
    assert decoder.checksum_enabled
    assert decoder.end() == []


@pytest.mark.parametrize("name", ["crcon", "crcoff"])
def test_a_mode_frame_with_a_checksum_is_not_the_mode_frame(name: str) -> None:
    # Exact match only (P3): "#crcoff3F!" must neither decode as crcoff nor switch the mode.
    digits = get_algorithm("crc8").digits(name.encode())
    decoder = Decoder(checksum_enabled=True)
    (event,) = decoder.feed(b"#" + name.encode() + digits + b"!")
    assert isinstance(event, BadFrame)
    assert event.reason is Reason.MALFORMED
    assert decoder.checksum_enabled


def test_stop_is_the_only_command_honoured_bare() -> None:
    from rovlink.protocol import COMMANDS

    assert [spec.name for spec in COMMANDS if spec.honoured_bare] == ["stop"]
