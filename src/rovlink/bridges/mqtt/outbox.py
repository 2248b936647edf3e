"""Events kept while the broker is away, published when it is back (at least once, QoS 1)."""

from __future__ import annotations

from collections import deque

__all__ = ["Outbox"]


class Outbox:
    """A bounded queue of ``(topic, payload)``; the oldest go first when it is full.

    >>> box = Outbox(capacity=2)
    >>> for n in range(3):
    ...     box.put("t", bytes([n]))
    >>> box.dropped, [payload for _, payload in box.items()]
    (1, [b'\\x01', b'\\x02'])
    """

    def __init__(self, capacity: int = 1000) -> None:
        self._items: deque[tuple[str, bytes]] = deque(maxlen=capacity)
        #: Events lost because the outbox was full.
        self.dropped = 0

    def __len__(self) -> int:
        return len(self._items)

    def put(self, topic: str, payload: bytes) -> None:
        """Keep an event to publish."""
        if len(self._items) == self._items.maxlen:
            self.dropped += 1
        self._items.append((topic, payload))

    def items(self) -> list[tuple[str, bytes]]:
        """What is kept, oldest first (still kept until :meth:`done`)."""
        return list(self._items)

    def peek(self) -> tuple[str, bytes] | None:
        """The oldest event, if any."""
        return self._items[0] if self._items else None

    def done(self) -> None:
        """The oldest event was published."""
        self._items.popleft()
