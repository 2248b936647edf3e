"""What each topic carries, as JSON, and how a command request is read.

Every payload is a JSON object with ``robot`` and ``at`` (Unix time, s). A command request is
either plain text in the console's words (``th 90 30``) or a JSON object
``{"command": "th 90 30", "id": "anything", "at": 1767225600.25}``; the reply echoes ``id``, and
``at`` (optional, Unix time, s) says when it was published, so that the bridge can refuse motion
that reaches it late.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any

from rovlink.bridges.mqtt.outbox import DroppedEvents
from rovlink.client.sensors import Sensors
from rovlink.piloting.commanded import CommandedState
from rovlink.piloting.health import LinkHealth
from rovlink.protocol import Response

__all__ = [
    "MAX_REQUEST_BYTES",
    "CommandRequest",
    "PayloadError",
    "encode",
    "event_payload",
    "events_dropped_payload",
    "offline_state",
    "read_request",
    "reply_payload",
    "state_payload",
    "telemetry_payload",
]

#: A command is a few words; anything longer is refused unread.
MAX_REQUEST_BYTES = 512
#: The keys of a JSON request; any other is refused (a stop is carried out with a warning).
_REQUEST_KEYS = ("command", "id", "at")
#: A value quoted in an error is cut to this many characters.
_SHOWN_CHARACTERS = 40


class PayloadError(ValueError):
    """A command payload that cannot be read; the message says what was wrong."""


@dataclass(frozen=True, slots=True)
class CommandRequest:
    """A command as asked for on the command topic."""

    text: str
    request_id: str | int | None = None
    #: What is wrong with the request's ``id`` or ``at`` (then ``None``): the command is
    #: refused, but a ``stop`` is carried out all the same.
    problem: str | None = None
    #: When the request says it was published (its ``at``), Unix time, s.
    published_at_s: float | None = None


def encode(payload: dict[str, Any]) -> bytes:
    """Compact JSON, UTF-8.

    A lone surrogate (a request's ``"\\ud800"``, echoed in its reply) has no UTF-8: it is
    written as the JSON escape it came as, which a JSON reader takes back as it was.

    >>> encode({"id": "\\ud800", "text": "é"})
    b'{"id":"\\\\ud800","text":"\\xc3\\xa9"}'
    """
    text = json.dumps(payload, separators=(",", ":"), ensure_ascii=False)
    return text.encode("utf-8", errors="backslashreplace")


def telemetry_payload(robot: str, sensors: Sensors, sequence: int, at_s: float) -> dict[str, Any]:
    """One reading of every sensor; ``seq`` counts readings, so a subscriber sees gaps."""
    return {
        "robot": robot,
        "at": round(at_s, 3),
        "seq": sequence,
        "depth_cm": sensors.depth_cm,
        "pressure_raw": sensors.pressure_raw,
        "leak": sensors.leak_detected,
        "roll_deg": sensors.roll_deg,
        "pitch_deg": sensors.pitch_deg,
        "heading_deg": sensors.heading_deg,
    }


def state_payload(
    robot: str,
    commanded: CommandedState,
    health: LinkHealth,
    *,
    depth_cm: int | None,
    leak: bool | None,
    commands_allowed: bool,
    simulated: bool = False,
    at_s: float,
    now_s: float,
) -> dict[str, Any]:
    """The retained state: online, the lock, mode and set-points as last sent, link health.

    The lock is the one the controller announced, if it did after the bridge's last start or
    stop (debug output on), with where it came from in ``lock_heard_because``
    (``stopped by another line``); else as last sent, and ``lock_heard_because`` is ``None``.
    ``depth_cm`` and ``leak`` are ``None`` until the first sensor reading. ``simulated``: the
    controller is rovlink's simulator (``sim://``), not a robot.
    """
    silent_s = health.silent_s(now_s)
    return {
        "robot": robot,
        "at": round(at_s, 3),
        "online": True,
        "lock": str(commanded.latest_lock),
        "lock_heard_because": commanded.heard_lock_because,
        "mode": None if commanded.vertical_mode is None else str(commanded.vertical_mode),
        "target_depth_cm": commanded.target_depth_cm,
        "vertical_thrust_percent": commanded.vertical_thrust_percent,
        "direction_deg": commanded.direction_deg,
        "power_percent": commanded.power_percent,
        "depth_cm": depth_cm,
        "leak": leak,
        "commands_allowed": commands_allowed,
        "simulated": simulated,
        "link": {
            "status": health.status,
            "average_reply_ms": None
            if health.average_reply_s is None
            else round(health.average_reply_s * 1000, 1),
            "failures": health.failures,
            "silent_s": None if silent_s is None else round(silent_s, 1),
        },
    }


def offline_state(robot: str, reason: str) -> dict[str, Any]:
    """The retained state of a robot whose bridge is gone (the last will, or a clean exit)."""
    return {"robot": robot, "online": False, "reason": reason}


def event_payload(robot: str, event: str, detail: str, at_s: float) -> dict[str, Any]:
    """An event: ``leak``, ``failsafe``, ``reset_suspected``, ``link``, ``lock`` (a lock change
    the controller announced), ``events_dropped``."""
    return {"robot": robot, "at": round(at_s, 3), "event": event, "detail": detail}


def events_dropped_payload(
    robot: str, drops: DroppedEvents, kept: int, at_s: float
) -> dict[str, Any]:
    """The ``events_dropped`` event: how many events a full outbox dropped while the broker
    could not take them, and when the first and the last of them happened (``first_dropped_at``,
    ``last_dropped_at``, Unix time, s).

    >>> payload = events_dropped_payload("rov-1", DroppedEvents(3, 0.0, 1.5), 1000, 60.0)
    >>> payload["dropped"], payload["last_dropped_at"]
    (3, 1.5)
    >>> for part in payload["detail"].split(": "):
    ...     print(part)
    3 events dropped while the broker could not take them (the bridge keeps the latest 1000)
    they happened from 1970-01-01T00:00:00.000Z to 1970-01-01T00:00:01.500Z
    """
    what = "1 event" if drops.count == 1 else f"{drops.count} events"
    when = (
        f"it happened at {_utc(drops.first_at_s)}"
        if drops.count == 1
        else f"they happened from {_utc(drops.first_at_s)} to {_utc(drops.last_at_s)}"
    )
    detail = (
        f"{what} dropped while the broker could not take them "
        f"(the bridge keeps the latest {kept}): {when}"
    )
    payload = event_payload(robot, "events_dropped", detail, at_s)
    payload["dropped"] = drops.count
    payload["first_dropped_at"] = round(drops.first_at_s, 3)
    payload["last_dropped_at"] = round(drops.last_at_s, 3)
    return payload


def _utc(at_s: float) -> str:
    """``2026-11-27T14:10:01.234Z``."""
    moment = datetime.fromtimestamp(at_s, timezone.utc)
    return moment.strftime("%Y-%m-%dT%H:%M:%S.") + f"{moment.microsecond // 1000:03d}Z"


def reply_payload(
    robot: str,
    request: CommandRequest | None,
    *,
    frame: str | None = None,
    replies: tuple[Response, ...] = (),
    error: str | None = None,
    warning: str | None = None,
) -> dict[str, Any]:
    """The answer to a command: ``ok``, the frame sent and any replies, or the error; and a
    warning when the frame went out but the controller drops it (locked, the other vertical
    mode), as far as the state as last sent tells."""
    payload: dict[str, Any] = {"robot": robot, "ok": error is None}
    if request is not None:
        payload["command"] = request.text
        if request.request_id is not None:
            payload["id"] = request.request_id
    if frame is not None:
        payload["frame"] = frame
    if replies:
        payload["replies"] = [
            {
                "name": reply.name,
                "values": {
                    argument.name: value
                    for argument, value in zip(reply.spec.arguments, reply.values, strict=True)
                },
            }
            for reply in replies
        ]
    if error is not None:
        payload["error"] = error
    if warning is not None:
        payload["warning"] = warning
    return payload


def read_request(payload: bytes) -> CommandRequest:
    """The command in a payload of the command topic (``PayloadError`` if there is none).

    >>> read_request(b"th 90 30").text, read_request(b'{"command": "stop", "id": 7}').request_id
    ('th 90 30', 7)
    >>> read_request(b'{"cmd": "stop"}')
    Traceback (most recent call last):
    ...
    rovlink.bridges.mqtt.payloads.PayloadError: a JSON request needs "command", a string
    >>> read_request(b'{"command": "stop", "id": 1.5}').problem
    '"id" must be a string or an integer, got 1.5'
    >>> read_request(b'{"command": "th 90 30", "at": 1767225600.25}').published_at_s
    1767225600.25
    >>> read_request(b'{"command": "th 90 30", "time": 1767225600.25}').problem
    'unknown key "time": a JSON request has "command", and optionally "id" and "at"'
    """
    if len(payload) > MAX_REQUEST_BYTES:
        raise PayloadError(f"payload of {len(payload)} bytes; a command is at most 512")
    try:
        # (A byte order mark, as Windows editors and PowerShell write one at the start of a
        # file sent with `mosquitto_pub -f`, is not part of the command.)
        text = payload.decode("utf-8-sig").strip()
    except UnicodeDecodeError:
        raise PayloadError("payload is not UTF-8 text") from None
    if not text:
        raise PayloadError("empty payload; send a command such as 'stop' or 'th 90 30'")
    if not text.startswith("{"):
        first, problem = _first_line(text)
        return CommandRequest(first, None, problem)
    try:
        request = json.loads(text, object_pairs_hook=_JsonObject.of)
    except json.JSONDecodeError as error:
        raise PayloadError(f"payload is not valid JSON: {error.msg} at {error.pos}") from None
    if not isinstance(request, dict):
        raise PayloadError("a JSON request must be an object")
    command = request.get("command")
    if not isinstance(command, str) or not command.strip():
        raise PayloadError('a JSON request needs "command", a string')
    command, several_lines = _first_line(command.strip())
    repeated = getattr(request, "repeated", None)
    if repeated is not None:
        # Parsers differ on which one counts (Python's: the last), so a tool that reads the
        # first would see another request than the bridge: `{"command": "stop", "command": …}`.
        problem = f'"{repeated}" is given more than once: which one is meant is not clear'
        return CommandRequest(command.strip(), None, problem)
    request_id = request.get("id")
    # Not raised here: a stop with a bad id or time must still stop the robot.
    if request_id is not None and (
        isinstance(request_id, bool) or not isinstance(request_id, (str, int))
    ):
        problem = f'"id" must be a string or an integer, got {_shown(request_id)}'
        return CommandRequest(command.strip(), None, problem)
    published_at = request.get("at")
    published_at_s = None if published_at is None else _unix_time_s(published_at)
    if published_at is not None and published_at_s is None:
        problem = f'"at" must be Unix time in seconds, a number, got {_shown(published_at)}'
        return CommandRequest(command.strip(), request_id, problem)
    unknown = [key for key in request if key not in _REQUEST_KEYS]
    if unknown:
        # A misspelt "at" ("time", "At") would leave motion unchecked for lateness, unseen.
        problem = (
            f"unknown key {_shown(unknown[0])}: a JSON request has "
            '"command", and optionally "id" and "at"'
        )
        return CommandRequest(command.strip(), request_id, problem)
    if several_lines is not None:
        return CommandRequest(command, request_id, several_lines)
    return CommandRequest(command.strip(), request_id, published_at_s=published_at_s)


def _first_line(text: str) -> tuple[str, str | None]:
    """The command of a payload and, if it has more lines than one, the problem: a message
    carries one command (a file of them sent whole read as one command with too many values).

    >>> _first_line("stop\\r\\n\\nstart")
    ('stop', 'one command per message: this one has 2 lines ("start" after "stop")')
    """
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    if len(lines) <= 1:
        return text, None
    return lines[0], (
        f"one command per message: this one has {len(lines)} lines "
        f"({_shown(lines[1])} after {_shown(lines[0])})"
    )


class _JsonObject(dict[str, Any]):
    """A JSON object that remembers a key given more than once (``json`` keeps the last)."""

    repeated: str | None = None

    @classmethod
    def of(cls, pairs: list[tuple[str, Any]]) -> _JsonObject:
        json_object = cls(pairs)
        if len(json_object) < len(pairs):
            keys = [key for key, _ in pairs]
            json_object.repeated = next(k for n, k in enumerate(keys) if k in keys[:n])
        return json_object


def _unix_time_s(value: Any) -> float | None:
    """``value`` as a finite float of seconds, or ``None`` if it is not one (a JSON integer may
    have hundreds of digits: too large for a float)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        seconds = float(value)
    except OverflowError:
        return None
    return seconds if math.isfinite(seconds) else None


def _shown(value: Any) -> str:
    """``value`` as JSON, cut short: an error repeats what was wrong, not a whole payload."""
    text = json.dumps(value, ensure_ascii=False)
    return text if len(text) <= _SHOWN_CHARACTERS else text[: _SHOWN_CHARACTERS - 1] + "…"
