"""From what happened on a link to recording entries: the client's events, or tapped bytes.

:class:`SessionLog` keeps what entries depend on (queries awaiting replies, the telemetry
state, the lock and leak states) and turns each happening into entries.
:class:`ClientEventLog` feeds it the host driver's events (the driver has already matched
replies to queries); :class:`TapLog` feeds it raw bytes seen in each direction by a tap or a
sniffer, decoding them itself, since no driver of ours is in the middle.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

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
    Setting,
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

    def __init__(self, *, checksum: bool = False) -> None:
        self.telemetry = TelemetryState()
        #: The checksum mode the next command is taken in, as the commands seen set it (P3).
        self.checksum = checksum
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
        setting = command.setting
        if setting is not None and setting[0] is Setting.CHECKSUM:
            self.checksum = setting[1]
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

    def __init__(self, *, checksum: bool = False) -> None:
        self.log = SessionLog(checksum=checksum)

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


@dataclass(slots=True)
class _Awaited:
    """A query sent and the names of the replies it still awaits, oldest first."""

    query: str
    names: deque[str]
    #: The checksum mode in force when the controller took the query: its replies' mode (P3).
    checksum: bool


class TapLog:
    """Entries from bytes seen in each direction, decoded here.

    Replies are matched to the oldest query still awaiting a reply of their name, the way the
    controller answers (in order, P4; ``qsa``'s six in their order, P12). Each reply is decoded
    in the checksum mode that was in force when its query was taken (P3: a mode change takes
    effect from the next frame, however the bytes were chunked). A sniffer's bytes (all ``in``)
    hold both directions: a frame that starts with ``#`` is a command, recorded as one.
    """

    def __init__(self, *, checksum: bool = False, algorithm: str = "crc8") -> None:
        self.log = SessionLog(checksum=checksum)
        self._out = Decoder(checksum_enabled=checksum, algorithm=algorithm)
        self._in = Decoder(checksum_enabled=checksum, algorithm=algorithm)
        self._awaited: deque[_Awaited] = deque(maxlen=_MAX_AWAITED)
        # The start byte of the frame the ``in`` stream is inside (b"": between frames).
        self._in_start = b""

    def entries(
        self, t_s: float, wall_ns: int, direction: str, data: bytes, by_session: bool = False
    ) -> list[Entry]:
        """The entries of ``data`` seen going ``direction`` (``out``: to the controller);
        ``by_session``: written by the tap itself."""
        out: list[Entry] = [self.log.wire(t_s, wall_ns, direction, data, by_session)]
        if direction == "out":
            self._take(self._out.feed(data), t_s, wall_ns, by_session, out)
            return out
        decoder = self._in
        if b"#" not in data and self._in_start != b"#" and self._one_reply_mode():
            # Replies alone, all in one mode (the usual case): the chunk in one go.
            decoder.checksum_enabled = self._reply_mode()
            self._in_start = _start_after(data, self._in_start)
            self._take(decoder.feed(data), t_s, wall_ns, False, out)
            return out
        # Frame by frame: each is read in its own mode, known only once the one before it has
        # been matched to its query.
        for piece in _frame_pieces(data):
            start = _start_after(piece, self._in_start, ended=False)
            decoder.checksum_enabled = self.log.checksum if start == b"#" else self._reply_mode()
            self._in_start = _start_after(piece, self._in_start)
            self._take(decoder.feed(piece), t_s, wall_ns, False, out)
        return out

    def _reply_mode(self) -> bool:
        """The mode of the next reply: its query's, else (a reply to nothing) the current."""
        return self._awaited[0].checksum if self._awaited else self.log.checksum

    def _one_reply_mode(self) -> bool:
        mode = self.log.checksum
        return all(awaited.checksum == mode for awaited in self._awaited)

    def _take(
        self, events: list[Event], t_s: float, wall_ns: int, by_session: bool, out: list[Entry]
    ) -> None:
        log = self.log
        for decoded in events:
            event = self._in_the_other_mode(decoded) if isinstance(decoded, BadFrame) else decoded
            if isinstance(event, Frame):
                message = event.message
                if message.kind is Kind.COMMAND:
                    command = Command(message.name, message.values)
                    if command.spec.replies:  # (in the mode before the command's own change)
                        self._awaited.append(
                            _Awaited(command.name, deque(command.spec.replies), log.checksum)
                        )
                    log.command(t_s, wall_ns, command, by_session, out)
                    continue
                query = self._answered(event)
                if query is not None:
                    response = Response(message.name, message.values)
                    log.replies(t_s, wall_ns, query, (response,), out)
                    continue
            log.decoded(t_s, wall_ns, event, out)

    def _in_the_other_mode(self, event: BadFrame) -> Event:
        """A reply that failed in the mode of the oldest awaited query, read again in the other
        mode if a query awaits it in that one: the oldest may never be answered (a probe sent
        while the board booted, a query lost to noise), and read in its mode every reply after
        a mode change was taken for a bad frame."""
        raw = event.raw
        if not raw.startswith(b"$") or not self._awaited:
            return event
        mode = not self._awaited[0].checksum
        decoder = Decoder(checksum_enabled=mode, algorithm=self._in.algorithm)
        decoded = decoder.feed(raw)
        if len(decoded) != 1 or not isinstance(decoded[0], Frame):
            return event
        name = decoded[0].message.name
        awaits = any(a.checksum is mode and a.names[0] == name for a in self._awaited)
        return decoded[0] if awaits else event

    def _answered(self, event: Frame) -> str | None:
        """The query that ``event`` answers, taken off the awaited list; ``None`` if none.

        The controller answers in order (P4): the queries before the one answered will never
        be, and are let go."""
        name = event.message.name
        for index, awaited in enumerate(self._awaited):
            if awaited.names[0] == name:
                awaited.names.popleft()
                for _ in range(index):
                    self._awaited.popleft()
                if not awaited.names:
                    self._awaited.popleft()
                return awaited.query
        return None


def _frame_pieces(data: bytes) -> list[bytes]:
    """``data`` cut after each ``!``: each piece ends a frame, but for the last."""
    parts = data.split(b"!")
    pieces = [part + b"!" for part in parts[:-1]]
    if parts[-1]:
        pieces.append(parts[-1])
    return pieces


def _start_after(data: bytes, before: bytes, *, ended: bool = True) -> bytes:
    """The start byte of the frame ``data`` leaves the stream inside (``ended=False``: of the
    frame its last ``!`` ends); ``before``: the one it started inside."""
    bang = data.rfind(b"!")
    tail = data[bang + 1 :] if ended or bang < 0 else data[:bang]
    found = max(tail.rfind(b"#"), tail.rfind(b"$"))
    if found >= 0:
        return tail[found : found + 1]
    if ended and b"!" in data:
        return b""
    return before
