"""A pyserial-like port that injects faults into another link, in both directions.

Two daemon threads move the bytes: one reads the inner link, damages what it reads and queues it
for the host with its delay; one writes the host's (damaged) bytes to the inner link when their
delay is over. Without a delay the host's bytes go straight through in the caller's thread.
"""

from __future__ import annotations

import collections
import random
import threading
import time

from rovlink.client.errors import ConnectionLostError
from rovlink.client.links import Link
from rovlink.faults.injector import FaultCounters, FaultInjector
from rovlink.faults.settings import FaultSettings
from rovlink.logs import get_logger

__all__ = ["FaultPort"]

logger = get_logger(__name__)

_READ_WAIT_S = 0.02
#: How long close() waits for each of the port's threads to end, s.
_JOIN_S = 1.0
#: How long a close() waits for one under way in another thread, s: its joins and the write
#: of the held-back bytes.
_CLOSE_WAIT_S = 2 * _JOIN_S + 1.0


class _Delayed:
    """Chunks waiting for their time, in order (a serial line never reorders)."""

    def __init__(self, settings: FaultSettings, rng: random.Random) -> None:
        self._settings = settings
        self._rng = rng
        self._last_due_s = 0.0
        self.chunks: collections.deque[tuple[float, bytes]] = collections.deque()

    def push(self, data: bytes, now_s: float, counters: FaultCounters) -> None:
        settings = self._settings
        delay_s = settings.delay_ms / 1000.0
        if settings.jitter_ms:
            delay_s += self._rng.uniform(-settings.jitter_ms, settings.jitter_ms) / 1000.0
        due_s = max(now_s + delay_s, self._last_due_s)
        self._last_due_s = due_s
        if delay_s > 0:
            counters.chunks_delayed += 1
        self.chunks.append((due_s, data))

    def pop_due(self, now_s: float) -> bytes:
        out = bytearray()
        chunks = self.chunks
        while chunks and chunks[0][0] <= now_s:
            out += chunks.popleft()[1]
        return bytes(out)

    def next_due_s(self) -> float | None:
        return self.chunks[0][0] if self.chunks else None


class FaultPort:
    """The pyserial subset (``read``, ``in_waiting``, ``write``, ``close``, ``timeout``,
    ``is_open``) over an inner :class:`~rovlink.client.links.Link`, with faults.

    ``counters`` says what was done to each direction: ``to_controller`` and
    ``from_controller``.
    """

    def __init__(self, inner: Link, settings: FaultSettings, name: str = "fault://") -> None:
        self.timeout: float | None = None
        self.name = name
        self.settings = settings
        self._inner = inner
        seeds = random.Random(settings.seed)
        self._down = FaultInjector(
            ber=settings.ber, drop=settings.drop, dup=settings.dup, rng=_child(seeds)
        )
        self._up = FaultInjector(
            ber=settings.ber, drop=settings.drop, dup=settings.dup, rng=_child(seeds)
        )
        self._down_delay = _Delayed(settings, _child(seeds))
        self._up_delay = _Delayed(settings, _child(seeds))
        self._lock = threading.Condition()
        self._write_lock = threading.Lock()
        self._open = True
        #: Set once close() has sent the held-back bytes and closed the inner link.
        self._closed = threading.Event()
        self._lost: str | None = None
        self._reader = threading.Thread(target=self._read_loop, name="fault reader", daemon=True)
        self._reader.start()
        self._writer: threading.Thread | None = None
        if settings.delays:
            self._writer = threading.Thread(
                target=self._write_loop, name="fault writer", daemon=True
            )
            self._writer.start()

    @property
    def counters(self) -> dict[str, FaultCounters]:
        """What was done to the bytes of each direction so far."""
        return {"to_controller": self._down.counters, "from_controller": self._up.counters}

    @property
    def is_open(self) -> bool:
        """Whether the port can be used."""
        return self._open and self._lost is None

    @property
    def in_waiting(self) -> int:
        """Bytes whose delay is over, ready to read."""
        with self._lock:
            return sum(len(data) for due, data in self._up_delay.chunks if due <= time.monotonic())

    def write(self, data: bytes) -> int:
        """Damage ``data`` and send it (after its delay)."""
        self._check()
        with self._lock:
            damaged = self._down.apply(bytes(data))
            if self._writer is not None:
                self._down_delay.push(damaged, time.monotonic(), self._down.counters)
                self._lock.notify_all()
                return len(data)
        if damaged:
            with self._write_lock:
                self._inner.write(damaged)
        return len(data)

    def read(self, size: int = 1) -> bytes:
        """Up to ``size`` bytes whose delay is over, waiting up to :attr:`timeout` for one."""
        deadline = None if self.timeout is None else time.monotonic() + self.timeout
        with self._lock:
            while True:
                now = time.monotonic()
                ready = self._take(now, size)
                if ready:
                    return ready
                self._check()
                due = self._up_delay.next_due_s()
                wait_s = None if due is None else max(due - now, 0.0)
                if deadline is not None:
                    remaining = deadline - now
                    if remaining <= 0:
                        return b""
                    wait_s = remaining if wait_s is None else min(wait_s, remaining)
                self._lock.wait(wait_s)

    def close(self) -> None:
        """Send the host's bytes still held back by the delay, then close the inner link and
        stop the threads (idempotent: called while another thread closes the port, it returns
        once that close has ended).

        The held-back bytes go at once rather than being dropped: a program's last ``#stop!``
        is typically written just before it closes its link, and a serial line delivers what
        was written before it was closed.
        """
        with self._lock:
            closing = self._open
            self._open = False
            self._lock.notify_all()
        if not closing:
            # Another thread's close is under way (the driver's abort_writes() closes the port
            # from a thread of its own): returning before it has sent the held-back bytes let
            # a program exit, its threads with it, without its last #stop!.
            self._closed.wait(_CLOSE_WAIT_S)
            return
        try:
            self._inner.wake()
            self._reader.join(timeout=_JOIN_S)
            if self._writer is not None:
                self._writer.join(timeout=_JOIN_S)
                self._flush_delayed()
            self._inner.close()
        finally:
            self._closed.set()
        for direction, counters in self.counters.items():
            logger.info("%s %s: %s", self.name, direction, counters.summary())

    def send_clean(self, data: bytes) -> None:
        """Write ``data`` to the inner link at once, without faults (a proxy's last ``#stop!``).

        The host's bytes still waiting for their delay are discarded first: sent after it, a
        departed client's queued ``#mvs`` would make the robot move again after its ``#stop!``.
        """
        # The write lock first, as the writer takes it: a chunk it already took goes out
        # before ``data``, and nothing it has not taken goes out at all.
        with self._write_lock:
            with self._lock:
                discarded = sum(len(chunk) for _, chunk in self._down_delay.chunks)
                self._down_delay.chunks.clear()
            if discarded:
                logger.info(
                    "%s: %d delayed bytes to the controller discarded", self.name, discarded
                )
            self._inner.write(data)

    # -- internals ---------------------------------------------------------------------------

    def _flush_delayed(self) -> None:
        """Write every chunk still waiting for its delay to the inner link, in order."""
        with self._write_lock:
            with self._lock:
                pending = b"".join(chunk for _, chunk in self._down_delay.chunks)
                self._down_delay.chunks.clear()
            if not pending or self._lost is not None:
                return
            try:
                self._inner.write(pending)
            except ConnectionLostError:
                logger.warning(
                    "%s: %d delayed bytes to the controller could not be sent: the link is lost",
                    self.name,
                    len(pending),
                )

    def _take(self, now: float, size: int) -> bytes:
        chunks = self._up_delay.chunks
        out = bytearray()
        while chunks and chunks[0][0] <= now and len(out) < size:
            due, data = chunks.popleft()
            room = size - len(out)
            out += data[:room]
            if len(data) > room:
                chunks.appendleft((due, data[room:]))
        return bytes(out)

    def _lost_text(self, error: ConnectionLostError) -> str:
        """Why the inner link was lost, without its name where this port's already gives it
        (``fault proxy to tcp …: closed by the other end``, not the link named twice)."""
        text = str(error)
        prefix = f"{self._inner.description}: "
        if self._inner.description in self.name and text.startswith(prefix):
            return text[len(prefix) :]
        return text

    def _check(self) -> None:
        if not self._open:
            raise ConnectionLostError(f"{self.name}: closed")
        if self._lost is not None:
            raise ConnectionLostError(f"{self.name}: {self._lost}")

    def _read_loop(self) -> None:
        inner = self._inner
        while self._open:
            try:
                data = inner.read_available(_READ_WAIT_S)
            except ConnectionLostError as error:
                with self._lock:
                    self._lost = self._lost_text(error)
                    self._lock.notify_all()
                return
            if not data:
                continue
            with self._lock:
                damaged = self._up.apply(data)
                if damaged:
                    self._up_delay.push(damaged, time.monotonic(), self._up.counters)
                    self._lock.notify_all()

    def _write_loop(self) -> None:
        while True:
            with self._lock:
                while self._open:
                    now = time.monotonic()
                    due = self._down_delay.next_due_s()
                    if due is not None and due <= now:
                        break
                    self._lock.wait(None if due is None else max(due - now, 0.0))
                else:
                    return
            try:
                # Taken under the write lock, so that send_clean() can discard it until then.
                with self._write_lock:
                    with self._lock:
                        data = self._down_delay.pop_due(time.monotonic())
                    if data:
                        self._inner.write(data)
            except ConnectionLostError as error:
                with self._lock:
                    self._lost = self._lost_text(error)
                    self._lock.notify_all()
                return


def _child(seeds: random.Random) -> random.Random:
    return random.Random(seeds.getrandbits(64))
