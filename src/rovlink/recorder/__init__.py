"""The flight recorder: every byte, frame, event and telemetry row of a session, to a file.

Example::

    from rovlink.recorder import Recorder, read_entries

    with Recorder("dive.mcap", url="sim://") as recorder:
        with rovlink.connect("sim://", on_event=recorder.on_event) as rov:
            rov.depth_cm()
    entries = list(read_entries("dive.mcap"))

Formats by suffix (:mod:`rovlink.recorder.formats`), the entries of each channel
(:mod:`rovlink.recorder.entries`), reading back with :func:`read_entries`.
"""

from rovlink.recorder.entries import (
    TELEMETRY_FIELDS,
    Entry,
    EventEntry,
    FrameEntry,
    HeaderEntry,
    TelemetryEntry,
    WireEntry,
)
from rovlink.recorder.formats import FORMATS, format_of, read_entries
from rovlink.recorder.recorder import Recorder, rotated_path
from rovlink.recorder.sink import RecordingDamagedError, RecordingError

__all__ = [
    "FORMATS",
    "TELEMETRY_FIELDS",
    "Entry",
    "EventEntry",
    "FrameEntry",
    "HeaderEntry",
    "Recorder",
    "RecordingDamagedError",
    "RecordingError",
    "TelemetryEntry",
    "WireEntry",
    "format_of",
    "read_entries",
    "rotated_path",
]
