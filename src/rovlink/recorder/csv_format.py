"""``.csv``: the telemetry table, one row per change, with both clocks.

``pandas.read_csv(path)`` reads it with no options: a header line, ``t_s`` (monotonic seconds),
``wall_time`` (ISO 8601, UTC), then one column per :data:`TELEMETRY_FIELDS`, empty where not
known yet.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from datetime import datetime, timezone

from rovlink.recorder.entries import TELEMETRY_FIELDS, Entry, TelemetryEntry
from rovlink.recorder.sink import FileSink, RecordingDamagedError, RecordingError

__all__ = ["HEADER", "TelemetryCsvSink", "read_csv"]

#: The CSV's columns.
HEADER = ("t_s", "wall_time", *TELEMETRY_FIELDS)


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

    def write(self, entry: Entry) -> None:
        if isinstance(entry, TelemetryEntry):
            values = entry.values
            self._writer.writerow(
                [
                    f"{entry.t_s:.6f}",
                    _wall_time(entry.wall_ns),
                    *("" if values[name] is None else values[name] for name in TELEMETRY_FIELDS),
                ]
            )
            self._written += 1

    def flush(self) -> None:
        self._text.flush()
        super().flush()

    def size_bytes(self) -> int:
        self._text.flush()
        return super().size_bytes()

    def close(self) -> None:
        if not self._file.closed:
            try:
                self.flush()
            finally:  # closed even when the disk is full
                self._text.close()


def read_csv(path: str) -> Iterator[Entry]:
    """The telemetry rows of a ``.csv`` recording."""
    try:
        stream = open(path, encoding="utf-8", newline="")  # noqa: SIM115 - closed below
    except OSError as error:
        raise RecordingError(f"{path}: {error.strerror}") from None
    count = 0
    with stream:
        rows = csv.reader(stream)
        try:
            header = next(rows, None)
        except UnicodeDecodeError:
            raise RecordingError(
                f"{path}: not UTF-8 text, so not a rovlink telemetry CSV"
            ) from None
        if header != list(HEADER):
            raise RecordingError(f"{path}: not a rovlink telemetry CSV (its header differs)")
        while True:
            try:
                row = next(rows, None)
            except UnicodeDecodeError:
                raise RecordingDamagedError(
                    f"{path}: not UTF-8 text after row {rows.line_num}; "
                    f"read {count} rows before it",
                    entries_read=count,
                    incomplete=False,
                ) from None
            if row is None:
                break
            try:
                if len(row) != len(HEADER):
                    raise ValueError(f"{len(row)} columns, not {len(HEADER)}")
                wall = datetime.fromisoformat(row[1])
                values = {
                    name: int(text) if text else None
                    for name, text in zip(TELEMETRY_FIELDS, row[2:], strict=True)
                }
                entry = TelemetryEntry(float(row[0]), int(wall.timestamp() * 1e9), values)
            except ValueError as error:
                raise RecordingDamagedError(
                    f"{path}: row {rows.line_num} is damaged or cut short ({error}); "
                    f"read {count} rows before it",
                    entries_read=count,
                    incomplete=True,
                ) from None
            count += 1
            yield entry
