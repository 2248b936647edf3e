"""Recording formats by file suffix, as python-can's loggers: ``.mcap`` (default), ``.jsonl``,
``.csv`` (the telemetry table), ``.bin`` (the raw wire).

Each format's module loads only when a file of its kind is written or read (``mcap`` is a
third-party library).

>>> format_of("dive.csv").description
'telemetry table (CSV)'
>>> format_of("dive.txt")
Traceback (most recent call last):
...
ValueError: dive.txt: unknown recording format '.txt'; use .mcap, .jsonl, .csv or .bin
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Iterator
from dataclasses import dataclass
from typing import cast

import rovlink
from rovlink.recorder.entries import FORMAT_VERSION, Entry, HeaderEntry
from rovlink.recorder.sink import RecordingError, Sink

__all__ = ["FORMATS", "Format", "MissingLibraryError", "format_of", "open_sink", "read_entries"]


@dataclass(frozen=True)
class Format:
    """A recording format: its module, sink class and reader function."""

    suffix: str
    description: str
    module: str
    sink: str
    reader: str


#: The formats, by suffix.
FORMATS: dict[str, Format] = {
    ".mcap": Format(
        ".mcap", "MCAP (Foxglove)", "rovlink.recorder.mcap_format", "McapSink", "read_mcap"
    ),
    ".jsonl": Format(
        ".jsonl",
        "JSON lines",
        "rovlink.recorder.jsonl_format",
        "JsonLinesSink",
        "read_jsonl",
    ),
    ".csv": Format(
        ".csv",
        "telemetry table (CSV)",
        "rovlink.recorder.csv_format",
        "TelemetryCsvSink",
        "read_csv",
    ),
    ".bin": Format(
        ".bin", "raw wire bytes", "rovlink.recorder.bin_format", "RawWireSink", "read_bin"
    ),
}


def format_of(path: str) -> Format:
    """The format of ``path`` by its suffix; ValueError naming the path if unknown."""
    suffix = os.path.splitext(path)[1].lower()
    found = FORMATS.get(suffix)
    if found is None:
        known = ", ".join(FORMATS)
        known = known[: known.rfind(", ")] + " or" + known[known.rfind(",") + 1 :]
        if not suffix:  # ("unknown recording format ''" named nothing a user typed)
            raise ValueError(f"{path}: no suffix to choose the recording format by; use {known}")
        raise ValueError(f"{path}: unknown recording format {suffix!r}; use {known}")
    return found


class MissingLibraryError(RecordingError):
    """A format whose library is not installed (``.mcap`` needs the ``record`` extra)."""


def _module(kind: Format) -> object:
    try:
        return importlib.import_module(kind.module)
    except ModuleNotFoundError as error:
        raise MissingLibraryError(
            f"{kind.suffix} recordings need the {error.name} library: pip install 'rovlink[record]'"
        ) from None


def open_sink(path: str) -> Sink:
    """A sink writing ``path`` in the format of its suffix (OSError if it cannot be created,
    :class:`MissingLibraryError` if its library is not installed)."""
    kind = format_of(path)
    sink_class = getattr(_module(kind), kind.sink)
    return cast(Sink, sink_class(path))


def read_entries(path: str) -> Iterator[Entry]:
    """The entries of the recording at ``path`` (:class:`RecordingError` if none can be read;
    ends with :class:`~rovlink.recorder.sink.RecordingDamagedError` at damage)."""
    try:
        kind = format_of(path)
    except ValueError as error:
        raise RecordingError(str(error)) from None
    if os.path.isdir(path):
        raise RecordingError(f"{path}: is a directory")
    reader = getattr(_module(kind), kind.reader)
    return _refusing_newer(path, cast(Iterator[Entry], reader(path)))


def _refusing_newer(path: str, entries: Iterator[Entry]) -> Iterator[Entry]:
    """``entries``, refused at a header of a newer format version than this rovlink reads: its
    fields may mean something else, and a replay or a plot of them would mislead."""
    for entry in entries:
        if isinstance(entry, HeaderEntry) and entry.format_version > FORMAT_VERSION:
            raise RecordingError(
                f"{path}: recorded by {entry.program} {entry.version} in format version "
                f"{entry.format_version}; rovlink {rovlink.__version__} reads versions up to "
                f"{FORMAT_VERSION}: upgrade rovlink to read it"
            )
        yield entry
