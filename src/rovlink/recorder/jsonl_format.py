"""``.jsonl``: one JSON object per line per entry, ``channel`` naming its kind.

Text that any tool reads (``jq``, pandas' ``read_json(lines=True)``); a file cut short loses at
most its last, unfinished line.
"""

from __future__ import annotations

import json
from collections.abc import Iterator

from rovlink.recorder.entries import Entry, EntryError, entry_from_json
from rovlink.recorder.sink import FileSink, RecordingDamagedError, RecordingError

__all__ = ["JsonLinesSink", "read_jsonl"]


class JsonLinesSink(FileSink):
    """Writes entries as JSON lines."""

    unit = "lines"

    def write(self, entry: Entry) -> None:
        line = json.dumps({"channel": entry.channel, **entry.to_json()}, separators=(",", ":"))
        self._file.write(line.encode() + b"\n")
        self._written += 1


def read_jsonl(path: str) -> Iterator[Entry]:
    """The entries of a ``.jsonl`` recording."""
    try:
        stream = open(path, "rb")  # noqa: SIM115 - closed by the with below
    except OSError as error:
        raise RecordingError(f"{path}: {error.strerror}") from None
    count = 0
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
            count += 1
            yield entry
    if count == 0:  # (an empty file: nothing of it was written, as an empty .mcap)
        raise RecordingDamagedError.empty(path)
