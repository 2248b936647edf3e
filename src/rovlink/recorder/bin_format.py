"""``.bin``: the raw wire only, both directions in the order they happened, nothing added.

What a logic analyser or ``socat`` would capture, and what ``rovlink decode`` reads. It has no
timestamps and no directions: the other formats keep those.
"""

from __future__ import annotations

from collections.abc import Iterator

from rovlink.recorder.entries import Entry, WireEntry
from rovlink.recorder.sink import FileSink, open_recording

__all__ = ["RawWireSink", "read_bin"]

_READ_BYTES = 1 << 16


class RawWireSink(FileSink):
    """Writes the wire entries' bytes and nothing else."""

    unit = "bytes"

    def write(self, entry: Entry) -> None:
        if isinstance(entry, WireEntry):
            self._file.write(entry.data)
            self._written += len(entry.data)


def read_bin(path: str) -> Iterator[Entry]:
    """A raw capture as wire entries (direction ``in``: a capture does not say; times 0)."""
    stream = open_recording(path)
    with stream:
        while chunk := stream.read(_READ_BYTES):
            yield WireEntry(0.0, 0, "in", chunk)
