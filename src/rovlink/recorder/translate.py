"""From what happened on a link to recording entries: the client's events, or tapped bytes.

:class:`SessionLog` keeps what entries depend on (queries awaiting replies, the telemetry
state, the lock and leak states) and turns each happening into entries.
:class:`ClientEventLog` feeds it the host driver's events (the driver has already matched
replies to queries); :class:`TapLog` feeds it raw bytes seen in each direction by a tap or a
sniffer, decoding them itself, since no driver of ours is in the middle.
"""

from __future__ import annotations

from collections import deque

from rovlink.client.events import (
    BytesReceived,
    BytesSent,
    ClientEvent,
    LateReply,
    LinkState,
    ModeChanged,
    MotionExpired,
    QueryFailed,
    ReplyReceived,
    ResetSuspected,
    Unsolicited,
)
from rovlink.protocol import (
    BadFrame,
    Command,
    Decoder,
    Event,
    Frame,
    Kind,
    Response,
    Text,
)
from rovlink.recorder.entries import (
    Entry,
    EventEntry,
    FrameEntry,
    TelemetryEntry,
    WireEntry,
)
from rovlink.recorder.telemetry import TelemetryState

__all__ = ["ClientEventLog", "SessionLog", "TapLog"]

#: Send times remembered per query name, to give replies their round trip; bounded so that a
#: controller that never answers cannot grow memory.
_MAX_AWAITED = 64


class SessionLog:
    """The entries of a session, made one happening at a time."""

    def __init__(self) -> None:
        self.telemetry = TelemetryState()
        self._sent_at: dict[str, deque[float]] = {}
        self._leak: int | None = None

    def wire(
        self, t_s: float, wall_ns: int, direction: str, data: bytes, by_session: bool = False
    ) -> WireEntry:
        """The entry of bytes on the wire."""
        return WireEntry(t_s, wall_ns, direction, data, by_session)

    def command(
        self, t_s: float, wall_ns: int, command: Command, by_session: bool, out: list[Entry]
    ) -> None:
        """A command went out: its frame, its effect on the lock and the telemetry."""
        out.append(
            FrameEntry(t_s, wall_ns, "out", "command", command.name, command.values, by_session)
        )
        if command.spec.is_query:
            awaited = self._sent_at.setdefault(command.name, deque(maxlen=_MAX_AWAITED))
            awaited.append(t_s)
        was_locked = self.telemetry.values["locked"]
        if self.telemetry.observe_command(command):
            locked = self.telemetry.values["locked"]
            if locked != was_locked:
                state = "locked" if locked else "unlocked"
                out.append(EventEntry(t_s, wall_ns, "lock", command.name, state))
            out.append(TelemetryEntry(t_s, wall_ns, dict(self.telemetry.values)))

    def replies(
        self,
        t_s: float,
        wall_ns: int,
        query: str | None,
        responses: tuple[Response, ...],
        out: list[Entry],
        *,
        late: bool = False,
    ) -> None:
        """Responses came in, answering ``query`` (``None``: none); the telemetry follows
        unless they came late (the driver discarded them)."""
        round_trip_ms = None
        if query is not None:
            awaited = self._sent_at.get(query)
            if awaited:
                round_trip_ms = round((t_s - awaited.popleft()) * 1000.0, 3)
        changed = False
        for response in responses:
            out.append(
                FrameEntry(
                    t_s,
                    wall_ns,
                    "in",
                    "response",
                    response.name,
                    response.values,
                    query=query,
                    round_trip_ms=round_trip_ms,
                    late=late,
                )
            )
            if not late:
                changed |= self.telemetry.observe_response(response)
        if changed:
            self._note_leak(t_s, wall_ns, out)
            out.append(TelemetryEntry(t_s, wall_ns, dict(self.telemetry.values)))

    def forget(self, query: str) -> None:
        """A query failed: its send time is no longer awaited."""
        awaited = self._sent_at.get(query)
        if awaited:
            awaited.popleft()

    def decoded(self, t_s: float, wall_ns: int, event: Event, out: list[Entry]) -> None:
        """A decoder event that answered no query: debug text, a bad or a stray frame."""
        if isinstance(event, Text):
            out.append(EventEntry(t_s, wall_ns, "text", "", event.text))
        elif isinstance(event, BadFrame):
            raw = event.raw.decode("latin-1")
            detail = f"{raw} ({event.detail})" if event.detail else raw
            out.append(EventEntry(t_s, wall_ns, "bad_frame", event.reason.value, detail))
        else:
            message = event.message
            if message.kind is Kind.RESPONSE:
                response = Response(message.name, message.values)
                self.replies(t_s, wall_ns, None, (response,), out)
            out.append(
                EventEntry(t_s, wall_ns, "stray_frame", message.name, event.raw.decode("ascii"))
            )

    def _note_leak(self, t_s: float, wall_ns: int, out: list[Entry]) -> None:
        leak = self.telemetry.values["leak"]
        if leak != self._leak:
            if leak:
                out.append(EventEntry(t_s, wall_ns, "leak", "q.l", "leak latch fired"))
            elif self._leak:
                out.append(EventEntry(t_s, wall_ns, "leak", "q.l", "leak latch reset"))
            self._leak = leak


class ClientEventLog:
    """Entries from the host driver's events (:mod:`rovlink.client.events`)."""

    def __init__(self) -> None:
        self.log = SessionLog()

    def entries(self, wall_ns: int, event: ClientEvent) -> list[Entry]:
        """The entries of one event, seen at ``wall_ns``."""
        log = self.log
        t_s = event.at_s
        out: list[Entry] = []
        if isinstance(event, BytesSent):
            out.append(log.wire(t_s, wall_ns, "out", event.data, event.by_session))
            if event.command is not None:
                log.command(t_s, wall_ns, event.command, event.by_session, out)
        elif isinstance(event, BytesReceived):
            out.append(log.wire(t_s, wall_ns, "in", event.data))
        elif isinstance(event, ReplyReceived):
            log.replies(t_s, wall_ns, event.query.name, event.responses, out)
        elif isinstance(event, LateReply):
            response = event.response
            log.replies(t_s, wall_ns, response.name, (response,), out, late=True)
            out.append(EventEntry(t_s, wall_ns, "late_reply", response.name, "discarded"))
        elif isinstance(event, Unsolicited):
            log.decoded(t_s, wall_ns, event.event, out)
        elif isinstance(event, QueryFailed):
            log.forget(event.query.name)
            out.append(EventEntry(t_s, wall_ns, "query_failed", event.query.name, event.outcome))
        elif isinstance(event, ResetSuspected):
            detail = f"{event.consecutive_timeouts} consecutive timeouts"
            out.append(EventEntry(t_s, wall_ns, "reset_suspected", "", detail))
        elif isinstance(event, ModeChanged):
            state = "on" if event.enabled else "off"
            out.append(EventEntry(t_s, wall_ns, "mode_changed", event.setting.value, state))
        elif isinstance(event, MotionExpired):
            names = ",".join(command.name for command in event.commands)
            out.append(EventEntry(t_s, wall_ns, "motion_expired", names, "zero thrust sent"))
        elif isinstance(event, LinkState):
            out.append(EventEntry(t_s, wall_ns, "link", event.state, event.detail))
        return out


class TapLog:
    """Entries from bytes seen in each direction, decoded here.

    Replies are matched to the oldest query still awaiting a reply of their name, the way the
    controller answers (in order, P4; ``qsa``'s six in their order, P12). The reply decoder
    follows the checksum mode that the host's frames set (P3).
    """

    def __init__(self, *, checksum: bool = False, algorithm: str = "crc8") -> None:
        self.log = SessionLog()
        self._out = Decoder(checksum_enabled=checksum, algorithm=algorithm)
        self._in = Decoder(checksum_enabled=checksum, algorithm=algorithm)
        # Each query sent and the names of the replies it still awaits, oldest first.
        self._awaited: deque[tuple[str, deque[str]]] = deque(maxlen=_MAX_AWAITED)

    def entries(self, t_s: float, wall_ns: int, direction: str, data: bytes) -> list[Entry]:
        """The entries of ``data`` seen going ``direction`` (``out``: to the controller)."""
        log = self.log
        out: list[Entry] = [log.wire(t_s, wall_ns, direction, data)]
        if direction == "out":
            for event in self._out.feed(data):
                if isinstance(event, Frame) and event.message.kind is Kind.COMMAND:
                    command = Command(event.message.name, event.message.values)
                    log.command(t_s, wall_ns, command, False, out)
                    if command.spec.replies:
                        self._awaited.append((command.name, deque(command.spec.replies)))
                else:
                    log.decoded(t_s, wall_ns, event, out)
            self._in.checksum_enabled = self._out.checksum_enabled
            return out
        for event in self._in.feed(data):
            query = self._answered(event)
            if query is None or not isinstance(event, Frame):
                log.decoded(t_s, wall_ns, event, out)
                continue
            response = Response(event.message.name, event.message.values)
            log.replies(t_s, wall_ns, query, (response,), out)
        return out

    def _answered(self, event: Event) -> str | None:
        """The query that ``event`` answers, taken off the awaited list; ``None`` if none."""
        if not isinstance(event, Frame) or event.message.kind is not Kind.RESPONSE:
            return None
        name = event.message.name
        for index, (query, names) in enumerate(self._awaited):
            if names[0] == name:
                names.popleft()
                if not names:
                    del self._awaited[index]
                return query
        return None
