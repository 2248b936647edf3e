"""Wall-clock pacing of ticks and of bytes at a baud rate, with times passed in (no sleeping)."""

from __future__ import annotations

import logging

import pytest

from rovlink.sim.pacing import LinePacer, TickSchedule


def test_real_time_runs_one_tick_per_period() -> None:
    schedule = TickSchedule(0.01, start_wall_s=100.0)
    assert schedule.due(100.005) == 0
    assert schedule.seconds_until_next(100.005) == pytest.approx(0.005)
    assert schedule.due(100.010) == 1
    assert schedule.due(100.0355) == 2
    assert schedule.due(100.0355) == 0
    assert schedule.seconds_until_next(100.0355) == pytest.approx(0.0045)


def test_speed_scales_the_wall_clock() -> None:
    schedule = TickSchedule(0.01, start_wall_s=0.0, speed=10.0)
    assert schedule.due(0.1) == 100


def test_as_fast_as_possible_runs_batches_without_waiting() -> None:
    schedule = TickSchedule(0.01, start_wall_s=0.0, speed=0.0, batch_ticks=50)
    assert schedule.as_fast_as_possible
    assert schedule.due(0.0) == 50
    assert schedule.seconds_until_next(0.0) == 0.0


def test_a_long_stall_skips_ahead_instead_of_racing() -> None:
    schedule = TickSchedule(0.01, start_wall_s=0.0, max_lag_s=0.5)
    assert schedule.due(0.02) == 2
    assert schedule.due(30.0) == 1  # 30 s suspended: not 3000 ticks at once
    assert schedule.due(30.01) == 1


def test_a_speed_beyond_the_cpu_gives_its_ticks_in_batches() -> None:
    # 10 ms of wall time at 10 000 times real time is 10 000 ticks, more than a CPU runs in
    # 10 ms: given at once, the lines waited for them, and the next batch was longer still.
    schedule = TickSchedule(0.01, start_wall_s=0.0, speed=10_000.0, batch_ticks=100)
    batches = [schedule.due(0.01) for _ in range(101)]
    assert max(batches) == 100
    assert sum(batches) == 10_000  # none lost: the rest are due at the next calls
    assert batches[-1] == 0
    assert schedule.seconds_until_next(0.01) == pytest.approx(0.000001)


def test_a_schedule_that_cannot_keep_up_warns_once(caplog: pytest.LogCaptureFixture) -> None:
    schedule = TickSchedule(0.01, start_wall_s=0.0, speed=10_000.0, max_lag_s=0.5)
    with caplog.at_level(logging.DEBUG, logger="rovlink.sim.pacing"):
        assert schedule.due(1.0) == 1  # 1 s behind: skips ahead
        assert schedule.due(2.0) == 1
    assert [record.levelno for record in caplog.records] == [logging.WARNING, logging.DEBUG]


def test_speed_must_not_be_negative() -> None:
    with pytest.raises(ValueError, match="speed"):
        TickSchedule(0.01, start_wall_s=0.0, speed=-1.0)


def test_an_unpaced_line_releases_everything_at_once() -> None:
    line = LinePacer(None)
    line.push(b"#qd!", 5.0)
    assert line.release(5.0) == b"#qd!"
    assert line.next_release_s() is None


def test_a_paced_line_releases_bytes_at_the_8n1_rate() -> None:
    line = LinePacer(9600)  # 1.0417 ms a byte
    assert line.byte_s == pytest.approx(10 / 9600)
    line.push(b"0123456789", 1.0)
    assert line.release(1.0) == b""
    assert line.next_release_s() == pytest.approx(1.0 + 10 / 9600)
    assert line.release(1.0 + 3.5 * 10 / 9600) == b"012"
    assert line.release(1.0 + 10 * 10 / 9600) == b"3456789"
    assert len(line) == 0


def test_an_idle_line_starts_the_next_byte_when_it_is_pushed() -> None:
    line = LinePacer(1000)  # 10 ms a byte
    line.push(b"a", 0.0)
    assert line.release(0.5) == b"a"
    line.push(b"bc", 2.0)
    assert line.release(2.015) == b"b"
    line.push(b"d", 2.015)  # queued behind "c"
    assert line.release(2.029) == b"c"
    assert line.release(2.031) == b"d"


def test_an_undrained_line_drops_its_oldest_bytes() -> None:
    line = LinePacer(None, limit_bytes=4)
    line.push(b"abcdef", 0.0)
    assert line.dropped_bytes == 2
    assert line.release(0.0) == b"cdef"


def test_baud_must_be_positive() -> None:
    with pytest.raises(ValueError, match="baud"):
        LinePacer(0)
