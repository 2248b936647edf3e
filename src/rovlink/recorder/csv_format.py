"""``.csv``: the telemetry table, one row per change, with both clocks.

``pandas.read_csv(path)`` reads it with no options: a header line, ``t_s`` (monotonic seconds),
``wall_time`` (ISO 8601, UTC), then one column per :data:`TELEMETRY_FIELDS`, empty where not
known yet, and ``event``. A file its recorder closed ends with a closing row, whose ``event`` is
``recording_end`` (the other rows leave it empty): the time the recording ended and the values
held until then. A file without it was cut short (its recorder killed between two rows). Files
written before the ``event`` column (:data:`UNENDED_HEADER`) have no closing row, and are read
as before.
"""

from __future__ import annotations

import csv
import io
import time
from collections.abc import Iterator, Mapping
from datetime import datetime, timezone
from typing import BinaryIO

from rovlink.recorder.entries import (
    TELEMETRY_FIELDS,
    Entry,
    EventEntry,
    TelemetryEntry,
    check_telemetry_range,
)
from rovlink.recorder.sink import FileSink, RecordingDamagedError, RecordingError, open_recording

__all__ = ["END_EVENT", "HEADER", "UNENDED_HEADER", "TelemetryCsvSink", "read_csv"]

#: The ``event`` of the row that ends a file its recorder closed (as ``.jsonl``'s last line).
END_EVENT = "recording_end"
#: The CSV's columns.
HEADER = ("t_s", "wall_time", *TELEMETRY_FIELDS, "event")
#: The columns of files written before the closing row: nothing says whether one was cut.
UNENDED_HEADER = HEADER[:-1]


def _wall_time(wall_ns: int) -> str:
    return datetime.fromtimestamp(wall_ns / 1e9, tz=timezone.utc).isoformat(timespec="microseconds")


class TelemetryCsvSink(FileSink):
    """Writes the telemetry entries as CSV rows (the header line not counted)."""

    unit = "rows"

    def __init__(self, path: str) -> None:
        super().__init__(path)
        self._text = io.TextIOWrapper(self._file, encoding="utf-8", newline="")
        self._writer = csv.writer(self._text, lineterminator="\n")
        self._writer.writerow(HEADER)
        self._last_values: Mapping[str, int | None] = dict.fromkeys(TELEMETRY_FIELDS)
        self._last_clocks: tuple[float, int] | None = None
        self._failed = False  # (a file that lost rows is not ended as whole)

    def write(self, entry: Entry) -> None:
        # Every entry's clocks, not only telemetry's: the closing row says when it all ended.
        self._last_clocks = (entry.t_s, entry.wall_ns)
        if isinstance(entry, TelemetryEntry):
            self._write_row(entry.t_s, entry.wall_ns, entry.values, "")
            self._last_values = entry.values
            self._written += 1

    def _write_row(
        self, t_s: float, wall_ns: int, values: Mapping[str, int | None], event: str
    ) -> None:
        row = [
            f"{t_s:.6f}",
            _wall_time(wall_ns),
            *("" if values[name] is None else values[name] for name in TELEMETRY_FIELDS),
            event,
        ]
        try:
            self._writer.writerow(row)
        except BaseException:
            self._failed = True
            raise

    def flush(self) -> None:
        try:
            self._text.flush()
            super().flush()
        except BaseException:
            self._failed = True
            raise

    def size_bytes(self) -> int:
        self._text.flush()
        return super().size_bytes()

    def close(self) -> None:
        """End the file with its closing row (not counted as a row of the session), unless
        writing failed before, and close it."""
        if not self._file.closed:
            try:
                if not self._failed:
                    t_s, wall_ns = self._last_clocks or (time.monotonic(), time.time_ns())
                    self._write_row(t_s, wall_ns, self._last_values, END_EVENT)
                self.flush()
            finally:  # closed even when the disk is full
                self._text.close()


def read_csv(path: str) -> Iterator[Entry]:
    """The telemetry rows of a ``.csv`` recording, then (a file its recorder closed) its
    closing row's time as a :data:`END_EVENT` event: when the recording ended.

    Each line is decoded on its own: a byte that is not UTF-8 damages its row alone, and the
    rows before it are read (a text stream decodes thousands of bytes at once, and failed on
    the first row when the damage lay anywhere in the first of them).
    """
    stream = open_recording(path)
    count = 0
    with stream:
        lines = _TextLines(stream)
        rows = csv.reader(lines)
        try:
            header = next(rows, None)
        except _NotTextError:
            raise RecordingError(
                f"{path}: not UTF-8 text, so not a rovlink telemetry CSV"
            ) from None
        if header is None:  # (an empty file: its recorder killed before its first flush)
            raise RecordingDamagedError.empty(path)
        if not lines.last_complete and ",".join(HEADER).startswith(",".join(header)):
            raise RecordingDamagedError(
                f"{path}: ends in its header line (the recording was cut short); read 0 rows",
                entries_read=0,
                incomplete=True,
            )
        if header not in (list(HEADER), list(UNENDED_HEADER)):
            raise RecordingError(f"{path}: not a rovlink telemetry CSV (its header differs)")
        columns = len(header)
        ends_with_its_row = columns == len(HEADER)
        ended = False
        while True:
            try:
                row = next(rows, None)
            except _NotTextError as error:
                raise RecordingDamagedError(
                    f"{path}: row {error.line_number} is damaged (not UTF-8 text); "
                    f"read {count} rows before it",
                    entries_read=count,
                    incomplete=False,
                ) from None
            if row is None:
                break
            try:
                if not lines.last_complete:
                    # The recorder ends every row with its newline: a row without one was cut
                    # short, even where what is left parses (30 cut to 3 in the last column).
                    raise ValueError("no newline at its end")
                if len(row) != columns:
                    raise ValueError(f"{len(row)} columns, not {columns}")
                if ended:
                    raise ValueError(f"a row after the closing row ({END_EVENT})")
                event = row[-1] if ends_with_its_row else ""
                if event not in ("", END_EVENT):
                    raise ValueError(f"unknown event {event!r}")
                wall = datetime.fromisoformat(row[1])
                values = {
                    name: int(text) if text else None
                    for name, text in zip(
                        TELEMETRY_FIELDS, row[2 : 2 + len(TELEMETRY_FIELDS)], strict=True
                    )
                }
                for name, value in values.items():
                    check_telemetry_range(name, value)
                entry = TelemetryEntry(float(row[0]), int(wall.timestamp() * 1e9), values)
            except ValueError as error:  # (an EntryError too: a value out of its range)
                # Cut short: the last row, without its newline; else damaged (status 1).
                cut = not lines.last_complete
                raise RecordingDamagedError(
                    f"{path}: row {rows.line_num} is {'cut short' if cut else 'damaged'} "
                    f"({error}); read {count} rows before it",
                    entries_read=count,
                    incomplete=cut,
                ) from None
            if event == END_EVENT:
                ended = True
                # When the recording ended, which only this row says in a table of changes:
                # without it a dive's last minutes at one depth were plotted as none.
                yield EventEntry(entry.t_s, entry.wall_ns, END_EVENT, "recording", "closed")
                continue
            count += 1
            yield entry
    if ends_with_its_row and not ended:
        raise RecordingDamagedError(
            f"{path}: the recording ends early, without its closing row (its recorder was "
            f"stopped abruptly); read {count} rows",
            entries_read=count,
            incomplete=True,
        )


class _NotTextError(Exception):
    """A line of the file that is not UTF-8 text (its number counts from 1)."""

    def __init__(self, line_number: int) -> None:
        super().__init__(line_number)
        self.line_number = line_number


class _TextLines:
    """The lines of a binary stream, each decoded alone (:class:`_NotTextError` at one that is
    not UTF-8); :attr:`last_complete` says whether the last line given ended with its newline
    (a recorder stopped abruptly leaves its last row without one)."""

    def __init__(self, stream: BinaryIO) -> None:
        self._numbered = enumerate(stream, start=1)
        self.last_complete = True

    def __iter__(self) -> Iterator[str]:
        return self

    def __next__(self) -> str:
        number, line = next(self._numbered)
        self.last_complete = line.endswith(b"\n")
        try:
            return line.decode("utf-8")
        except UnicodeDecodeError:
            raise _NotTextError(number) from None
