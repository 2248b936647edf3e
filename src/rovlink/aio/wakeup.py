"""Waiting for an ``asyncio.Event`` or a timeout, whichever comes first, in a way that never
swallows a cancellation."""

from __future__ import annotations

import asyncio

__all__ = ["wait_for_event"]


async def wait_for_event(event: asyncio.Event, timeout_s: float | None) -> None:
    """Wait until ``event`` is set, at most ``timeout_s`` (``None``: no limit).

    Not ``asyncio.wait_for``: on Python 3.10 a cancellation that comes as the event is set is
    swallowed (bpo-37658). A bridge's task woken just as the bridge ends would run on for ever,
    and a ``close()`` cancelled by its caller's timeout as a reply came would go on draining.

    Example::

        await wait_for_event(self._wake_publisher, 0.5)
    """
    waiter = asyncio.ensure_future(event.wait())
    try:
        await asyncio.wait({waiter}, timeout=timeout_s)
    finally:
        waiter.cancel()
