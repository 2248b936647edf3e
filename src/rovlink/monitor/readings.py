"""What the monitor has received: the latest sensor reading, when, and the depth over time."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from rovlink.client import Sensors

__all__ = ["DEFAULT_WINDOW_S", "DepthSample", "Readings"]

#: Seconds of depth history kept for the chart.
DEFAULT_WINDOW_S = 60.0


@dataclass(frozen=True, slots=True)
class DepthSample:
    """One depth reading and when it arrived (monotonic seconds)."""

    at_s: float
    depth_cm: int


@dataclass(slots=True)
class Readings:
    """The latest reading, the depth history of the last ``window_s`` seconds, the leak alarm.

    >>> readings = Readings(window_s=10.0)
    >>> readings.record(Sensors(120, 530, False, -1, 3, 275), at_s=5.0)
    >>> readings.latest.depth_cm, readings.age_s(6.5)
    (120, 1.5)
    """

    window_s: float = DEFAULT_WINDOW_S
    latest: Sensors | None = None
    latest_at_s: float | None = None
    history: deque[DepthSample] = field(default_factory=deque)
    #: Set by the first reading with the leak latch set; cleared only by a reading without it.
    leak_since_s: float | None = None

    def record(self, reading: Sensors, at_s: float) -> None:
        """A new reading arrived at ``at_s``."""
        self.latest = reading
        self.latest_at_s = at_s
        self.history.append(DepthSample(at_s, reading.depth_cm))
        oldest_s = at_s - self.window_s
        while self.history and self.history[0].at_s < oldest_s:
            self.history.popleft()
        if reading.leak_detected:
            if self.leak_since_s is None:
                self.leak_since_s = at_s
        else:
            self.leak_since_s = None

    @property
    def leak(self) -> bool:
        """Whether the latest reading had the leak latch set."""
        return self.leak_since_s is not None

    def age_s(self, now_s: float) -> float | None:
        """Seconds since the latest reading; ``None`` before the first."""
        return None if self.latest_at_s is None else now_s - self.latest_at_s
