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
    entries: list[Entry] = []
    for at_s, (direction, data) in enumerate(chunks):
        entries += log.entries(float(at_s), at_s, direction, data)
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
