"""The control loop's fixed rate and its overrun count, on a simulated clock."""

from __future__ import annotations

import pytest

from rovlink.board.schedule import FixedRateSchedule


def test_periods_stay_on_a_fixed_grid() -> None:
    schedule = FixedRateSchedule(0.01, start_s=100.0)
    assert schedule.is_due(100.0)
    # Each period's work takes 3 ms and starts a little late: no drift, no overrun.
    for n in range(100):
        start = 100.0 + n * 0.01 + 0.0005
        assert schedule.is_due(start)
        assert not schedule.finished(start, start + 0.003)
        assert not schedule.is_due(start + 0.003)
    assert schedule.next_s == pytest.approx(101.0)
    assert schedule.seconds_until_due(100.9995) == pytest.approx(0.0005)
    assert (schedule.periods, schedule.overruns, schedule.skipped_periods) == (100, 0, 0)
    assert schedule.longest_s == pytest.approx(0.003)


def test_an_overrun_is_counted_and_the_missed_periods_skipped() -> None:
    schedule = FixedRateSchedule(0.01, start_s=0.0)
    assert not schedule.finished(0.0, 0.004)
    # The period due at 0.01 s takes 25 ms: the ones due at 0.02 and 0.03 s are missed.
    assert schedule.finished(0.01, 0.035)
    assert (schedule.overruns, schedule.skipped_periods) == (1, 2)
    assert schedule.next_s == pytest.approx(0.04)  # back on the grid, no burst to catch up
    assert not schedule.is_due(0.039)
    assert not schedule.finished(0.04, 0.041)
    assert schedule.overruns == 1


def test_a_late_wake_up_counts_as_an_overrun() -> None:
    schedule = FixedRateSchedule(0.01, start_s=0.0)
    schedule.finished(0.0, 0.001)
    # The process was not scheduled for 50 ms (a loaded machine): its work was quick.
    assert schedule.finished(0.061, 0.062)
    assert schedule.overruns == 1
    assert schedule.next_s == pytest.approx(0.07)


def test_a_period_must_be_positive() -> None:
    with pytest.raises(ValueError, match="period_s must be > 0"):
        FixedRateSchedule(0.0, 0.0)
