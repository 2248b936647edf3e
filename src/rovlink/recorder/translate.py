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
from rovlink.recorder.link_decoding import DEFAULT_REPLY_TIMEOUT_S, LinkDecoder
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
        self._leak: int | None = None

    def wire(
        self, t_s: float, wall_ns: int, direction: str, data: bytes, by_session: bool = False
    ) -> WireEntry:
        """The entry of bytes on the wire."""
        return WireEntry(t_s, wall_ns, direction, data, by_session)

    def command(
        self,
        t_s: float,
        wall_ns: int,
        command: Command,
        by_session: bool,
        out: list[Entry],
        *,
        retry: bool | None = None,
    ) -> None:
        """A command went out: its frame, its effect on the lock and the telemetry
        (``retry``: whether it was a retry of the driver's, ``None``: not known)."""
        out.append(
            FrameEntry(
                t_s,
                wall_ns,
                "out",
                "command",
                command.name,
                command.values,
                by_session,
                retry=retry,
            )
        )
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
        round_trip_ms: float | None = None,
        late: bool = False,
    ) -> None:
        """Responses came in, answering ``query`` (``None``: none) ``round_trip_ms`` after it
        went out; the telemetry follows unless they came late (the driver discarded them)."""
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
        # The send times of the queries awaiting replies, per name, oldest first.
        self._sent_at: dict[str, deque[float]] = {}

    def entries(self, wall_ns: int, event: ClientEvent) -> list[Entry]:
        """The entries of one event, seen at ``wall_ns``."""
        log = self.log
        t_s = event.at_s
        out: list[Entry] = []
        if isinstance(event, BytesSent):
            out.append(log.wire(t_s, wall_ns, "out", event.data, event.by_session))
            command = event.command
            if command is not None:
                if command.spec.is_query:
                    sent = self._sent_at.setdefault(command.name, deque(maxlen=_MAX_AWAITED))
                    sent.append(t_s)
                log.command(t_s, wall_ns, command, event.by_session, out, retry=event.retry)
        elif isinstance(event, BytesReceived):
            out.append(log.wire(t_s, wall_ns, "in", event.data))
        elif isinstance(event, ReplyReceived):
            name = event.query.name
            sent_s = self._take_sent(name)
            round_trip_ms = None if sent_s is None else _milliseconds(t_s - sent_s)
            log.replies(t_s, wall_ns, name, event.responses, out, round_trip_ms=round_trip_ms)
        elif isinstance(event, LateReply):
            # Its query failed, and its send time went with the failure: a send time taken
            # here would be a later query's (a retry's), which would then have none.
            response = event.response
            log.replies(t_s, wall_ns, response.name, (response,), out, late=True)
            out.append(EventEntry(t_s, wall_ns, "late_reply", response.name, "discarded"))
        elif isinstance(event, Unsolicited):
            log.decoded(t_s, wall_ns, event.event, out)
        elif isinstance(event, QueryFailed):
            self._take_sent(event.query.name)
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

    def _take_sent(self, query: str) -> float | None:
        """The send time of the oldest ``query`` awaiting a reply, no longer awaited."""
        sent = self._sent_at.get(query)
        return sent.popleft() if sent else None


class TapLog:
    """Entries from bytes seen in each direction, decoded here (see :class:`LinkDecoder`:
    each reply in its query's checksum mode, a sniffer's commands as commands; a reply after
    its query timed out, ``reply_timeout_s`` as the host waits, is late, P20)."""

    def __init__(
        self,
        *,
        checksum: bool = False,
        algorithm: str = "crc8",
        reply_timeout_s: float = DEFAULT_REPLY_TIMEOUT_S,
    ) -> None:
        self.log = SessionLog(checksum=checksum)
        self._link = LinkDecoder(
            checksum=checksum, algorithm=algorithm, reply_timeout_s=reply_timeout_s
        )

    def link_changed(self) -> None:
        """The link was lost or reopened: the queries awaiting replies are forgotten."""
        self._link.forget_awaited()

    def entries(
        self, t_s: float, wall_ns: int, direction: str, data: bytes, by_session: bool = False
    ) -> list[Entry]:
        """The entries of ``data`` seen going ``direction`` (``out``: to the controller);
        ``by_session``: written by the tap itself."""
        log = self.log
        out: list[Entry] = [log.wire(t_s, wall_ns, direction, data, by_session)]
        for event, answer in self._link.feed_timed(direction, data, t_s):
            if isinstance(event, Frame):
                message = event.message
                if message.kind is Kind.COMMAND:
                    command = Command(message.name, message.values)
                    log.command(t_s, wall_ns, command, by_session and direction == "out", out)
                    continue
                if answer is not None:
                    response = Response(message.name, message.values)
                    if answer.late:  # (no round trip, as the driver's late replies)
                        log.replies(t_s, wall_ns, answer.query, (response,), out, late=True)
                        detail = "after its query timed out"
                        out.append(EventEntry(t_s, wall_ns, "late_reply", response.name, detail))
                    else:
                        round_trip_ms = _milliseconds(t_s - answer.sent_s)
                        log.replies(
                            t_s,
                            wall_ns,
                            answer.query,
                            (response,),
                            out,
                            round_trip_ms=round_trip_ms,
                        )
                    continue
            log.decoded(t_s, wall_ns, event, out)
        return out


def _milliseconds(seconds: float) -> float:
    return round(seconds * 1000.0, 3)
