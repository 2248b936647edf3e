"""Reading a recording back at its recorded pace, and resending its commands so."""

from __future__ import annotations

import pytest

from rovlink.protocol import Command, Response
from rovlink.recorder import Entry, FrameEntry, HeaderEntry
from rovlink.recorder.comparison import ReplayStep, run_replay
from rovlink.recorder.playback import paced

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
