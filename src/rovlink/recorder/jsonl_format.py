"""``.jsonl``: one JSON object per line per entry, ``channel`` naming its kind.

Text that any tool reads (``jq``, pandas' ``read_json(lines=True)``); a file cut short loses at
most its last, unfinished line. A file its recorder closed ends with a ``recording_end`` event
(format 3): text has no index to be missing, and a file cut between two lines, by a recorder
killed as it flushed, would read as a whole recording.
"""

from __future__ import annotations

import json
from collections.abc import Iterator

from rovlink.recorder.entries import (
    Entry,
    EntryError,
    EventEntry,
    HeaderEntry,
    entry_from_json,
)
from rovlink.recorder.sink import FileSink, RecordingDamagedError, RecordingError, open_recording

__all__ = ["END_EVENT", "JsonLinesSink", "read_jsonl"]

#: The event that ends a file its recorder closed; the reader takes it, and does not yield it.
END_EVENT = "recording_end"
#: The first format version whose closed files end with :data:`END_EVENT`.
_ENDED_SINCE_VERSION = 3


class JsonLinesSink(FileSink):
    """Writes entries as JSON lines."""

    unit = "lines"

    def __init__(self, path: str) -> None:
        super().__init__(path)
        self._last_clocks: tuple[float, int] | None = None
        self._failed = False  # (a file that lost lines is not ended as whole)

    def write(self, entry: Entry) -> None:
        self._write_line(entry)
        self._written += 1
        self._last_clocks = (entry.t_s, entry.wall_ns)

    def _write_line(self, entry: Entry) -> None:
        line = json.dumps({"channel": entry.channel, **entry.to_json()}, separators=(",", ":"))
        try:
            self._file.write(line.encode() + b"\n")
        except BaseException:
            self._failed = True
            raise

    def flush(self) -> None:
        try:
            super().flush()
        except BaseException:
            self._failed = True
            raise

    def close(self) -> None:
        """End the file with its :data:`END_EVENT` (not counted as a line of the session),
        unless writing it failed before, and close it."""
        if not self._file.closed and not self._failed and self._last_clocks is not None:
            t_s, wall_ns = self._last_clocks
            self._write_line(EventEntry(t_s, wall_ns, END_EVENT, "recording", "closed"))
        super().close()


def read_jsonl(path: str) -> Iterator[Entry]:
    """The entries of a ``.jsonl`` recording."""
    stream = open_recording(path)
    count = 0
    version: int | None = None
    ended = False
    with stream:
        for number, line in enumerate(stream, start=1):
            complete = line.endswith(b"\n")
            try:
                data = json.loads(line)
                if not isinstance(data, dict) or not isinstance(data.get("channel"), str):
                    raise EntryError("not an object with a channel")
                entry = entry_from_json(data["channel"], data)
            except (ValueError, EntryError) as error:
                if number == 1:
                    raise RecordingError(f"{path}: not a rovlink JSON-lines recording") from None
                if not complete:
                    raise RecordingDamagedError(
                        f"{path}: ends in the middle of line {number} (the recording was cut "
                        f"short); read {count} entries before it",
                        entries_read=count,
                        incomplete=True,
                    ) from None
                raise RecordingDamagedError(
                    f"{path}: line {number} is damaged ({error}); read {count} entries before it",
                    entries_read=count,
                    incomplete=False,
                ) from None
            if isinstance(entry, HeaderEntry) and version is None:
                version = entry.format_version
            ended = isinstance(entry, EventEntry) and entry.event == END_EVENT
            if ended:
                continue
            count += 1
            yield entry
    if count == 0:  # (an empty file: nothing of it was written, as an empty .mcap)
        raise RecordingDamagedError.empty(path)
    if not ended and version is not None and version >= _ENDED_SINCE_VERSION:
        raise RecordingDamagedError(
            f"{path}: the recording ends early, without its closing line (its recorder was "
            f"stopped abruptly); read {count} entries",
            entries_read=count,
            incomplete=True,
        )
