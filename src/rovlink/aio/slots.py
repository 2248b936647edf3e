"""The asyncio client's bound on queries on the wire (``max_in_flight``).

An ``asyncio.Semaphore`` would do, but its ``acquire`` is a coroutine that scans its waiters
even when a slot is free, which costs a polling loop about half a microsecond a query. Here the
usual case is one test of an integer, and a freed slot is handed straight to the oldest waiter,
so that ``free`` is non-zero only while nobody waits.
"""

from __future__ import annotations

import asyncio
from collections import deque

__all__ = ["InFlightSlots", "check_max_in_flight"]


def check_max_in_flight(max_in_flight: object) -> None:
    """``max_in_flight`` as ``connect`` takes it: TypeError for what is no integer, ValueError
    for an integer below 1 (as every other setting's wrong type and wrong value are told apart).

    >>> check_max_in_flight(1.5)
    Traceback (most recent call last):
    ...
    TypeError: max_in_flight must be an integer ≥ 1, got 1.5
    >>> check_max_in_flight(0)
    Traceback (most recent call last):
    ...
    ValueError: max_in_flight must be an integer ≥ 1, got 0
    """
    text = f"max_in_flight must be an integer ≥ 1, got {max_in_flight!r}"
    if isinstance(max_in_flight, bool) or not isinstance(max_in_flight, int):
        raise TypeError(text)
    if max_in_flight < 1:
        raise ValueError(text)


class InFlightSlots:
    """At most ``count`` holders at a time, served in the order they came.

    Example::

        slots = InFlightSlots(8)
        if slots.free:      # the usual case, no coroutine
            slots.free -= 1
        else:
            await slots.take()
        try:
            ...
        finally:
            slots.release()
    """

    def __init__(self, count: int) -> None:
        self.free = count
        #: Those waiting for a slot, oldest first (none while ``free`` is non-zero).
        self.waiters: deque[asyncio.Future[None]] = deque()

    async def take(self) -> None:
        """Wait for a slot and hold it (take ``free`` directly when it is non-zero).

        Example::

            await slots.take()   # returns at once while a slot is free
            try:
                await rov.depth_cm()
            finally:
                slots.release()
        """
        if self.free:
            self.free -= 1
            return
        waiter: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self.waiters.append(waiter)
        try:
            await waiter
        except asyncio.CancelledError:
            if waiter.done() and not waiter.cancelled():
                self.release()  # handed a slot just before the cancellation: pass it on
            elif waiter in self.waiters:  # (a release may have dropped it already)
                self.waiters.remove(waiter)
            raise

    def release(self) -> None:
        """Give a slot back: to the oldest waiter, or to ``free``.

        >>> slots = InFlightSlots(1)
        >>> slots.free -= 1   # taken
        >>> slots.release()
        >>> slots.free
        1
        """
        waiters = self.waiters
        while waiters:
            waiter = waiters.popleft()
            if not waiter.done():
                waiter.set_result(None)
                return
        self.free += 1
