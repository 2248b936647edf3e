"""The recorder: takes a session's events on the link's thread at the cost of an append, and
writes them on its own thread, so that recording never slows or stops the robot's link.

>>> import rovlink, tempfile, os
>>> path = os.path.join(tempfile.mkdtemp(), "dive.jsonl")
>>> with Recorder(path, url="sim://") as recorder:
...     with rovlink.connect("sim://", on_event=recorder.on_event) as rov:
...         depth = rov.depth_cm()
>>> recorder.entries_written > 0, recorder.dropped
(True, 0)
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType

import rovlink
from rovlink.client.events import ClientEvent, LinkState
from rovlink.recorder.entries import Entry, HeaderEntry
from rovlink.recorder.formats import format_of, open_sink
from rovlink.recorder.link_decoding import DEFAULT_REPLY_TIMEOUT_S
from rovlink.recorder.sink import Sink
from rovlink.recorder.translate import ClientEventLog, TapLog

__all__ = ["DEFAULT_QUEUE_LIMIT", "Recorder", "TappedBytes", "rotated_path"]

logger = logging.getLogger(__name__)

#: Items the link may hand over before the writer takes them; beyond it items are counted as
#: dropped rather than stall the link. A saturated 1 Mbaud line fills a tenth of it per second.
DEFAULT_QUEUE_LIMIT = 100_000
#: How often the writer takes what the link handed over.
_DRAIN_INTERVAL_S = 0.05
#: How often the file is made durable: a power cut loses at most this much.
FLUSH_INTERVAL_S = 1.0


@dataclass(frozen=True, slots=True)
class TappedBytes:
    """Bytes seen by a tap or a sniffer going ``direction`` (``out``: to the controller)."""

    at_s: float
    direction: str
    data: bytes
    #: Written by the tap itself (its ``#stop!`` when a program leaves), not by the program.
    by_session: bool = False


def rotated_path(path: str, index: int) -> str:
    """The name of the ``index``-th file of a rotated recording (0: ``path`` itself).

    >>> rotated_path("dives/dive.mcap", 0), rotated_path("dives/dive.mcap", 2)
    ('dives/dive.mcap', 'dives/dive.002.mcap')
    """
    if index == 0:
        return path
    stem, suffix = os.path.splitext(path)
    return f"{stem}.{index:03d}{suffix}"


class Recorder:
    """Records a session to ``path`` (format by suffix: ``.mcap``, ``.jsonl``, ``.csv``,
    ``.bin``).

    Give :meth:`on_event` to the driver as its event hook (``on_event=`` or ``subscribe``), or
    feed :meth:`on_bytes` from a tap. ``max_size_bytes`` and ``split_s`` start a new file
    (``dive.001.mcap``, ...) when the current one reaches that size or age. If the file cannot
    be written (disk full, permission), the recording stops, ``error`` says why and
    ``on_failure`` is called with it (without one, it is logged at ERROR); the link is never
    affected.

    ``checksum`` is the mode the link is in as the recording starts, which its header says:
    off for a driver about to connect (its connect probe and mode frame go plain; a
    ``--checksum`` driver's ``#crcon!`` is recorded as it switches), the link's mode for a tap
    or a sniffer joining it. ``reply_timeout_s``: how long the program behind a tap waits for a
    reply; a reply after that is recorded as late, not matched to a later query (P20).

    The file is created when the recorder is made, so a path that cannot be written is an
    ``OSError`` at once.
    """

    def __init__(
        self,
        path: str,
        *,
        url: str = "",
        checksum: bool = False,
        algorithm: str = "crc8",
        program: str = "rovlink",
        max_size_bytes: int | None = None,
        split_s: float | None = None,
        queue_limit: int = DEFAULT_QUEUE_LIMIT,
        on_failure: Callable[[str], None] | None = None,
        reply_timeout_s: float = DEFAULT_REPLY_TIMEOUT_S,
    ) -> None:
        format_of(path)  # an unknown suffix is refused before anything is created
        self.path = path
        #: Every file written so far, in order.
        self.paths: list[str] = [path]
        #: Entries written to the files.
        self.entries_written = 0
        #: What the files hold for sure, in :attr:`held_unit` (see :meth:`held`).
        self._held_before = 0
        #: Items not recorded because the writer fell behind by ``queue_limit``.
        self.dropped = 0
        #: Why the recording stopped early, if it did.
        self.error: str | None = None
        self._header = (url, checksum, algorithm, program)
        self._max_size_bytes = max_size_bytes
        self._split_s = split_s
        self._queue_limit = queue_limit
        self._on_failure = on_failure
        self._queue: deque[ClientEvent | TappedBytes] = deque()
        self._accepting = True
        self._events = ClientEventLog(checksum=checksum)
        self._tap = TapLog(checksum=checksum, algorithm=algorithm, reply_timeout_s=reply_timeout_s)
        self._tapped = False  # fed by a tap (on_bytes) rather than the driver's events
        self._sink: Sink | None = open_sink(path)
        #: The format's own unit of what its files hold: ``messages``, ``lines``, ``rows``,
        #: ``bytes``.
        self.held_unit = self._sink.unit
        self._file_started_s = time.monotonic()
        self._write_header()
        self._stopping = threading.Event()
        # Wakes the writer for :meth:`sync`, and its caller once it is done.
        self._sync_changed = threading.Condition()
        self._syncs_asked = 0
        self._syncs_done = 0
        self._thread = threading.Thread(target=self._run, name="rovlink-recorder", daemon=True)
        self._thread.start()

    # -- on the link's thread: an append, nothing else ---------------------------------------

    def on_event(self, event: ClientEvent) -> None:
        """The driver's event hook: hand ``event`` to the writer."""
        if self._accepting:
            queue = self._queue
            if len(queue) < self._queue_limit:
                queue.append(event)
            else:
                self.dropped += 1

    def on_bytes(
        self, direction: str, data: bytes, at_s: float | None = None, *, by_session: bool = False
    ) -> None:
        """Bytes seen by a tap going ``direction`` (``out``: host to controller), at ``at_s``
        on :func:`time.monotonic` (default: now); ``by_session``: written by the tap itself."""
        if self._accepting:
            queue = self._queue
            if len(queue) < self._queue_limit:
                now_s = time.monotonic() if at_s is None else at_s
                queue.append(TappedBytes(now_s, direction, data, by_session))
            else:
                self.dropped += 1

    def held(self) -> int:
        """What the files hold, in the format's own :attr:`held_unit` (an MCAP file's
        messages, a CSV's rows, a raw capture's bytes): everything, once closed; after a
        failure, only what a flush made durable before it."""
        sink = self._sink
        return self._held_before + (sink.held() if sink is not None else 0)

    def sync(self, timeout_s: float = 5.0) -> str | None:
        """Write and make durable everything handed over so far, and return :attr:`error`:
        whether the recording holds the session up to now. A command checks it before it ends,
        while it can still stop the robot (a failure may show only as the file is flushed).
        Waits at most ``timeout_s`` for a disk that does not answer (``None`` back then, as the
        recording has not failed yet)."""
        with self._sync_changed:
            self._syncs_asked += 1
            asked = self._syncs_asked
            self._sync_changed.notify_all()
            self._sync_changed.wait_for(
                lambda: self._syncs_done >= asked or not self._thread.is_alive(), timeout_s
            )
        return self.error

    # -- ending ------------------------------------------------------------------------------

    def close(self) -> None:
        """Write what is left, finish the file (its index) and stop the writer."""
        with self._sync_changed:
            self._stopping.set()
            self._sync_changed.notify_all()
        self._thread.join()
        self._accepting = False

    def __enter__(self) -> Recorder:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    # -- the writer's thread -----------------------------------------------------------------

    def _run(self) -> None:
        last_flush_s = time.monotonic()
        try:
            while True:
                with self._sync_changed:
                    self._sync_changed.wait_for(
                        lambda: self._stopping.is_set() or self._syncs_asked > self._syncs_done,
                        _DRAIN_INTERVAL_S,
                    )
                    asked = self._syncs_asked
                if self._stopping.is_set():
                    break
                self._drain()
                now_s = time.monotonic()
                if now_s - last_flush_s >= FLUSH_INTERVAL_S or asked > self._syncs_done:
                    last_flush_s = now_s
                    self._flush_or_rotate(now_s)
                self._synced(asked)
            self._drain()
            if self._sink is not None:
                self._close_sink(self._sink)
        except OSError as error:
            self._fail(error.strerror or str(error))
        except Exception:  # a bug in the writer must stop the recording, never the link
            logger.exception("the recorder's writer failed")
            self._fail("the recorder failed (logged)")
        finally:
            self._synced(None)  # (nothing more will be written)

    def _synced(self, asked: int | None) -> None:
        """What :meth:`sync` asked up to ``asked`` (``None``: all) is done: wake its callers."""
        with self._sync_changed:
            if asked is None:
                asked = self._syncs_asked
            if asked > self._syncs_done:
                self._syncs_done = asked
                self._sync_changed.notify_all()

    def _drain(self) -> None:
        queue = self._queue
        sink = self._sink
        if sink is None:
            queue.clear()
            return
        events, tap = self._events, self._tap
        written = 0
        # Items carry the driver's monotonic time (``time.monotonic``, which the loop's clock
        # is too); the wall clock is that plus the clocks' offset, read here rather than per
        # item on the link's thread. Items wait at most a drain interval, so an adjustment of
        # the wall clock shifts them by no more than it shifts everything else.
        offset_ns = time.time_ns() - time.monotonic_ns()
        # What is there now, not until the queue is empty: a link that fills it as fast as it
        # drains must not keep the file from being flushed and rotated.
        for _ in range(len(queue)):
            item = queue.popleft()
            wall_ns = int(item.at_s * 1e9) + offset_ns
            if isinstance(item, TappedBytes):
                self._tapped = True
                entries = tap.entries(
                    item.at_s, wall_ns, item.direction, item.data, item.by_session
                )
            else:
                if isinstance(item, LinkState) and self._tapped:  # (a tap's link lost)
                    tap.link_changed()
                entries = events.entries(wall_ns, item)
            for entry in entries:
                sink.write(entry)
            written += len(entries)
        self.entries_written += written

    def _flush_or_rotate(self, now_s: float) -> None:
        sink = self._sink
        if sink is None:
            return
        sink.flush()
        too_big = self._max_size_bytes is not None and sink.size_bytes() >= self._max_size_bytes
        too_old = self._split_s is not None and now_s - self._file_started_s >= self._split_s
        if too_big or too_old:
            self._close_sink(sink)
            path = rotated_path(self.path, len(self.paths))
            self._sink = open_sink(path)
            self.paths.append(path)
            self._file_started_s = now_s
            self._write_header()
            logger.info("recording continues in %s", path)

    def _close_sink(self, sink: Sink) -> None:
        """Close the current file; what it holds is counted in :meth:`held` (a close that
        raises leaves it current, for :meth:`_fail`)."""
        sink.close()
        self._held_before += sink.held()
        self._sink = None

    def _write_header(self) -> None:
        url, _, algorithm, program = self._header
        # The mode in force as this file starts (a file of a rotation is read on its own).
        checksum = (self._tap if self._tapped else self._events).log.checksum
        entry: Entry = HeaderEntry(
            time.monotonic(),
            time.time_ns(),
            url,
            checksum,
            algorithm,
            program,
            rovlink.__version__,
        )
        assert self._sink is not None
        self._sink.write(entry)
        self.entries_written += 1

    def _fail(self, reason: str) -> None:
        self._accepting = False
        self._queue.clear()
        where = self.paths[-1]
        self.error = f"recording to {where} stopped: {reason}"
        if self._on_failure is None:  # (else reported once, by whoever asked to be told)
            logger.error("%s (the link goes on)", self.error)
        sink = self._sink
        if sink is not None:
            with contextlib.suppress(Exception):  # the file is as good as the disk let it be
                self._close_sink(sink)
            self._held_before += sink.held() if self._sink is not None else 0
            self._sink = None
        if self._on_failure is not None:
            self._on_failure(self.error)
