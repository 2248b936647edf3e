"""What a browser may send over ``/ws``, checked before anything acts on it.

Every message is a JSON object with a ``type``. Anything else — not JSON, not an object, an
unknown type, a missing or mistyped field, a value out of the command table's range, a command
a page may not send — is a :class:`MessageError` whose text names what was wrong; the server
answers it with an ``error`` message and sends nothing to the robot.

>>> parse_message('{"type": "command", "name": "mvd", "values": [150]}')
CommandRequest(command=Command(name='mvd', values=(150,)), sent_ms=None)
>>> parse_message('{"type": "command", "name": "th", "values": [90, 40]}')
Traceback (most recent call last):
...
rovlink.station.messages.MessageError: command: 'th' cannot be sent as a command; ...
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from rovlink.protocol import ArgumentError, Command, UnknownCommandError, lookup
from rovlink.station.relay import PilotInput

__all__ = [
    "MAX_MESSAGE_BYTES",
    "PAGE_COMMANDS",
    "CommandRequest",
    "ControlRequest",
    "InputMessage",
    "MessageError",
    "RecordRequest",
    "StopRequest",
    "VisibilityMessage",
    "parse_message",
    "parse_stop",
]

#: Larger messages are refused unread (the largest real one is a few hundred bytes).
MAX_MESSAGE_BYTES = 4096

#: The commands a pilot's page may send as such. Motion (``th``, ``mvs``) comes only from the
#: pilot's input through the relay and its watchdog; the checksum and debug modes belong to the
#: link; queries are the server's.
PAGE_COMMANDS: tuple[str, ...] = (
    "start",
    "stop",
    "mvdirect",
    "mvd",
    "h+",
    "h-",
    "slreset",
    "mgmp",
    "mvpdp",
    "mvpdi",
    "mvpidd",
    "sdz",
    "sdk",
)


class MessageError(ValueError):
    """A message the server refuses; the text says what was wrong, for the page to show."""


@dataclass(frozen=True, slots=True)
class ControlRequest:
    """``take_control`` or ``release_control``.

    ``take_control`` may say whom the page takes control from (``from``: the pilot's id as the
    page knows it, ``null`` for nobody): if someone else has it by the time it arrives (another
    page took it a moment before), nothing changes and the page is told, so that it asks
    first, as for any pilot. Without ``from`` (a program), control is taken from whoever has it.
    """

    take: bool
    from_pilot: str | None = None
    from_given: bool = False


@dataclass(frozen=True, slots=True)
class StopRequest:
    """``stop``: ``#stop!`` now (any page may send it: it only makes the robot safer).

    ``stop_id`` names one press of STOP: the page sends it over its WebSocket and over one of
    its own (``/stop``), and the second to arrive is the same STOP.
    """

    stop_id: str | None = None


@dataclass(frozen=True, slots=True)
class InputMessage:
    """``input``: the pilot's controls (see :class:`~rovlink.station.relay.PilotInput`)."""

    pilot: PilotInput
    #: What produced it, ``gamepad`` or ``keyboard``: shown to the others.
    source: str
    #: When the page sent it, on the page's own clock (ms; ``None``: not said): how late
    #: messages arrive is measured against the earliest any arrived.
    sent_ms: float | None = None


@dataclass(frozen=True, slots=True)
class VisibilityMessage:
    """``visibility``: the page was hidden (another tab, minimised) or shown again."""

    hidden: bool


@dataclass(frozen=True, slots=True)
class CommandRequest:
    """``command``: one frame of :data:`PAGE_COMMANDS`, its values checked by the table.

    ``sent_ms``, as an input's: when the page sent it, on its own clock (``None``: not said).
    """

    command: Command
    sent_ms: float | None = None


@dataclass(frozen=True, slots=True)
class RecordRequest:
    """``record_start`` or ``record_stop``: the pilot's record button."""

    start: bool


PageMessage = (
    ControlRequest | StopRequest | InputMessage | VisibilityMessage | CommandRequest | RecordRequest
)

_INPUT_SOURCES = ("gamepad", "keyboard")


def _refuse_constant(name: str) -> Any:
    raise MessageError(f"not JSON: {name} is not a number JSON allows")


def parse_message(text: str | bytes | None) -> PageMessage:
    """The message in ``text``, checked; MessageError naming what was wrong."""
    if not isinstance(text, str):
        raise MessageError("messages are JSON text, not binary")
    if len(text) > MAX_MESSAGE_BYTES:
        raise MessageError(f"message of {len(text)} characters; the limit is {MAX_MESSAGE_BYTES}")
    try:
        data = json.loads(text, parse_constant=_refuse_constant)
    except RecursionError:
        raise MessageError("not JSON: nested too deeply") from None
    except json.JSONDecodeError as error:
        raise MessageError(f"not JSON: {error.msg} at character {error.pos}") from None
    if not isinstance(data, dict):
        raise MessageError(f"a message is a JSON object with a type, not {type(data).__name__}")
    kind = data.get("type")
    if not isinstance(kind, str):
        raise MessageError("a message needs a 'type' (a string)")
    if kind in ("take_control", "release_control"):
        if kind == "take_control" and "from" in data:
            from_pilot = data["from"]
            if from_pilot is not None and not isinstance(from_pilot, str):
                raise MessageError(
                    f"take_control: 'from' must be a page's id or null, got {from_pilot!r:.40}"
                )
            return ControlRequest(take=True, from_pilot=from_pilot, from_given=True)
        return ControlRequest(take=kind == "take_control")
    if kind == "stop":
        return StopRequest(_stop_id(data, kind))
    if kind == "input":
        return _input(data)
    if kind == "visibility":
        return VisibilityMessage(_field(data, kind, "hidden", bool))
    if kind == "command":
        return _command(data)
    if kind in ("record_start", "record_stop"):
        return RecordRequest(start=kind == "record_start")
    known = (
        "take_control, release_control, stop, input, visibility, command, record_start, record_stop"
    )
    raise MessageError(f"unknown message type {kind[:40]!r}; known: {known}")


#: The longest ``stop_id`` taken (a page makes them far shorter).
MAX_STOP_ID_CHARS = 64


def _stop_id(data: dict[str, Any], kind: str) -> str | None:
    if data.get("stop_id") is None:
        return None
    stop_id = _field(data, kind, "stop_id", str)
    if not 0 < len(stop_id) <= MAX_STOP_ID_CHARS:
        raise MessageError(f"{kind}: 'stop_id' must be 1 to {MAX_STOP_ID_CHARS} characters")
    return str(stop_id)


def parse_stop(text: str) -> tuple[str | None, str | None]:
    """The STOP a page sends on a connection of its own (``/stop``: ``{"stop_id": ...,
    "page_id": ...}``, both optional): its ``stop_id`` and the id of the page that sent it;
    MessageError naming what was wrong.

    >>> parse_stop('{"stop_id": "k3-1", "page_id": "p2"}')
    ('k3-1', 'p2')
    >>> parse_stop('[]')
    Traceback (most recent call last):
    ...
    rovlink.station.messages.MessageError: a STOP is a JSON object, not list
    """
    if len(text) > MAX_MESSAGE_BYTES:
        raise MessageError(f"a STOP of {len(text)} characters; the limit is {MAX_MESSAGE_BYTES}")
    try:
        data = json.loads(text, parse_constant=_refuse_constant)
    except (RecursionError, json.JSONDecodeError):
        raise MessageError("a STOP is JSON text") from None
    if not isinstance(data, dict):
        raise MessageError(f"a STOP is a JSON object, not {type(data).__name__}")
    page_id = None
    if data.get("page_id") is not None:
        page_id = str(_field(data, "stop", "page_id", str))[:MAX_STOP_ID_CHARS]
    return _stop_id(data, "stop"), page_id


def _field(data: dict[str, Any], kind: str, name: str, wanted: type) -> Any:
    value = data.get(name)
    if wanted is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif wanted is float:
        ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    else:
        ok = isinstance(value, wanted)
    if not ok:
        raise MessageError(f"{kind}: '{name}' must be {_TYPE_WORDS[wanted]}, got {value!r:.40}")
    return value


_TYPE_WORDS = {bool: "true or false", int: "an integer", float: "a number", str: "a string"}


def _input(data: dict[str, Any]) -> InputMessage:
    deadman = _field(data, "input", "deadman", bool)
    source = data.get("source", "gamepad")
    if source not in _INPUT_SOURCES:
        raise MessageError(f"input: 'source' must be gamepad or keyboard, got {source!r:.40}")
    direction_deg = _field(data, "input", "direction_deg", int)
    power_percent = _field(data, "input", "power_percent", int)
    vertical_percent = _field(data, "input", "vertical_percent", int)
    pad_timestamp_ms = None
    if source == "gamepad":
        pad_timestamp_ms = float(_field(data, "input", "pad_timestamp_ms", float))
    sent_ms = None
    if "sent_ms" in data:
        sent_ms = float(_field(data, "input", "sent_ms", float))
    try:
        pilot = PilotInput(
            deadman=deadman,
            direction_deg=direction_deg,
            power_percent=power_percent,
            vertical_percent=vertical_percent,
            pad_timestamp_ms=pad_timestamp_ms,
        )
    except ValueError as error:
        raise MessageError(f"input: {error}") from None
    return InputMessage(pilot, source, sent_ms)


def _command(data: dict[str, Any]) -> CommandRequest:
    name = _field(data, "command", "name", str)
    if name not in PAGE_COMMANDS:
        try:
            lookup(name)
        except UnknownCommandError:
            raise MessageError(f"command: unknown command {name[:40]!r}") from None
        raise MessageError(
            f"command: {name!r} cannot be sent as a command; a page may send "
            + ", ".join(PAGE_COMMANDS)
            + " (motion comes from the pilot's input)"
        )
    values = data.get("values", [])
    if not isinstance(values, list) or not all(
        isinstance(value, int) and not isinstance(value, bool) for value in values
    ):
        raise MessageError(f"command {name}: 'values' must be a list of integers")
    try:
        command = Command(name, tuple(values))
    except (ArgumentError, ValueError) as error:
        raise MessageError(f"command: {error}") from None
    sent_ms = None
    if "sent_ms" in data:
        sent_ms = float(_field(data, "command", "sent_ms", float))
    return CommandRequest(command, sent_ms)
