"""Wall-clock pacing: when simulation ticks are due, and bytes at a serial line's rate.

Both are pure bookkeeping over times the caller passes in, so the stepping code is the same in
real time and as fast as possible, and tests need no sleeping.
"""

from __future__ import annotations

import logging
import math

from rovlink.logs import get_logger
from rovlink.protocol.frames import BITS_PER_BYTE_8N1

__all__ = ["LinePacer", "TickSchedule"]

logger = get_logger(__name__)


class TickSchedule:
    """How many simulation ticks are due at a wall-clock time.

    ``speed`` is simulated seconds per wall second: 1 is real time; 0 means as fast as
    possible. Either way no call gives more than ``batch_ticks``: the rest are due at the next
    call, so the caller serves its lines between batches. When the simulation falls more than
    ``max_lag_s`` behind (a suspended process, an overloaded machine, a speed beyond the CPU),
    it skips ahead instead of racing.
    """

    def __init__(
        self,
        tick_s: float,
        start_wall_s: float,
        *,
        speed: float = 1.0,
        batch_ticks: int = 100,
        max_lag_s: float = 0.5,
    ) -> None:
        if not (math.isfinite(speed) and speed >= 0):
            raise ValueError(f"speed must be ≥ 0, got {speed}")
        self.tick_s = tick_s
        self.speed = speed
        self.batch_ticks = batch_ticks
        self._max_lag_s = max_lag_s
        self._start_wall_s = start_wall_s
        self._ticks = 0
        self._skipped_before = False

    @property
    def as_fast_as_possible(self) -> bool:
        """Whether the schedule ignores the wall clock."""
        return self.speed == 0

    def due(self, wall_s: float) -> int:
        """Ticks to run now; the caller runs them and they count as done."""
        if self.speed == 0:
            return self.batch_ticks
        wanted = math.floor((wall_s - self._start_wall_s) * self.speed / self.tick_s + 1e-9)
        count = wanted - self._ticks
        if count * self.tick_s / self.speed > self._max_lag_s:
            # A speed the CPU cannot keep up with skips ahead every max_lag_s: say it once.
            logger.log(
                logging.DEBUG if self._skipped_before else logging.WARNING,
                "simulation %.2f s behind the wall clock: skipping ahead",
                count * self.tick_s / self.speed,
            )
            self._skipped_before = True
            count = 1
            self._start_wall_s = wall_s - (self._ticks + 1) * self.tick_s / self.speed
        # Capped: at a speed beyond the CPU, the ticks of max_lag_s took longer than that to
        # run, so every batch was longer than the last, and the lines (a #stop! among them)
        # went unserved for seconds.
        count = min(max(count, 0), self.batch_ticks)
        self._ticks += count
        return count

    def seconds_until_next(self, wall_s: float) -> float:
        """Wall seconds until the next tick is due (0 when one is due or in fast mode)."""
        if self.speed == 0:
            return 0.0
        next_wall_s = self._start_wall_s + (self._ticks + 1) * self.tick_s / self.speed
        return max(next_wall_s - wall_s, 0.0)


class LinePacer:
    """One direction of a serial line: bytes leave no faster than ``baud`` allows (8N1).

    ``baud=None`` is an unpaced line: every byte is released at once.
    """

    __slots__ = ("_buffer", "_byte_s", "_limit", "_start_s", "dropped_bytes")

    def __init__(self, baud: int | None, *, limit_bytes: int = 1 << 16) -> None:
        if baud is not None and baud <= 0:
            raise ValueError(f"baud must be > 0, got {baud}")
        self._byte_s = 0.0 if baud is None else BITS_PER_BYTE_8N1 / baud
        self._buffer = bytearray()
        self._start_s = -math.inf  # when the first buffered byte started on the line
        self._limit = limit_bytes
        #: Bytes lost because nobody drained the line (as a UART's FIFO overflows).
        self.dropped_bytes = 0

    @property
    def byte_s(self) -> float:
        """Seconds one byte takes on the line (0 if unpaced)."""
        return self._byte_s

    def __len__(self) -> int:
        return len(self._buffer)

    def push(self, data: bytes, now_s: float) -> None:
        """Queue bytes for the line at wall time ``now_s``."""
        if not self._buffer:
            self._start_s = max(self._start_s, now_s)
        self._buffer += data
        overflow = len(self._buffer) - self._limit
        if overflow > 0:
            del self._buffer[:overflow]
            self.dropped_bytes += overflow

    def release(self, now_s: float) -> bytes:
        """The bytes whose transmission has finished by ``now_s``."""
        if not self._buffer:
            return b""
        if self._byte_s == 0.0:
            count = len(self._buffer)
        else:
            count = min(int((now_s - self._start_s) / self._byte_s + 1e-9), len(self._buffer))
            if count <= 0:
                return b""
            self._start_s += count * self._byte_s
        released = bytes(self._buffer[:count])
        del self._buffer[:count]
        return released

    def next_release_s(self) -> float | None:
        """Wall time at which the next byte is complete, or None if nothing is queued."""
        if not self._buffer:
            return None
        return self._start_s + self._byte_s
