"""Polling every sensor at a rate that may change while it runs, for the bridges."""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from rovlink.aio.wakeup import wait_for_event
from rovlink.client.errors import ConnectionLostError, QueryTimeoutError
from rovlink.client.sensors import Sensors
from rovlink.logs import get_logger
from rovlink.piloting.tracked import TrackedClient

__all__ = ["SensorPoller", "reopening"]

logger = get_logger("rovlink.bridges")


def reopening(rov: TrackedClient, error: BaseException) -> bool:
    """Whether ``error`` is the controller link being reopened (a client with ``reconnect``):
    a bridge carries on, rather than end as when the connection is lost for good or closed."""
    return isinstance(error, ConnectionError) and not rov.client.closed


class SensorPoller:
    """Reads ``#qsa!`` at :attr:`rate_hz` and hands every reading to ``on_reading``.

    A reading that times out is logged and counted in the client's link health (the bridges
    publish that health). A link being reopened (a client with ``reconnect``) skips readings
    until it is back; a connection lost for good ends :meth:`run` with ``ConnectionLostError``.
    Each reading missed (timed out or skipped) calls ``on_missed``: the last one is no longer
    the robot as it is.
    """

    def __init__(
        self,
        rov: TrackedClient,
        on_reading: Callable[[Sensors], None],
        *,
        rate_hz: float = 5.0,
        on_missed: Callable[[], None] = lambda: None,
    ) -> None:
        self._rov = rov
        self._on_reading = on_reading
        self._on_missed = on_missed
        self.rate_hz = rate_hz
        self.latest: Sensors | None = None
        self._rate_changed = asyncio.Event()

    def set_rate(self, rate_hz: float) -> None:
        """Poll at ``rate_hz`` from the next reading on (a faster rate takes effect at once)."""
        if rate_hz <= 0:
            raise ValueError(f"poll rate must be > 0 Hz, got {rate_hz}")
        self.rate_hz = rate_hz
        self._rate_changed.set()

    async def run(self) -> None:
        """Poll until cancelled."""
        loop = asyncio.get_running_loop()
        due_s = loop.time()
        while True:
            try:
                reading = await self._rov.sensors()
            except QueryTimeoutError as error:
                logger.warning("sensor poll failed: %s", error)
                self._on_missed()
            except ConnectionLostError as error:
                if not reopening(self._rov, error):
                    raise
                logger.debug("sensor poll skipped: %s", error)  # (the client says it is lost)
                self._on_missed()
            else:
                self.latest = reading
                self._on_reading(reading)
            # Keep the cadence (a slow reply does not push every later one back); after a
            # stall, start again from now rather than catch up in a burst.
            due_s += 1.0 / self.rate_hz
            now_s = loop.time()
            if due_s <= now_s:
                due_s = now_s
                continue
            self._rate_changed.clear()
            await wait_for_event(self._rate_changed, due_s - now_s)
            if self._rate_changed.is_set():
                due_s = loop.time()  # a new rate: from now
