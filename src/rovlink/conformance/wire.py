"""The conformance suite's own end of the line: raw bytes out, raw bytes and strict decoding in.

A conformance check judges the controller's bytes themselves (leading zeros, a missing checksum,
a stray ``!`` in debug text), which a host session forgives or hides by design: it retries,
accepts lowercase checksums and discards late replies. So the suite drives the link directly,
below the session, and reads what comes back with the protocol core's decoder. Every exchange is
kept as evidence: the bytes sent, the bytes received and how long the reply took.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from rovlink.client.links import Link
from rovlink.protocol import BadFrame, Decoder, Event, Frame, Text

__all__ = ["BITS_PER_BYTE", "Exchange", "Wire"]

#: A byte on an 8N1 serial line: a start bit, eight data bits, a stop bit.
BITS_PER_BYTE = 10


@dataclass
class Exchange:
    """What was sent, what came back, and when the last expected frame arrived."""

    sent: bytes
    received: bytes = b""
    events: list[Event] = field(default_factory=list)
    #: Seconds from the end of the write to the read that completed the expected frames.
    reply_s: float | None = None

    @property
    def frames(self) -> list[Frame | BadFrame]:
        """The frames received (valid or dropped by the decoder), in order."""
        return [event for event in self.events if isinstance(event, Frame | BadFrame)]

    @property
    def valid_frames(self) -> list[Frame]:
        """The frames that decoded to a message."""
        return [event for event in self.events if isinstance(event, Frame)]

    @property
    def text(self) -> list[Text]:
        """Text lines received between frames (debug output, noise)."""
        return [event for event in self.events if isinstance(event, Text)]


class Wire:
    """Raw exchanges with a controller over an open :class:`~rovlink.client.links.Link`.

    ``replies_checksummed`` is the checksum mode the replies are decoded in; the checks set it
    as they switch the controller's mode. Every exchange is recorded in :attr:`log`.

    ``baudrate``: the rate of the serial line the bytes cross, if any. A write returns once
    the serial driver holds the bytes, and the line takes ``10 / baudrate`` s a byte to carry
    them, after the bytes written before: the waits for a reply, or for the silence after a
    frame, count from when the bytes written so far have reached the controller.
    """

    def __init__(
        self,
        link: Link,
        *,
        algorithm: str = "crc8",
        baudrate: int | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.link = link
        self.algorithm = algorithm
        self._baudrate = baudrate
        self._clock = clock
        #: When the bytes written so far have crossed the line (the wire's clock).
        self._line_free_s = 0.0
        self._decoder = Decoder(algorithm=algorithm)
        self.log: list[Exchange] = []

    def now_s(self) -> float:
        """The wire's clock, s."""
        return self._clock()

    @property
    def replies_checksummed(self) -> bool:
        """Whether replies are expected to carry checksums (decoded so)."""
        return self._decoder.checksum_enabled

    @replies_checksummed.setter
    def replies_checksummed(self, enabled: bool) -> None:
        self._decoder.checksum_enabled = enabled

    def send(self, data: bytes, *, frames: int = 0, timeout_s: float, linger_s: float) -> Exchange:
        """Write ``data`` and read until ``frames`` frames came and then ``linger_s`` of quiet
        passed (to catch anything extra), or until ``timeout_s`` passed."""
        exchange = Exchange(sent=data)
        self.log.append(exchange)
        if data:
            self.link.write(data)
            if self._baudrate:
                on_line_s = len(data) * BITS_PER_BYTE / self._baudrate
                self._line_free_s = max(self._clock(), self._line_free_s) + on_line_s
        self._read(exchange, frames, timeout_s, linger_s)
        return exchange

    def drain(self, quiet_s: float, limit_s: float = 2.0) -> Exchange:
        """Read until nothing has come for ``quiet_s`` (at most ``limit_s``)."""
        return self.send(b"", timeout_s=limit_s, linger_s=quiet_s)

    def _read(self, exchange: Exchange, frames: int, timeout_s: float, linger_s: float) -> None:
        clock = self._clock
        start = clock()
        # (the reply time is measured from the write; the waits from the bytes' arrival)
        arrived = max(start, self._line_free_s)
        deadline = arrived + timeout_s
        quiet_until = arrived + linger_s if frames == 0 else None
        received = bytearray()
        count = 0
        while True:
            now = clock()
            until = deadline if quiet_until is None else min(deadline, quiet_until)
            if now >= until:
                break
            data = self.link.read_available(min(until - now, 0.05))
            if not data:
                continue
            now = clock()
            received += data
            events = self._decoder.feed(data)
            exchange.events.extend(events)
            count += sum(isinstance(event, Frame | BadFrame) for event in events)
            if frames and count >= frames and exchange.reply_s is None:
                exchange.reply_s = now - start
            if count >= frames:
                quiet_until = now + linger_s
        exchange.received = bytes(received)
