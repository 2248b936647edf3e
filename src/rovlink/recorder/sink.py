"""What every recording format provides: a sink to write entries and a reader to read them back.

A format is chosen by the file's suffix (:mod:`rovlink.recorder.formats`), as python-can chooses
its loggers. A sink writes entries in the order given; :meth:`Sink.flush` makes everything
written so far durable (on disk, through a power cut), which the recorder does every second.
A reader yields the entries it can read and ends with :class:`RecordingDamagedError` if the file is
cut short or damaged, after everything readable before the damage.
"""

from __future__ import annotations

import io
import os
import stat
from typing import BinaryIO, Protocol

from rovlink.recorder.entries import Entry

__all__ = ["FileSink", "RecordingDamagedError", "RecordingError", "Sink", "open_recording"]


class RecordingError(Exception):
    """A recording that cannot be read at all: missing, unreadable, or not a recording."""


def open_recording(path: str) -> io.BufferedReader:
    """``path`` opened for a reader, or a :class:`RecordingError` naming it and why not.

    >>> open_recording("/nonexistent/dive.jsonl")
    Traceback (most recent call last):
    ...
    rovlink.recorder.sink.RecordingError: /nonexistent/dive.jsonl: No such file or directory
    """
    try:
        return open(path, "rb")
    except OSError as error:
        raise RecordingError(f"{path}: {error.strerror}") from None


class RecordingDamagedError(RecordingError):
    """A recording readable up to a point: ``entries_read`` entries came before the damage.

    ``incomplete`` is true when the file merely ends early (its recorder was killed or lost
    power) rather than holding bytes that are not a recording.
    """

    def __init__(self, message: str, *, entries_read: int, incomplete: bool) -> None:
        super().__init__(message)
        self.entries_read = entries_read
        self.incomplete = incomplete

    @classmethod
    def empty(cls, path: str) -> RecordingDamagedError:
        """An empty file of a recording's format: a recorder killed before its first second
        was written (a recording that ends early, as any other)."""
        return cls(
            f"{path}: empty: its recorder was stopped before its first second was written; "
            "read 0 entries",
            entries_read=0,
            incomplete=True,
        )


class Sink(Protocol):
    """Where a recorder writes entries."""

    #: What the file holds, in the format's own terms: ``messages``, ``lines``, ``rows``,
    #: ``bytes``.
    unit: str

    def write(self, entry: Entry) -> None:
        """Add one entry."""

    def flush(self) -> None:
        """Make everything written so far durable."""

    def close(self) -> None:
        """Finish the file (its index and summary, where the format has them)."""

    def size_bytes(self) -> int:
        """The file's size so far (after the last flush)."""

    def held(self) -> int:
        """How many :attr:`unit` the file holds for sure: those written before the last
        :meth:`flush` (or :meth:`close`) that succeeded."""


class FileSink:
    """The file handling every format shares: open, durable flush, size, close.

    A format's :meth:`write` adds what it wrote, in its :attr:`unit`, to :attr:`_written`.
    """

    unit = "entries"

    def __init__(self, path: str) -> None:
        self.path = path
        self._file: BinaryIO = open(path, "wb")  # noqa: SIM115 - closed by close()
        # A pipe to another program (a FIFO) has no disk to sync to: it refuses fsync (EINVAL),
        # and the recording stopped at its first flush.
        self._on_disk = not stat.S_ISFIFO(os.fstat(self._file.fileno()).st_mode)
        self._written = 0
        self._durable = 0

    def flush(self) -> None:
        """Write the buffers out and ask the system to put them on the disk."""
        written = self._written
        self._file.flush()
        if self._on_disk:
            os.fsync(self._file.fileno())
        self._durable = written

    def held(self) -> int:
        return self._durable

    def size_bytes(self) -> int:
        # (A pipe has no position, and nothing it held stays to be counted: never too big.)
        return self._file.tell() if self._on_disk else 0

    def close(self) -> None:
        if not self._file.closed:
            try:
                self.flush()
            finally:
                self._file.close()
