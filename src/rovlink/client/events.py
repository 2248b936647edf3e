"""What happened on a connection, one event at a time: the client's one hook for every tool.

``rovlink.connect(url, on_event=callback)`` (and ``rovlink.aio.connect``) calls ``callback`` with
each of these, in order: every byte written and read, exactly as on the wire, every reply with the
query it answered, and everything the session decided — a late reply discarded, a query that
failed, a suspected reset, a mode switch, an expired motion command. The console, the monitor and
the recorder all read the link through this hook, so none of them decodes the bytes again.

Every event carries ``at_s``, the session's monotonic clock when it happened, and ``direction``:
``out`` (host to controller), ``in`` (controller to host) or ``local`` (a decision of the session).

>>> event = BytesSent(at_s=1.5, data=b"#qd!", command=None)
>>> event.direction, event.data
('out', b'#qd!')
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from inspect import iscoroutinefunction
from typing import ClassVar

from rovlink.protocol import Command, Event, Response, Setting

__all__ = [
    "BytesReceived",
    "BytesSent",
    "ClientEvent",
    "EventCallback",
    "LateReply",
    "LinkState",
    "ModeChanged",
    "MotionExpired",
    "QueryFailed",
    "ReplyReceived",
    "ResetSuspected",
    "Unsolicited",
    "check_not_async",
    "subscriber",
]


@dataclass(frozen=True, slots=True)
class BytesSent:
    """Bytes written to the controller; ``command`` is the command they carry, if one;
    ``by_session``: the session wrote them itself (a keep-alive, a fence, a mode frame, zero
    thrust after ``motion_timeout``), not the program; ``retry``: a query sent again after an
    attempt of it failed (the program asked for it once: a replay sends it once)."""

    direction: ClassVar[str] = "out"
    at_s: float
    data: bytes
    command: Command | None
    by_session: bool = False
    retry: bool = False


@dataclass(frozen=True, slots=True)
class BytesReceived:
    """A chunk of bytes read from the controller, as it came (frames, text and noise)."""

    direction: ClassVar[str] = "in"
    at_s: float
    data: bytes


@dataclass(frozen=True, slots=True)
class ReplyReceived:
    """A query answered: its replies, in order (``qsa``: six)."""

    direction: ClassVar[str] = "in"
    at_s: float
    query: Command
    responses: tuple[Response, ...]


@dataclass(frozen=True, slots=True)
class LateReply:
    """A reply that came after its query had failed: counted and discarded, never handed on.
    ``by_session``: every query that failed with a reply of its name was the session's own (a
    keep-alive, a fence), not the program's: nobody asked for it."""

    direction: ClassVar[str] = "in"
    at_s: float
    response: Response
    by_session: bool = False


@dataclass(frozen=True, slots=True)
class Unsolicited:
    """Something that answered no query: debug text, line noise, a dropped or a stray frame."""

    direction: ClassVar[str] = "in"
    at_s: float
    event: Event


@dataclass(frozen=True, slots=True)
class QueryFailed:
    """One attempt of a query failed: ``timeout``, ``corrupt``, ``lost`` or ``resync``."""

    direction: ClassVar[str] = "local"
    at_s: float
    query: Command
    outcome: str


@dataclass(frozen=True, slots=True)
class ResetSuspected:
    """Queries kept timing out: the controller may have reset (P21); the mode is re-asserted."""

    direction: ClassVar[str] = "local"
    at_s: float
    consecutive_timeouts: int


@dataclass(frozen=True, slots=True)
class ModeChanged:
    """The session switched the checksum or debug mode, with the controller (P3, P5)."""

    direction: ClassVar[str] = "local"
    at_s: float
    setting: Setting
    enabled: bool


@dataclass(frozen=True, slots=True)
class MotionExpired:
    """No motion command renewed within ``motion_timeout``: zero thrust was sent (P23)."""

    direction: ClassVar[str] = "local"
    at_s: float
    commands: tuple[Command, ...]


@dataclass(frozen=True, slots=True)
class LinkState:
    """The link itself: ``lost`` (with ``reconnect=True``, being reopened) or ``reconnected``."""

    direction: ClassVar[str] = "local"
    at_s: float
    state: str
    detail: str = ""


ClientEvent = (
    BytesSent
    | BytesReceived
    | ReplyReceived
    | LateReply
    | Unsolicited
    | QueryFailed
    | ResetSuspected
    | ModeChanged
    | MotionExpired
    | LinkState
)

#: Called with every event of a connection (see the module's documentation), in order and one
#: at a time: by the blocking client from one of the program's threads or its reader thread, by
#: the asyncio client in its event loop.
#: ``events: list[ClientEvent] = []``, then
#: ``rovlink.connect(url, on_event=events.append)`` keeps them all.
EventCallback = Callable[[ClientEvent], None]


def subscriber(callback: EventCallback) -> EventCallback:
    """The argument of ``subscribe``, checked now: a callback that is not callable would fail
    at every event, each failure only logged, and the program would hear nothing.

    >>> subscriber(None)
    Traceback (most recent call last):
    ...
    TypeError: subscribe: callback must be callable (it is called with each event), got None
    """
    if not callable(callback):
        raise TypeError(
            f"subscribe: callback must be callable (it is called with each event), got {callback!r}"
        )
    check_not_async("subscribe: callback", callback)
    return callback


def check_not_async(name: str, callback: object) -> None:
    """TypeError for an ``async def`` given as a callback: it is called and its result
    dropped, so the coroutine it returns would never run, and the program would hear nothing
    (but a ``RuntimeWarning`` at each event).

    >>> async def show(event: object) -> None: ...
    >>> check_not_async("on_event", show)  # doctest: +ELLIPSIS, +NORMALIZE_WHITESPACE
    Traceback (most recent call last):
    ...
    TypeError: on_event must be a plain function, not an async def: it is called with each
    event in turn and nothing awaits what it returns, so <function show at ...> would never
    run; call asyncio.get_running_loop().create_task(...) from a plain function instead
    """
    if iscoroutinefunction(callback):
        raise TypeError(
            f"{name} must be a plain function, not an async def: it is called with each event "
            f"in turn and nothing awaits what it returns, so {callback!r} would never run; call "
            "asyncio.get_running_loop().create_task(...) from a plain function instead"
        )
