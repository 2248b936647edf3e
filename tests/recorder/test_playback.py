"""Reading a recording back at its recorded pace, and resending its commands so."""

from __future__ import annotations

import pytest

from rovlink.protocol import Command, Response
from rovlink.recorder import Entry, EventEntry, FrameEntry, HeaderEntry
from rovlink.recorder.comparison import ReplayStep, replay_steps, run_replay
from rovlink.recorder.playback import paced, session_lines

#: Ten billion seconds: more than time.sleep can wait at once (its clock counts about 292
#: years), as a damaged time in a recording can ask.
_FAR_OFF_S = 1e10


class _Clock:
    """A clock that the sleeps move on; after three sleeps the test has seen enough."""

    def __init__(self) -> None:
        self.now_s = 100.0
        self.sleeps: list[float] = []

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        if len(self.sleeps) == 3:
            raise _SeenEnoughError
        self.now_s += seconds

    def clock(self) -> float:
        return self.now_s


class _SeenEnoughError(Exception):
    pass


def test_a_far_off_time_is_waited_for_in_sleeps_time_can_take() -> None:
    # Before, one sleep of the whole gap: OverflowError, a traceback of replay --follow.
    entries: list[Entry] = [
        HeaderEntry(1.0, 1, "sim://", False, "crc8", "test", "0"),
        FrameEntry(2.0, 2, "out", "command", "qd", ()),
        FrameEntry(2.0 + _FAR_OFF_S, 3, "out", "command", "qd", ()),
    ]
    clock = _Clock()
    shown = paced(entries, 1.0, sleep=clock.sleep, clock=clock.clock)
    with pytest.raises(_SeenEnoughError):
        list(shown)
    assert clock.sleeps == [3600.0] * 3


def test_a_replay_waits_for_a_far_off_command_in_sleeps_time_can_take() -> None:
    steps = [
        ReplayStep(2.0, Command("qd")),
        ReplayStep(2.0 + _FAR_OFF_S, Command("qd")),
    ]
    clock = _Clock()
    replayed = run_replay(steps, lambda command: None, sleep=clock.sleep, clock=clock.clock)
    with pytest.raises(_SeenEnoughError):
        list(replayed)
    assert clock.sleeps == [3600.0] * 3


def test_a_divergence_shows_only_the_replies_that_differ_beyond_the_tolerance() -> None:
    # A pitch within the tolerance is no part of the difference (it was shown beside the leak,
    # as `recorded $qpi.+2!$q.l.0!, now $qpi.+3!$q.l.1!`).
    recorded = [Response("qd", (120,)), Response("qpi", (2,)), Response("q.l", (0,))]
    replayed = (Response("qd", (121,)), Response("qpi", (3,)), Response("q.l", (1,)))
    step = ReplayStep(1.0, Command("qsa"), recorded, expected_count=3)
    [(_, _, divergence)] = list(run_replay([step], lambda command: replayed, speed=0, tolerance=3))
    assert divergence is not None
    assert (divergence.recorded, divergence.replayed) == ("$q.l.0!", "$q.l.1!")


def test_a_difference_beyond_the_tolerance_is_shown() -> None:
    recorded = [Response("qd", (120,)), Response("qpi", (2,))]
    replayed = (Response("qd", (120,)), Response("qpi", (9,)))
    step = ReplayStep(1.0, Command("qsa"), recorded, expected_count=2)
    [(_, _, divergence)] = list(run_replay([step], lambda command: replayed, speed=0, tolerance=3))
    assert divergence is not None
    assert (divergence.recorded, divergence.replayed) == ("$qpi.+2!", "$qpi.+9!")


def _query(t_s: float, name: str = "qd", *, by_session: bool = False) -> FrameEntry:
    return FrameEntry(t_s, 0, "out", "command", name, (), by_session=by_session)


def _reply(t_s: float, value: int, query: str = "qd", name: str | None = None) -> FrameEntry:
    return FrameEntry(t_s, 0, "in", "response", name or query, (value,), query=query)


def _failed(t_s: float, name: str = "qd") -> EventEntry:
    return EventEntry(t_s, 0, "query_failed", name, "timeout")


def _recorded(steps: list[ReplayStep]) -> list[tuple[float, list[Response] | None, int]]:
    return [(step.t_s, step.recorded, step.expected_count) for step in steps]


def test_a_query_that_failed_for_good_recorded_no_reply_and_the_next_ones_their_own() -> None:
    # Its attempts failed (the driver retried it twice): the reply of each later qd was taken
    # for the one before's, and a replay showed every one of them as different.
    # (Each failure is followed by the driver's fence, #qhe!, and its retry.)
    entries: list[Entry] = [_query(1.0)]
    for at_s in (1.5, 2.0, 2.5):
        entries += [_failed(at_s), _query(at_s, "qhe", by_session=True), _reply(at_s, 9, "qhe")]
        if at_s < 2.5:
            entries.append(_query(at_s))
    entries.append(_query(3.0, "qr"))
    for index in range(3):
        entries += [_query(4.0 + index), _reply(4.01 + index, 10 + index)]
    assert _recorded(replay_steps(entries)) == [
        (1.0, None, 1),
        (3.0, None, 0),  # (the recording ends before its reply)
        (4.0, [Response("qd", (10,))], 1),
        (5.0, [Response("qd", (11,))], 1),
        (6.0, [Response("qd", (12,))], 1),
    ]


def test_a_query_answered_on_its_retry_recorded_the_retrys_reply() -> None:
    entries: list[Entry] = [
        _query(1.0, "qsa"),
        _reply(1.01, 5, "qsa", "qd"),  # the first of its six, then the rest lost: a failure
        _failed(1.5, "qsa"),
        _query(1.5, "qhe", by_session=True),  # the driver's fence
        _reply(1.5, 9, "qhe"),
        _query(1.5, "qsa"),  # its retry (recorded as the program's, as the driver sends it)
        *(_reply(1.51, 0, "qsa", name) for name in ("qd", "qr", "q.l", "qro", "qpi", "qhe")),
    ]
    [step] = replay_steps(entries)
    assert step.recorded is not None
    assert [response.values for response in step.recorded] == [(0,)] * 6  # the retry's alone


def test_a_query_the_recording_ends_before_the_reply_of_is_not_compared() -> None:
    # A --split part or a killed recorder ends between a query and its reply: a replay showed
    # a difference ('recorded no reply') that was none.
    entries: list[Entry] = [_query(1.0), _reply(1.01, 5), _query(2.0), _query(3.0)]
    assert _recorded(replay_steps(entries)) == [
        (1.0, [Response("qd", (5,))], 1),
        (2.0, None, 0),
        (3.0, None, 0),
    ]


def test_the_drivers_own_motion_and_lock_frames_are_replayed_where_they_were() -> None:
    # Before, an expired motion's zero thrust (and a #stop! kept for a reopened link) was left
    # out as the driver's: the replaying driver had to expire the motion itself, by the wall
    # clock, which at another --speed fell elsewhere, and where the recorded program (the
    # monitor) had no motion timeout, it stopped what the controller had kept going.
    entries: list[Entry] = [
        _query(0.5, "crcoff", by_session=True),  # a mode frame: the replaying driver's own
        _query(1.0, "start"),
        FrameEntry(1.1, 0, "out", "command", "th", (90, 40)),
        _query(2.0, "qhe", by_session=True),  # a keep-alive
        _reply(2.0, 90, "qhe"),
        EventEntry(3.1, 0, "motion_expired", "th", "zero thrust sent"),
        FrameEntry(3.1, 0, "out", "command", "th", (90, 0), by_session=True),
        _query(4.0, "stop", by_session=True),  # kept while the link was down
    ]
    assert [(step.t_s, str(step.command)) for step in replay_steps(entries)] == [
        (1.0, "#start!"),
        (1.1, "#th.90.40!"),
        (3.1, "#th.90.0!"),
        (4.0, "#stop!"),
    ]


def _marked(t_s: float, name: str = "qd", *, by_session: bool = False) -> FrameEntry:
    """A command as the driver's events record it: whether it was a retry is known."""
    return FrameEntry(t_s, 0, "out", "command", name, (), by_session=by_session, retry=False)


def test_a_keep_alive_on_the_wire_with_a_query_of_its_name_answers_none_of_the_programs() -> None:
    # Before, the keep-alive's reply (the older) was taken for the program's query, and its
    # failure for the program's failure: a replay showed "recorded no reply" where it had one.
    answered: list[Entry] = [_marked(1.0, by_session=True), _marked(1.01), _reply(1.02, 5)]
    answered.append(_reply(1.03, 6))
    failed: list[Entry] = [_marked(2.0, by_session=True), _marked(2.01), _failed(2.5)]
    failed.append(_reply(2.51, 7))
    assert _recorded(replay_steps(answered)) == [(1.01, [Response("qd", (6,))], 1)]
    assert _recorded(replay_steps(failed)) == [(2.01, [Response("qd", (7,))], 1)]


def test_the_listing_says_when_the_session_started() -> None:
    # Every time in it counted from the start, and nothing said when that was.
    header = HeaderEntry(10.0, 1_795_806_432_000_000_000, "sim://", False, "crc8", "demo", "1")
    damaged = HeaderEntry(10.0, 10**30, "sim://", False, "crc8", "demo", "1")
    assert list(session_lines([header, damaged])) == [
        "    0.000 s  --   demo 1 on sim:// (no checksum), started 2026-11-27 19:07:12 UTC",
        "    0.000 s  --   demo 1 on sim:// (no checksum)",
    ]


def test_a_taps_own_stop_is_listed_as_the_taps() -> None:
    # The #stop! a tap sends when a program leaves mid-dive was listed "(by the driver)", in a
    # session no rovlink driver took part in: a team asking why the robot stopped looked for
    # it in the pilot's program.
    stop = FrameEntry(12.0, 0, "out", "command", "stop", (), by_session=True)
    tap = HeaderEntry(10.0, 0, "socket://rov:5760", False, "crc8", "rovlink record", "1")
    driver = HeaderEntry(10.0, 0, "sim://", False, "crc8", "rovlink demo", "1")
    assert list(session_lines([tap, stop]))[-1] == "    2.000 s  out  #stop!  (by the tap)"
    assert list(session_lines([driver, stop]))[-1] == "    2.000 s  out  #stop!  (by the driver)"
