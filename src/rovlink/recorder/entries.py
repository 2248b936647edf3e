"""What a recording holds: entries on four channels, each with both clocks.

A recording is a sequence of entries in the order they happened. Every entry carries ``t_s``,
the session's monotonic clock (seconds; differences between entries are exact and never jump),
and ``wall_ns``, the wall clock in nanoseconds since the Unix epoch (when it happened, for people
and for Foxglove's timeline). The channels:

- ``wire``: bytes exactly as on the wire, one chunk per write or read, with their direction;
- ``frames``: every decoded frame: commands sent, replies with the query they answered;
- ``events``: what the session noticed or decided (timeouts, bad frames, late replies,
  suspected resets, mode changes, lock state, a leak, the link's state, debug text);
- ``telemetry``: one row of the robot's state whenever a reply or a command changed it.

>>> entry = WireEntry(t_s=1.5, wall_ns=0, direction="out", data=b"#qd!")
>>> WireEntry.from_json(entry.to_json()) == entry
True
"""

from __future__ import annotations

import base64
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any, ClassVar

from rovlink.protocol import Command, Response

__all__ = [
    "CHANNELS",
    "TELEMETRY_FIELDS",
    "Entry",
    "EntryError",
    "EventEntry",
    "FrameEntry",
    "HeaderEntry",
    "TelemetryEntry",
    "WireEntry",
    "check_telemetry_range",
    "entry_from_json",
    "utc_text",
]

#: The recording format's version; a reader refuses a newer one. 2: a header's ``checksum`` is
#: the mode of the file's first frames in every recording; in 1, a driving command's recording
#: made with ``--checksum`` said on, the mode its driver asked for, though the connect probe
#: and the mode frame before it went plain (the mode frame says what was asked for, in both).
#: 3: a ``.jsonl`` file its recorder closed ends with a ``recording_end`` event (a file without
#: it was cut: its recorder was killed).
FORMAT_VERSION = 3


def utc_text(wall_ns: int) -> str | None:
    """An entry's ``wall_ns`` as people read it, in UTC to the second (``None`` for a time no
    calendar holds: a damaged one).

    >>> utc_text(1_795_806_432_000_000_000)
    '2026-11-27 19:07:12 UTC'
    >>> utc_text(10**30) is None
    True
    """
    try:
        return f"{datetime.fromtimestamp(wall_ns / 1e9, tz=timezone.utc):%Y-%m-%d %H:%M:%S} UTC"
    except (OverflowError, ValueError, OSError):
        return None


class EntryError(ValueError):
    """A stored entry that does not have the shape of its channel."""


_CLOCKS_SCHEMA: dict[str, Any] = {
    "t_s": {"type": "number", "description": "session monotonic clock, s"},
    "wall_ns": {"type": "integer", "description": "wall clock, ns since the Unix epoch"},
}


@dataclass(frozen=True, slots=True)
class HeaderEntry:
    """How the recording was made: the link, the checksum mode its first frames are in (as the
    file starts: each file of a rotation has its own; a driver's recording starts plain, and
    its ``#crcon!`` and ``mode_changed`` event say when that changes), the program and its
    version."""

    channel: ClassVar[str] = "header"
    t_s: float
    wall_ns: int
    url: str
    checksum: bool
    algorithm: str
    program: str
    version: str
    format_version: int = FORMAT_VERSION

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> HeaderEntry:
        return cls(**_fields(cls, data))


@dataclass(frozen=True, slots=True)
class WireEntry:
    """Bytes exactly as on the wire; ``by_session``: written by the driver itself (keep-alive,
    fence, mode frame, expired motion), not by the program (a retry is the query again, after
    its ``query_failed`` event: its frame entry says so)."""

    channel: ClassVar[str] = "wire"
    t_s: float
    wall_ns: int
    direction: str
    data: bytes
    by_session: bool = False

    def to_json(self) -> dict[str, Any]:
        return {
            "t_s": self.t_s,
            "wall_ns": self.wall_ns,
            "direction": self.direction,
            "data_base64": base64.b64encode(self.data).decode("ascii"),
            "by_session": self.by_session,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> WireEntry:
        try:
            raw = base64.b64decode(data["data_base64"], validate=True)
        except (KeyError, TypeError, ValueError) as error:
            raise EntryError(f"wire entry without valid data_base64: {error}") from None
        fields = _fields(cls, {**data, "data": raw})
        return cls(**fields)


@dataclass(frozen=True, slots=True)
class FrameEntry:
    """A decoded frame: a command sent (``out``) or a response received (``in``).

    A response carries ``query``, the name of the query it answered (``None`` when it answered
    none), ``round_trip_ms`` from that query's frame, and ``late`` if it came after the query
    had failed (discarded by the driver). A command recorded from the driver's events carries
    ``retry``: ``True`` for a query the driver sent again after an attempt failed, ``False``
    for any other; ``None`` where nobody knows (bytes seen by a tap or a sniffer, or a
    recording older than the field).
    """

    channel: ClassVar[str] = "frames"
    t_s: float
    wall_ns: int
    direction: str
    kind: str
    name: str
    values: tuple[int, ...]
    by_session: bool = False
    query: str | None = None
    round_trip_ms: float | None = None
    late: bool = False
    retry: bool | None = None

    def to_json(self) -> dict[str, Any]:
        data = dataclasses.asdict(self)
        data["values"] = list(self.values)
        return data

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> FrameEntry:
        fields = _fields(cls, data)
        values = fields.get("values")
        if not isinstance(values, list) or not all(isinstance(v, int) for v in values):
            raise EntryError(f"frame entry's values must be a list of integers, got {values!r}")
        fields["values"] = tuple(values)
        entry = cls(**fields)
        _check_frame(entry)
        return entry


def _check_frame(entry: FrameEntry) -> None:
    """Refuse a frame that no controller takes or sends: the recorder writes only frames of the
    command table, so anything else is damage, named here rather than where it is printed or
    resent."""
    if (entry.direction, entry.kind) not in (("out", "command"), ("in", "response")):
        raise EntryError(
            f"frame entry: a {entry.kind!r} going {entry.direction!r} (a command goes out, "
            "a response comes in)"
        )
    message = Command if entry.kind == "command" else Response
    try:
        message(entry.name, entry.values)
    except (ValueError, TypeError) as error:  # an unknown name, a wrong count or range, a bool
        raise EntryError(f"frame entry: {error}") from None


@dataclass(frozen=True, slots=True)
class EventEntry:
    """Something the session noticed or decided.

    ``event`` is one of ``query_failed`` (``name``: the query, ``detail``: timeout, corrupt,
    lost or resync), ``bad_frame`` (``name``: the reason, e.g. ``checksum``), ``late_reply``,
    ``stray_frame``, ``text`` (debug output or noise), ``reset_suspected``, ``mode_changed``
    (``name``: checksum or debug, ``detail``: on/off), ``motion_expired``, ``lock``
    (``detail``: locked/unlocked), ``leak`` and ``link`` (``detail``: ready, lost, ...).
    """

    channel: ClassVar[str] = "events"
    t_s: float
    wall_ns: int
    event: str
    name: str = ""
    detail: str = ""

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> EventEntry:
        return cls(**_fields(cls, data))


#: The telemetry table's columns after the clocks, and what each one is.
TELEMETRY_FIELDS: dict[str, str] = {
    "depth_cm": "depth from the last qd reply, cm",
    "setpoint_cm": "depth set-point of the last mvd command, cm",
    "pressure_raw": "raw pressure reading from the last qr reply",
    "roll_deg": "roll from the last qro reply, degrees",
    "pitch_deg": "pitch from the last qpi reply, degrees",
    "heading_deg": "heading from the last qhe reply, degrees",
    "leak": "leak latch from the last q.l reply (1 fired)",
    "locked": "1 after stop, 0 after start",
    "vertical_direct": "vertical mode of the last mvdirect command (1 direct, 0 depth)",
    "vertical_thrust_percent": "vertical thrust of the last mvs command, %",
    "thrust_direction_deg": "direction of the last th command, degrees",
    "thrust_power_percent": "power of the last th command, %",
}


@dataclass(frozen=True, slots=True)
class TelemetryEntry:
    """The robot's state as the host knows it: the last value of each column (``None``: not
    known yet)."""

    channel: ClassVar[str] = "telemetry"
    t_s: float
    wall_ns: int
    values: Mapping[str, int | None]

    def to_json(self) -> dict[str, Any]:
        return {"t_s": self.t_s, "wall_ns": self.wall_ns, **self.values}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> TelemetryEntry:
        values: dict[str, int | None] = {}
        for name in TELEMETRY_FIELDS:
            value = data.get(name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, int)):
                raise EntryError(f"telemetry {name} must be an integer or null, got {value!r}")
            check_telemetry_range(name, value)
            values[name] = value
        clocks = _fields(cls, {"t_s": data.get("t_s"), "wall_ns": data.get("wall_ns")}, values)
        return cls(t_s=clocks["t_s"], wall_ns=clocks["wall_ns"], values=values)


def check_telemetry_range(name: str, value: int | None) -> None:
    """:class:`EntryError` if telemetry column ``name`` holds a value outside the range of the
    command table's argument it comes from: no controller sends it and no recorder writes it,
    so the file is damaged (a plot would draw a spike, or fail past a float's range)."""
    # (The ranges come through the telemetry's columns: loaded as a recording is read, since
    # that module needs this one.)
    from rovlink.recorder.telemetry import COLUMN_RANGES  # noqa: PLC0415

    low, high = COLUMN_RANGES[name]
    if value is not None and not low <= value <= high:
        shown = str(value)
        if len(shown) > 16:
            shown = f"{shown[:8]}… ({len(shown)} digits)"
        raise EntryError(f"telemetry {name} must be in {low}–{high}, got {shown}")


Entry = HeaderEntry | WireEntry | FrameEntry | EventEntry | TelemetryEntry

_TYPES: dict[str, type[Entry]] = {
    kind.channel: kind for kind in (HeaderEntry, WireEntry, FrameEntry, EventEntry, TelemetryEntry)
}


def entry_from_json(channel: str, data: Mapping[str, Any]) -> Entry:
    """The entry of ``channel`` stored as ``data``; :class:`EntryError` if it has another shape."""
    kind = _TYPES.get(channel)
    if kind is None:
        raise EntryError(f"unknown channel {channel!r}")
    try:
        _check_types(channel, data)
        return kind.from_json(data)
    except TypeError as error:
        raise EntryError(f"{channel} entry of the wrong shape: {error}") from None


# The JSON Schema types of CHANNELS: what each is in Python, and its name in an error.
_JSON_TYPES: dict[str, tuple[tuple[type, ...], str]] = {
    "string": ((str,), "a string"),
    "boolean": ((bool,), "a boolean"),
    "integer": ((int,), "an integer"),
    "number": ((int, float), "a number"),
    "null": ((type(None),), "null"),
    "array": ((list,), "a list"),
}


@dataclass(frozen=True, slots=True)
class _FieldCheck:
    """What the JSON Schema of a channel allows in one field, ready to check (made once: a
    recording of an hour holds some 360 000 entries)."""

    name: str
    #: The Python types of its JSON types.
    allowed: tuple[type, ...]
    #: Whether JSON's true and false are allowed (they are no numbers, though Python's bool is
    #: an int).
    boolean: bool
    #: Its JSON types, for an error.
    expected: str
    #: The values allowed, if the schema lists them.
    enum: tuple[Any, ...] | None

    @classmethod
    def of(cls, name: str, schema: Mapping[str, Any]) -> _FieldCheck:
        types = schema["type"] if isinstance(schema["type"], list) else [schema["type"]]
        return cls(
            name,
            tuple(python for each in types for python in _JSON_TYPES[each][0]),
            "boolean" in types,
            " or ".join(_JSON_TYPES[each][1] for each in types),
            tuple(schema["enum"]) if "enum" in schema else None,
        )


def _check_types(channel: str, data: Mapping[str, Any]) -> None:
    """Refuse a value of another type than the channel's JSON Schema gives it (or, with an
    ``enum``, another value): the tools that print, plot and resend an entry take its values to
    be what the schema says. An absent field is left to the entry's defaults and own checks."""
    for check in _CHECKS[channel]:
        name = check.name
        if name not in data:
            continue
        value = data[name]
        if (value.__class__ is bool and not check.boolean) or not isinstance(value, check.allowed):
            raise EntryError(f"{channel} entry: {name} must be {check.expected}, got {value!r}")
        if check.enum is not None and value not in check.enum:
            expected = ", ".join(repr(choice) for choice in check.enum)
            raise EntryError(f"{channel} entry: {name} must be one of {expected}, got {value!r}")


def _fields(
    cls: type[Entry], data: Mapping[str, Any], extra: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """``data``'s values for ``cls``'s fields, the clocks checked; extra keys are ignored (a
    newer minor version may add some)."""
    names = _FIELD_NAMES[cls]
    if extra:
        names = names - set(extra)
    fields = {name: data[name] for name in names if name in data}
    t_s, wall_ns = fields.get("t_s"), fields.get("wall_ns")
    if isinstance(t_s, bool) or not isinstance(t_s, int | float) or not math.isfinite(t_s):
        # (1e400 reads as infinity: a replay would wait for it for ever)
        raise EntryError(f"{cls.channel} entry: t_s must be a finite number, got {t_s!r}")
    if isinstance(wall_ns, bool) or not isinstance(wall_ns, int):
        raise EntryError(f"{cls.channel} entry: wall_ns must be an integer, got {wall_ns!r}")
    fields["t_s"] = float(t_s)
    return fields


_STRING = {"type": "string"}
_NULLABLE_INT = {"type": ["integer", "null"]}

#: Each channel's JSON Schema.
CHANNELS: dict[str, dict[str, Any]] = {
    "header": {
        "type": "object",
        "title": "rovlink.Header",
        "properties": {
            **_CLOCKS_SCHEMA,
            "url": _STRING,
            "checksum": {"type": "boolean"},
            "algorithm": _STRING,
            "program": _STRING,
            "version": _STRING,
            "format_version": {"type": "integer"},
        },
    },
    "wire": {
        "type": "object",
        "title": "rovlink.Wire",
        "properties": {
            **_CLOCKS_SCHEMA,
            "direction": {"type": "string", "enum": ["out", "in"]},
            "data_base64": {"type": "string", "contentEncoding": "base64"},
            "by_session": {"type": "boolean"},
        },
    },
    "frames": {
        "type": "object",
        "title": "rovlink.Frame",
        "properties": {
            **_CLOCKS_SCHEMA,
            "direction": {"type": "string", "enum": ["out", "in"]},
            "kind": {"type": "string", "enum": ["command", "response"]},
            "name": _STRING,
            "values": {"type": "array", "items": {"type": "integer"}},
            "by_session": {"type": "boolean"},
            "query": {"type": ["string", "null"]},
            "round_trip_ms": {"type": ["number", "null"]},
            "late": {"type": "boolean"},
            "retry": {"type": ["boolean", "null"]},
        },
    },
    "events": {
        "type": "object",
        "title": "rovlink.Event",
        "properties": {**_CLOCKS_SCHEMA, "event": _STRING, "name": _STRING, "detail": _STRING},
    },
    "telemetry": {
        "type": "object",
        "title": "rovlink.Telemetry",
        "properties": {
            **_CLOCKS_SCHEMA,
            **{
                name: {**_NULLABLE_INT, "description": description}
                for name, description in TELEMETRY_FIELDS.items()
            },
        },
    },
}


#: Each channel's checks of its JSON Schema, made once.
_CHECKS: dict[str, tuple[_FieldCheck, ...]] = {
    channel: tuple(_FieldCheck.of(name, field) for name, field in schema["properties"].items())
    for channel, schema in CHANNELS.items()
}
#: Each kind of entry's field names.
_FIELD_NAMES: dict[type[Entry], frozenset[str]] = {
    kind: frozenset(field.name for field in dataclasses.fields(kind)) for kind in _TYPES.values()
}
