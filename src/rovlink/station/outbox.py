"""A page's outbox: the messages waiting for its WebSocket, bounded, that keep what matters.

A page too slow to take its messages (a slow network, a throttled browser) cannot be sent
everything: the outbox holds :attr:`Outbox.size` of them. When it is full, a message is dropped
only if a newer one of its kind makes it useless — a reading (``telemetry``), a ``heartbeat``,
a ``recording`` state (each is the whole state, and a newer one waits behind it or arrives) —
the oldest of them first: the page skips old readings and catches up with the newest. What is
not superseded (``hello``, ``control``, ``log``, ``error``) is never dropped for a reading. An
outbox full of those, with nothing superseded to drop, *overflows*: the page is hopelessly
behind, its outbox is emptied and the page must be closed (it reconnects and gets a fresh
``hello`` with the whole state).

>>> outbox = Outbox(2)
>>> for t in (1, 2, 3):
...     outbox.put({"type": "telemetry", "t": t})
>>> [outbox.get_nowait()["t"] for _ in range(len(outbox))], outbox.dropped_messages
([2, 3], 1)
"""

from __future__ import annotations

import asyncio
from collections import Counter, deque
from typing import Any

__all__ = ["SUPERSEDED_KINDS", "Outbox", "OutboxOverflowError"]

#: The message types a newer one of the same type makes useless: each carries the whole of what
#: it shows (a reading, the station's time, the recording's state), none an event of its own.
SUPERSEDED_KINDS = frozenset({"telemetry", "heartbeat", "recording"})


class OutboxOverflowError(Exception):
    """The outbox was full of messages that may not be dropped: the page must be closed."""


class Outbox:
    """At most ``size`` messages for one page, taken in order by :meth:`get`; see the module."""

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError(f"an outbox holds at least one message, not {size}")
        self.size = size
        #: Messages the page will never get: superseded ones dropped, and those lost with an
        #: overflow.
        self.dropped_messages = 0
        #: The page is hopelessly behind (see the module): nothing more is queued for it.
        self.overflowed = False
        self._messages: deque[dict[str, Any]] = deque()
        self._kinds: Counter[str] = Counter()
        self._ready = asyncio.Event()  # set while there is a message or the overflow to tell
        self._overflow = asyncio.Event()

    def __len__(self) -> int:
        return len(self._messages)

    def empty(self) -> bool:
        """Whether no message waits."""
        return not self._messages

    def put(self, message: dict[str, Any]) -> None:
        """Queue ``message``; when full, drop the oldest superseded message to make room (or
        overflow: see the module)."""
        if self.overflowed:
            self.dropped_messages += 1
            return
        if len(self._messages) >= self.size and not self._drop_superseded(message["type"]):
            self.dropped_messages += len(self._messages) + 1
            self._messages.clear()
            self._kinds.clear()
            self.overflowed = True
            self._overflow.set()
            self._ready.set()
            return
        self._messages.append(message)
        self._kinds[message["type"]] += 1
        self._ready.set()

    def get_nowait(self) -> dict[str, Any]:
        """The oldest message waiting; :class:`IndexError` if none does."""
        message = self._messages.popleft()
        self._kinds[message["type"]] -= 1
        if not self._messages and not self.overflowed:
            self._ready.clear()
        return message

    async def get(self) -> dict[str, Any]:
        """The oldest message, once there is one; :class:`OutboxOverflowError` once overflowed."""
        while True:
            if self.overflowed:
                raise OutboxOverflowError("the page fell too far behind")
            if self._messages:
                return self.get_nowait()
            await self._ready.wait()

    async def wait_overflow(self) -> None:
        """Return once the outbox has overflowed (the page must be closed)."""
        await self._overflow.wait()

    def _drop_superseded(self, arriving: str) -> bool:
        """Drop the oldest message that a newer one of its kind (queued, or ``arriving``)
        supersedes; ``False`` if none is."""
        for index, message in enumerate(self._messages):
            kind = message["type"]
            if kind in SUPERSEDED_KINDS and self._kinds[kind] + (kind == arriving) >= 2:
                del self._messages[index]
                self._kinds[kind] -= 1
                self.dropped_messages += 1
                return True
        return False
