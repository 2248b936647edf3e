"""Events kept while the broker is away, published when it is back (at least once, QoS 1).

The outbox is bounded: when it is full the oldest event gives way, and the events dropped are
counted, with the times of the first and last of them, until the bridge says so
(:meth:`Outbox.take_drops`): a note it puts ahead of the kept events (:meth:`Outbox.put_first`),
so that subscribers learn what they missed before what followed it.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

__all__ = ["DEFAULT_CAPACITY", "DroppedEvents", "KeptEvent", "Outbox"]

#: Events kept by default while the broker is away.
DEFAULT_CAPACITY = 1000


@dataclass(frozen=True, slots=True)
class DroppedEvents:
    """Events the outbox dropped, full, and not yet said: how many, and when they happened."""

    count: int
    #: When the first and the last of them happened (their ``at``), Unix time, s.
    first_at_s: float
    last_at_s: float


@dataclass(frozen=True, slots=True, eq=False)
class KeptEvent:
    """One event waiting for the broker (compared by identity: each is its own)."""

    topic: str
    payload: bytes
    #: When it happened, Unix time, s.
    at_s: float


class Outbox:
    """A bounded queue of events; the oldest give way when it is full, and are counted.

    >>> box = Outbox(capacity=2)
    >>> [box.put("t", bytes([n]), at_s=10.0 + n) for n in range(4)]
    [False, False, True, True]
    >>> box.dropped, [event.payload for event in box.items()]
    (2, [b'\\x02', b'\\x03'])
    >>> box.take_drops(), box.take_drops()
    (DroppedEvents(count=2, first_at_s=10.0, last_at_s=11.0), None)
    >>> Outbox(capacity=0)
    Traceback (most recent call last):
    ...
    ValueError: the events kept for the broker must be at least 1, got 0
    """

    def __init__(self, capacity: int = DEFAULT_CAPACITY) -> None:
        if capacity < 1:
            raise ValueError(f"the events kept for the broker must be at least 1, got {capacity}")
        self.capacity = capacity
        self._items: deque[KeptEvent] = deque()
        #: Notes put ahead of the kept events (:meth:`put_first`), oldest first.
        self._first: deque[KeptEvent] = deque()
        #: Events lost because the outbox was full, since it was made.
        self.dropped = 0
        self._drops: DroppedEvents | None = None

    def __len__(self) -> int:
        return len(self._first) + len(self._items)

    def put(self, topic: str, payload: bytes, at_s: float) -> bool:
        """Keep an event that happened at ``at_s`` (Unix time, s) to publish; whether the
        oldest was dropped to make room for it."""
        dropped = len(self._items) >= self.capacity
        if dropped:
            oldest = self._items.popleft()
            self.dropped += 1
            drops = self._drops
            self._drops = DroppedEvents(
                1 if drops is None else drops.count + 1,
                oldest.at_s if drops is None else drops.first_at_s,
                oldest.at_s,
            )
        self._items.append(KeptEvent(topic, payload, at_s))
        return dropped

    def take_drops(self) -> DroppedEvents | None:
        """The events dropped since this was last asked, if any (then counted afresh)."""
        drops, self._drops = self._drops, None
        return drops

    def put_first(self, topic: str, payload: bytes, at_s: float) -> None:
        """Keep a note to publish before every kept event (what was dropped came before them);
        it never gives way."""
        self._first.append(KeptEvent(topic, payload, at_s))

    def items(self) -> list[KeptEvent]:
        """What is kept, in the order it is published (still kept until :meth:`done`)."""
        return [*self._first, *self._items]

    def peek(self) -> KeptEvent | None:
        """The next event to publish, if any."""
        if self._first:
            return self._first[0]
        return self._items[0] if self._items else None

    def done(self, event: KeptEvent) -> None:
        """``event`` was published: it is no longer kept (if it had been dropped meanwhile,
        nothing else is)."""
        for queue in (self._first, self._items):
            if queue and queue[0] is event:
                queue.popleft()
                return
