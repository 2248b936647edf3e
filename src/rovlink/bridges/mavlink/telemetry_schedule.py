"""Which telemetry message is due when, at the rates a ground station asks for.

A ground station sets rates with REQUEST_DATA_STREAM (a stream: a group of messages, in Hz) or
SET_MESSAGE_INTERVAL (one message, in µs). HEARTBEAT stays at 1 Hz whatever is asked: it is the
link's liveness signal for every ground station.
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["DEFAULT_RATES_HZ", "MAX_RATE_HZ", "STREAMS", "TelemetrySchedule"]

#: The messages sent unasked and their default rates, Hz.
DEFAULT_RATES_HZ: Mapping[str, float] = {
    "HEARTBEAT": 1.0,
    "SYS_STATUS": 1.0,
    "ATTITUDE": 4.0,
    "VFR_HUD": 4.0,
    "GLOBAL_POSITION_INT": 4.0,
    "SCALED_PRESSURE2": 2.0,
    "SYSTEM_TIME": 1.0,
}
#: The fastest rate served: the sensors are polled at most this often over the serial line.
MAX_RATE_HZ = 25.0
#: MAV_DATA_STREAM ids and the messages of each that the bridge sends (ArduPilot's grouping).
STREAMS: Mapping[int, tuple[str, ...]] = {
    1: ("SCALED_PRESSURE2",),  # RAW_SENSORS
    2: ("SYS_STATUS",),  # EXTENDED_STATUS
    6: ("GLOBAL_POSITION_INT",),  # POSITION
    10: ("ATTITUDE",),  # EXTRA1
    11: ("VFR_HUD",),  # EXTRA2
    12: ("SYSTEM_TIME",),  # EXTRA3
}
_ALL_STREAMS = 0
#: Messages filled from no sensor reading: their rates leave the sensor poll alone.
_CARRIES_NO_READING = frozenset({"HEARTBEAT", "SYSTEM_TIME"})
_FIXED = "HEARTBEAT"


class TelemetrySchedule:
    """Message rates and when each is next due.

    >>> schedule = TelemetrySchedule(now_s=0.0)
    >>> sorted(schedule.due(now_s=0.0))[:2]
    ['ATTITUDE', 'GLOBAL_POSITION_INT']
    >>> schedule.set_interval("ATTITUDE", 0.05, now_s=0.0)
    True
    >>> schedule.due(now_s=0.06)
    ['ATTITUDE']
    """

    def __init__(self, now_s: float) -> None:
        self.rates_hz: dict[str, float] = dict(DEFAULT_RATES_HZ)
        self._next_due_s: dict[str, float] = dict.fromkeys(self.rates_hz, now_s)

    def known(self, name: str) -> bool:
        """Whether ``name`` is a message the bridge can send on a schedule."""
        return name in DEFAULT_RATES_HZ

    def set_rate(self, name: str, rate_hz: float, now_s: float) -> bool:
        """Send ``name`` at ``rate_hz`` (0: not at all); ``False`` if it cannot be scheduled."""
        if not self.known(name) or name == _FIXED:
            return False
        rate = min(max(rate_hz, 0.0), MAX_RATE_HZ)
        self.rates_hz[name] = rate
        self._next_due_s[name] = now_s
        return True

    def set_interval(self, name: str, interval_s: float | None, now_s: float) -> bool:
        """SET_MESSAGE_INTERVAL: every ``interval_s`` (``None``: the default rate; ≤ 0: off)."""
        if interval_s is None:
            return self.set_rate(name, DEFAULT_RATES_HZ.get(name, 0.0), now_s)
        return self.set_rate(name, 1.0 / interval_s if interval_s > 0 else 0.0, now_s)

    def set_stream(self, stream_id: int, rate_hz: float, now_s: float) -> None:
        """REQUEST_DATA_STREAM: every message of the stream (0: all streams) at ``rate_hz``."""
        streams = STREAMS.values() if stream_id == _ALL_STREAMS else [STREAMS.get(stream_id, ())]
        for names in streams:
            for name in names:
                self.set_rate(name, rate_hz, now_s)

    def interval_us(self, name: str) -> int:
        """MESSAGE_INTERVAL's value for ``name``: −1 while it is off, 0 if it is not sent on a
        schedule at all, else its interval in µs."""
        if not self.known(name):
            return 0
        rate_hz = self.rates_hz[name]
        return round(1_000_000 / rate_hz) if rate_hz > 0 else -1

    def fastest_rate_hz(self) -> float:
        """The highest rate asked for of a message that carries readings: how often the sensors
        need reading (SYSTEM_TIME, asked fast, is no reason to poll the serial line faster)."""
        return max(
            rate_hz for name, rate_hz in self.rates_hz.items() if name not in _CARRIES_NO_READING
        )

    def due(self, now_s: float) -> list[str]:
        """The messages due now; each is then scheduled one period later."""
        due = []
        for name, rate_hz in self.rates_hz.items():
            if rate_hz <= 0 or now_s < self._next_due_s[name]:
                continue
            due.append(name)
            period_s = 1.0 / rate_hz
            # Keep the cadence; after a stall, start again from now rather than catch up.
            next_due_s = self._next_due_s[name] + period_s
            self._next_due_s[name] = next_due_s if next_due_s > now_s else now_s + period_s
        return due

    def next_due_s(self) -> float:
        """When the next message is due."""
        return min(due_s for name, due_s in self._next_due_s.items() if self.rates_hz[name] > 0)
