"""The control loop's fixed rate: when the next period is due, and the overruns counted.

Pure bookkeeping over the times the caller passes in, so the loop's timing is tested with a
simulated clock.
"""

from __future__ import annotations

import math

__all__ = ["FixedRateSchedule"]


class FixedRateSchedule:
    """Control periods at ``period_s`` on a fixed grid from ``start_s`` (no drift).

    A period *overruns* when its work ends after the next period was due (too much work, or
    the process woke late). The loop then skips the periods it missed rather than running them
    back to back, and counts both.
    """

    def __init__(self, period_s: float, start_s: float) -> None:
        if not (math.isfinite(period_s) and period_s > 0):
            raise ValueError(f"period_s must be > 0, got {period_s}")
        self.period_s = period_s
        self.next_s = start_s
        self.periods = 0
        self.overruns = 0
        self.skipped_periods = 0
        self.longest_s = 0.0

    def is_due(self, now_s: float) -> bool:
        """Whether a period is due."""
        return now_s >= self.next_s

    def seconds_until_due(self, now_s: float) -> float:
        """How long until the next period is due (0 if it is)."""
        return max(0.0, self.next_s - now_s)

    def finished(self, started_s: float, now_s: float) -> bool:
        """Record that the period due now ran from ``started_s`` to ``now_s``; True on overrun."""
        self.periods += 1
        self.longest_s = max(self.longest_s, now_s - started_s)
        self.next_s += self.period_s
        if now_s < self.next_s:
            return False
        missed = math.floor((now_s - self.next_s) / self.period_s) + 1
        self.overruns += 1
        self.skipped_periods += missed
        self.next_s += missed * self.period_s
        return True
