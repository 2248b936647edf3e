"""The faults themselves, sans-I/O: bytes in, damaged bytes out, counted, from a seeded stream.

Bit flips, drops and duplicates are rare events, so instead of a random draw per bit or byte the
injector draws the distance to the next event (a geometric distribution): a clean megabyte costs
a few draws, and the same seed gives the same damage however the stream is chunked.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

__all__ = ["FaultCounters", "FaultInjector"]


@dataclass
class FaultCounters:
    """What the injector did to one direction of the link."""

    bytes_in: int = 0
    bits_flipped: int = 0
    bytes_dropped: int = 0
    bytes_duplicated: int = 0
    chunks_delayed: int = 0

    def summary(self) -> str:
        """One line, e.g. ``120 bytes: 1 bit flipped, 0 dropped, 0 duplicated, 4 delayed``."""
        return (
            f"{self.bytes_in} bytes: {self.bits_flipped} bits flipped, "
            f"{self.bytes_dropped} dropped, {self.bytes_duplicated} duplicated, "
            f"{self.chunks_delayed} chunks delayed"
        )


class _EventGaps:
    """Distances between independent events of probability ``p`` per trial."""

    def __init__(self, probability: float, rng: random.Random) -> None:
        self._rng = rng
        self._log_q = math.log1p(-probability) if 0.0 < probability < 1.0 else None
        self._always = probability >= 1.0
        self._never = probability <= 0.0
        self.remaining = self._draw()

    def _draw(self) -> int:
        """Trials before the next event (0: the very next trial)."""
        if self._never:
            return 1 << 62
        if self._always or self._log_q is None:
            return 0
        return int(math.log(1.0 - self._rng.random()) / self._log_q)

    def events_in(self, trials: int) -> list[int]:
        """The indices (0-based) of the events among the next ``trials`` trials."""
        hits: list[int] = []
        position = self.remaining
        while position < trials:
            hits.append(position)
            position += 1 + self._draw()
        self.remaining = position - trials
        return hits


class FaultInjector:
    """Damage one direction of a byte stream: flip bits, then drop and duplicate bytes.

    >>> injector = FaultInjector(ber=0.0, drop=0.0, dup=1.0, rng=random.Random(1))
    >>> injector.apply(b"#qd!")
    b'##qqdd!!'
    >>> injector.counters.bytes_duplicated
    4
    """

    def __init__(self, *, ber: float, drop: float, dup: float, rng: random.Random) -> None:
        # A stream for each kind of event, so that the damage does not depend on the chunking.
        self._flips = _EventGaps(ber, random.Random(rng.getrandbits(64)))
        self._drops = _EventGaps(drop, random.Random(rng.getrandbits(64)))
        self._dups = _EventGaps(dup, random.Random(rng.getrandbits(64)))
        self.counters = FaultCounters()

    def apply(self, data: bytes) -> bytes:
        """The bytes as they arrive at the other end."""
        counters = self.counters
        counters.bytes_in += len(data)
        flips = self._flips.events_in(8 * len(data))
        damaged = bytearray(data)
        for bit in flips:
            damaged[bit >> 3] ^= 0x80 >> (bit & 7)
        counters.bits_flipped += len(flips)
        dropped = set(self._drops.events_in(len(damaged)))
        duplicated = set(self._dups.events_in(len(damaged)))
        if not dropped and not duplicated:
            return bytes(damaged)
        out = bytearray()
        for index, byte in enumerate(damaged):
            if index in dropped:
                counters.bytes_dropped += 1
                continue
            out.append(byte)
            if index in duplicated:
                counters.bytes_duplicated += 1
                out.append(byte)
        return bytes(out)
