"""Bytes seen by a tap or a sniffer, turned into entries: replies read in their query's checksum
mode, and a sniffer's commands recorded as commands."""

from __future__ import annotations

import asyncio

import rovlink
import rovlink.aio
from rovlink.client.events import (
    BytesSent,
    ClientEvent,
    LateReply,
    QueryFailed,
    ReplyReceived,
)
from rovlink.protocol import Command, Response, encode
from rovlink.recorder.entries import Entry, EventEntry, FrameEntry, TelemetryEntry
from rovlink.recorder.translate import ClientEventLog, TapLog


def _feed(log: TapLog, *chunks: tuple[str, bytes]) -> list[Entry]:
    """``chunks`` 10 ms apart: each reply well within the host's reply timeout."""
    entries: list[Entry] = []
    for index, (direction, data) in enumerate(chunks):
        entries += log.entries(index * 0.01, index, direction, data)
    return entries


def _problems(entries: list[Entry]) -> list[EventEntry]:
    return [
        e for e in entries if isinstance(e, EventEntry) and e.event in {"bad_frame", "stray_frame"}
    ]


def _replies(entries: list[Entry]) -> list[tuple[str | None, str, tuple[int, ...]]]:
    return [
        (e.query, e.name, e.values)
        for e in entries
        if isinstance(e, FrameEntry) and e.kind == "response"
    ]


def _checked(response: Response) -> bytes:
    return encode(response, "crc8")


def test_each_reply_is_read_in_the_mode_in_force_when_its_query_was_taken() -> None:
    # P3: in `#qd!#crcon!` the qd reply is plain; in `#qd8C!#crcoff!` it carries a checksum.
    entries = _feed(
        TapLog(),
        ("out", b"#qd!#crcon!"),
        ("in", encode(Response("qd", (5,)))),
        ("out", encode(Command("qd"), "crc8") + b"#crcoff!"),
        ("in", _checked(Response("qd", (6,)))),
    )
    assert _problems(entries) == []
    assert _replies(entries) == [("qd", "qd", (5,)), ("qd", "qd", (6,))]


def test_replies_of_two_modes_in_one_chunk_are_each_read_in_their_own() -> None:
    plain, checked = encode(Response("qd", (5,))), _checked(Response("qr", (7,)))
    entries = _feed(
        TapLog(),
        ("out", b"#qd!#crcon!" + encode(Command("qr"), "crc8")),
        ("in", plain[:3]),  # (a frame cut between chunks keeps its mode)
        ("in", plain[3:] + checked),
    )
    assert _problems(entries) == []
    assert _replies(entries) == [("qd", "qd", (5,)), ("qr", "qr", (7,))]


def test_a_sniffers_commands_are_recorded_as_commands() -> None:
    # Listening only, every byte is "in": the frames' # and $ still tell commands from replies.
    entries = _feed(
        TapLog(),
        ("in", b"#start!#qd!$qd.12!#crcon!"),
        ("in", encode(Command("qd"), "crc8") + _checked(Response("qd", (13,)))),
        ("in", b"#stop!"),
    )
    assert _problems(entries) == []
    commands = [e.name for e in entries if isinstance(e, FrameEntry) and e.kind == "command"]
    assert commands == ["start", "qd", "crcon", "qd", "stop"]
    assert _replies(entries) == [("qd", "qd", (12,)), ("qd", "qd", (13,))]
    locks = [e.detail for e in entries if isinstance(e, EventEntry) and e.event == "lock"]
    assert locks == ["unlocked", "locked"]
    last = [e for e in entries if isinstance(e, TelemetryEntry)][-1]
    assert last.values["locked"] == 1
    assert last.values["depth_cm"] == 13


def test_a_query_never_answered_does_not_set_the_mode_of_the_replies_after_it() -> None:
    # A probe sent while the board booted is never answered: read in its (plain) mode, every
    # checksummed reply after #crcon! was a bad frame, until 64 newer queries pushed it out.
    entries = _feed(
        TapLog(),
        ("out", b"#qd!"),  # never answered
        ("out", b"#crcon!" + encode(Command("qr"), "crc8")),
        ("in", _checked(Response("qr", (512,)))),
        ("out", encode(Command("qr"), "crc8")),
        ("in", _checked(Response("qr", (513,)))),
    )
    assert _problems(entries) == []
    assert _replies(entries) == [("qr", "qr", (512,)), ("qr", "qr", (513,))]


def _round_trips(entries: list[Entry]) -> list[tuple[str, float | None]]:
    return [
        (e.name, e.round_trip_ms)
        for e in entries
        if isinstance(e, FrameEntry) and e.kind == "response"
    ]


_SENSORS = b"$qd.1!$qr.2!$q.l.0!$qro.+0!$qpi.+0!$qhe.5!"


def test_a_tapped_reply_has_its_own_querys_round_trip_in_each_of_its_responses() -> None:
    # Each response of a qsa reply took a send time of its own: the second took the next
    # qsa's (50 ms here), the other four and the next reply had none.
    log = TapLog()
    entries = log.entries(0.0, 0, "out", b"#qsa!") + log.entries(0.05, 0, "out", b"#qsa!")
    entries += log.entries(0.1, 0, "in", _SENSORS) + log.entries(0.15, 0, "in", _SENSORS)
    assert (
        _round_trips(entries)
        == [(name, 100.0) for name in ("qd", "qr", "q.l", "qro", "qpi", "qhe")] * 2
    )


def test_a_tapped_reply_is_timed_from_its_own_query_not_an_unanswered_one() -> None:
    # The first qd was never answered (the qr after it was, so it never will be, P4): the
    # reply to the next qd was timed from it, two seconds before.
    log = TapLog()
    entries: list[Entry] = []
    for at_s, direction, data in (
        (0.0, "out", b"#qd!"),
        (1.0, "out", b"#qr!"),
        (1.001, "in", b"$qr.20!"),
        (2.0, "out", b"#qd!"),
        (2.003, "in", b"$qd.5!"),
    ):
        entries += log.entries(at_s, 0, direction, data)
    assert _round_trips(entries) == [("qr", 1.0), ("qd", 3.0)]


def test_a_late_reply_leaves_the_retrys_send_time_to_the_retrys_reply() -> None:
    # The late reply took the retry's send time, and the retry's own reply had none.
    query = Command("qd")
    log = ClientEventLog()
    entries: list[Entry] = []
    for event in (
        BytesSent(0.0, b"#qd!", query),
        QueryFailed(0.5, query, "timeout"),
        BytesSent(0.5, b"#qd!", query, by_session=True),
        LateReply(0.6, Response("qd", (4,))),
        ReplyReceived(0.503, query, (Response("qd", (5,)),)),
    ):
        entries += log.entries(0, event)
    assert _round_trips(entries) == [("qd", None), ("qd", 3.0)]


def _mode_frames_sent(events: list[ClientEvent]) -> list[tuple[str, bool]]:
    return [
        (event.command.name, event.by_session)
        for event in events
        if isinstance(event, BytesSent) and event.command is not None
    ]


def test_the_drivers_mode_frame_on_connecting_is_the_drivers_own() -> None:
    # It was recorded as a command of the program: listed without "(by the driver)" and resent
    # by rovlink replay --to, which then left the checksum mode --checksum asked for.
    events: list[ClientEvent] = []
    with rovlink.connect("sim://", on_event=events.append):
        pass
    assert _mode_frames_sent(events)[0] == ("crcoff", True)

    async def connect_async() -> None:
        async with rovlink.aio.connect("sim://", on_event=async_events.append):
            pass

    async_events: list[ClientEvent] = []
    asyncio.run(connect_async())
    assert _mode_frames_sent(async_events)[0] == ("crcoff", True)


def _timed(log: TapLog, *chunks: tuple[float, str, bytes]) -> list[Entry]:
    entries: list[Entry] = []
    for at_s, direction, data in chunks:
        entries += log.entries(at_s, 0, direction, data)
    return entries


def _late_flags(entries: list[Entry]) -> list[tuple[str | None, float | None, bool]]:
    return [
        (e.query, e.round_trip_ms, e.late)
        for e in entries
        if isinstance(e, FrameEntry) and e.kind == "response"
    ]


def test_a_query_that_timed_out_unanswered_is_not_matched_to_the_next_reply_of_its_name() -> None:
    # P20: the first qd's reply was lost; the next qd's reply, 3 s later, was matched to it
    # (3050 ms), and so was each later reply to the query before its own, for good.
    entries = _timed(
        TapLog(),
        (0.0, "out", b"#qd!"),
        (3.0, "out", b"#qd!"),
        (3.05, "in", b"$qd.7!"),
        (6.0, "out", b"#qd!"),
        (6.05, "in", b"$qd.8!"),
    )
    assert _late_flags(entries) == [("qd", 50.0, False), ("qd", 50.0, False)]
    assert _problems(entries) == []


def test_a_program_polling_faster_than_the_default_timeout_is_timed_with_its_own() -> None:
    # A program that waits 40 ms for each reply and polls every 50 ms: with its timeout given
    # (record --reply-timeout), a lost reply shifts no later round trip.
    entries = _timed(
        TapLog(reply_timeout_s=0.04),
        (0.0, "out", b"#qd!"),
        (0.05, "out", b"#qd!"),
        (0.051, "in", b"$qd.7!"),
        (0.1, "out", b"#qd!"),
        (0.101, "in", b"$qd.8!"),
    )
    assert _late_flags(entries) == [("qd", 1.0, False), ("qd", 1.0, False)]


def test_a_reply_after_its_query_timed_out_is_late() -> None:
    # No later query of its name awaits: the reply answers the one that timed out, late (the
    # host discarded it), with no round trip, as the driver's recordings show one.
    entries = _timed(TapLog(), (0.0, "out", b"#qd!"), (0.7, "in", b"$qd.7!"))
    assert _late_flags(entries) == [("qd", None, True)]
    late = [e for e in entries if isinstance(e, EventEntry) and e.event == "late_reply"]
    assert [(e.name, e.detail) for e in late] == [("qd", "after its query timed out")]


def test_a_pipelined_query_waits_a_timeout_from_the_last_reply_as_the_host_does() -> None:
    # On a slow line the host's deadline runs from the last reply that moved its queue: the
    # qr reply 800 ms after its query is on time, not late.
    entries = _timed(
        TapLog(),
        (0.0, "out", b"#qd!#qr!"),
        (0.4, "in", b"$qd.7!"),
        (0.8, "in", b"$qr.9!"),
    )
    assert _late_flags(entries) == [("qd", 400.0, False), ("qr", 800.0, False)]
