"""P3, P5: checksum and debug modes change from the next frame on, however the bytes are chunked.

A mode change never reaches back: a reply is encoded in the mode that stood when its query
arrived, and a dropped frame is reported only if debug output was on when it arrived.
"""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from rovlink.protocol import Decoder, Frame, Response, Text, encode
from tests.controller.controller_rig import Rig, make_rig


def _feed_in_chunks(rig: Rig, data: bytes, cuts: list[int]) -> bytes:
    """Feed ``data`` cut at ``cuts`` (offsets, any order, duplicates allowed); return the output."""
    output = bytearray()
    start = 0
    for cut in sorted({*cuts, len(data)}):
        if cut > start:
            output += rig.send(data[start:cut])
            start = cut
    return bytes(output)


def _cuts(data: bytes) -> st.SearchStrategy[list[int]]:
    return st.lists(st.integers(min_value=0, max_value=len(data)), max_size=len(data))


def _debug_lines(output: bytes) -> list[str]:
    return [event.text for event in Decoder().feed(output + b"\r\n") if isinstance(event, Text)]


# -- the examples, whole and one byte at a time ---------------------------------------


def test_a_query_before_crcon_in_the_same_chunk_is_answered_plain() -> None:
    assert make_rig().send(b"#qd!#crcon!") == b"$qd.0!"


def test_a_query_before_crcoff_in_the_same_chunk_is_answered_with_a_checksum() -> None:
    rig = make_rig()
    rig.send(b"#crcon!")
    assert rig.send(b"#qd8C!#crcoff!") == b"$qd.0A2!"
    assert not rig.controller.state().checksum_enabled


def test_a_query_after_crcon_in_the_same_chunk_is_answered_with_a_checksum() -> None:
    assert make_rig().send(b"#qd!#crcon!#qd8C!#qd!") == b"$qd.0!$qd.0A2!"


def test_mode_changes_back_and_forth_in_one_chunk() -> None:
    stream = b"#qd!#crcon!#qd8C!#crcoff!#qd!#crcon!#qd8C!"
    assert make_rig().send(stream) == b"$qd.0!$qd.0A2!$qd.0!$qd.0A2!"


def test_debug_on_and_off_in_one_chunk_each_take_effect_where_they_stand() -> None:
    output = make_rig().send(b"#debug1!#bogus!#debug0!#bogus!")
    dropped = [line for line in _debug_lines(output) if "bogus" in line]
    assert len(dropped) == 1, output


def test_debug_lines_report_each_checksum_mode_change_of_a_chunk_as_it_was() -> None:
    output = make_rig().send(b"#debug1!#crcon!#crcoff!")
    assert _debug_lines(output) == [
        "debug: debug output on",
        "debug: checksum mode on (crc8)",
        "debug: checksum mode off",
    ]


@given(st.data())
def test_per_frame_modes_hold_for_any_chunking(data: st.DataObject) -> None:
    examples = [
        (b"#qd!#crcon!", b"", b"$qd.0!"),
        (b"#qd8C!#crcoff!", b"#crcon!", b"$qd.0A2!"),
        (b"#qd!#crcon!#qd8C!#crcoff!#qd!", b"", b"$qd.0!$qd.0A2!$qd.0!"),
    ]
    for stream, setup, expected in examples:
        rig = make_rig()
        rig.send(setup)
        assert _feed_in_chunks(rig, stream, data.draw(_cuts(stream))) == expected


@given(st.data())
def test_debug_modes_hold_for_any_chunking(data: st.DataObject) -> None:
    stream = b"#debug1!#bogus!#debug0!#bogus!"
    output = _feed_in_chunks(make_rig(), stream, data.draw(_cuts(stream)))
    assert len([line for line in _debug_lines(output) if "bogus" in line]) == 1


# -- any stream: chunked input behaves as if each frame had arrived alone ----------------------

_FRAMES = [
    b"#qd!",
    b"#qd8C!",
    b"#q.l!",
    b"#crcon!",
    b"#crcoff!",
    b"#debug1!",
    b"#debug0!",
    b"#bogus!",
    b"#mgmp.100!",
    b"#qro!",
    b"noise\r\n",
]


@given(st.lists(st.sampled_from(_FRAMES), min_size=1, max_size=12), st.data())
def test_any_chunking_gives_the_output_of_one_frame_at_a_time(
    frames: list[bytes], data: st.DataObject
) -> None:
    reference = make_rig()
    expected = b"".join(reference.send(frame) for frame in frames)
    stream = b"".join(frames)
    rig = make_rig()
    assert _feed_in_chunks(rig, stream, data.draw(_cuts(stream))) == expected
    assert make_rig().send(stream) == expected
    assert rig.controller.state() == reference.controller.state()


def test_replies_in_a_mixed_chunk_decode_in_the_mode_they_were_sent_in() -> None:
    output = make_rig().send(b"#qd!#crcon!#qd8C!#crcoff!#qd!")
    decoder = Decoder()
    plain = decoder.feed(output[:6])
    decoder.checksum_enabled = True
    checked = decoder.feed(output[6:14])
    decoder.checksum_enabled = False
    plain += decoder.feed(output[14:])
    assert [event.message for event in plain + checked if isinstance(event, Frame)] == [
        Response("qd", (0,)),
        Response("qd", (0,)),
        Response("qd", (0,)),
    ]
    assert output[6:14] == encode(Response("qd", (0,)), "crc8")
