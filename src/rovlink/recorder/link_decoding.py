"""Both directions of a link decoded as its two ends read them: each reply in the checksum mode
of its query.

The controller takes ``#crcon!``/``#crcoff!`` from the next frame on (P3), and a reply carries
a checksum if the controller was in checksum mode when it took the query: so the reply to a
query sent just before ``#crcon!`` arrives after it, and is still plain. One decoder over both
directions, switching at the mode frame, reads such a reply as a bad frame. A
:class:`LinkDecoder` keeps a decoder per direction and the queries awaiting replies (answered
in order, P4), so that each reply is read in its own query's mode.

A query unanswered for the host's reply timeout (after it was sent, or after the last reply
that answered a query, whichever is later) can no longer be answered (P20): a reply of its name
after that is late, never its own. It is let go, so that a later reply of its name is matched
to the query it answers, not to the one left unanswered, and a late reply is told as late.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from rovlink.protocol import BadFrame, Command, Decoder, Event, Frame, Kind, Setting

__all__ = ["DEFAULT_REPLY_TIMEOUT_S", "Answer", "LinkDecoder"]

#: Queries remembered while awaiting replies; bounded so that a controller that never answers
#: cannot grow memory.
_MAX_AWAITED = 64
#: The host's reply timeout assumed unless told: the driver's default (``--timeout``).
DEFAULT_REPLY_TIMEOUT_S = 0.5


@dataclass(slots=True)
class _Awaited:
    """A query sent and the names of the replies it still awaits, oldest first."""

    query: str
    names: deque[str]
    #: The checksum mode in force when the controller took the query: its replies' mode (P3).
    checksum: bool
    #: When the query was seen going out (the caller's clock): its replies' round trip.
    sent_s: float = 0.0


@dataclass(slots=True)
class Answer:
    """The query a reply answered: its name, when it was seen going out, and whether the reply
    came late (after the query timed out, P20)."""

    query: str
    sent_s: float
    late: bool = False


class LinkDecoder:
    """Decode bytes seen going each way on a link; each event with the query it answered.

    A sniffer's bytes (all ``in``) hold both directions: a frame that starts with ``#`` is a
    command, read as one.

    Example:

    >>> link = LinkDecoder()
    >>> [event.raw for event, _ in link.feed("out", b"#qd!#crcon!")]
    [b'#qd!', b'#crcon!']
    >>> [(event.raw, query) for event, query in link.feed("in", b"$qd.12!")]  # plain: P3
    [(b'$qd.12!', 'qd')]
    """

    def __init__(
        self,
        *,
        checksum: bool = False,
        algorithm: str = "crc8",
        reply_timeout_s: float = DEFAULT_REPLY_TIMEOUT_S,
    ) -> None:
        #: The checksum mode the next command is taken in, as the commands seen set it (P3).
        self.checksum = checksum
        #: How long the host waits for a reply (P20): a query unanswered so long is let go.
        self.reply_timeout_s = reply_timeout_s
        self._out = Decoder(checksum_enabled=checksum, algorithm=algorithm)
        self._in = Decoder(checksum_enabled=checksum, algorithm=algorithm)
        self._awaited: deque[_Awaited] = deque(maxlen=_MAX_AWAITED)
        # Queries let go unanswered (timed out), oldest first: a reply to one of them is late.
        self._timed_out: deque[_Awaited] = deque(maxlen=_MAX_AWAITED)
        # When a reply last answered an awaited query: the host's deadlines run from it too.
        self._progress_s = 0.0
        # The start byte of the frame the ``in`` stream is inside (b"": between frames).
        self._in_start = b""
        # When the bytes being fed were seen (a query's send time).
        self._at_s = 0.0

    def set_mode(self, checksum: bool, algorithm: str) -> None:
        """Start again in ``checksum`` mode with ``algorithm`` (a new file of a rotated
        recording records the mode it starts in); ValueError for an unknown algorithm."""
        for decoder in (self._out, self._in):
            decoder.algorithm = algorithm
            decoder.checksum_enabled = checksum
        self.checksum = checksum

    def forget_awaited(self) -> None:
        """The link was lost: no reply to a query sent before will come (else each later reply
        of its name is matched to the query before its own, its round trip too long)."""
        self._awaited.clear()
        self._timed_out.clear()

    def feed(self, direction: str, data: bytes) -> list[tuple[Event, str | None]]:
        """The events of ``data`` seen going ``direction`` (``out``: to the controller), each
        with the query it answered (``None`` for commands, text, bad and stray frames)."""
        return [
            (event, None if answer is None else answer.query)
            for event, answer in self.feed_timed(direction, data, 0.0)
        ]

    def feed_timed(
        self, direction: str, data: bytes, at_s: float
    ) -> list[tuple[Event, Answer | None]]:
        """As :meth:`feed`, for ``data`` seen at ``at_s``: each event with the :class:`Answer`
        it gave (every response of a ``qsa`` reply with its ``qsa``'s; never a query that went
        unanswered before it, nor one that timed out before the reply came: the reply is then
        late, answering the query that timed out if none of its name awaits)."""
        out: list[tuple[Event, Answer | None]] = []
        self._at_s = at_s
        if direction == "out":
            self._take(self._out.feed(data), out)
            return out
        self._let_go_timed_out(at_s)
        decoder = self._in
        if b"#" not in data and self._in_start != b"#" and self._one_reply_mode():
            # Replies alone, all in one mode (the usual case): the chunk in one go.
            decoder.checksum_enabled = self._reply_mode()
            self._in_start = _start_after(data, self._in_start)
            self._take(decoder.feed(data), out)
            return out
        # Frame by frame: each is read in its own mode, known only once the one before it has
        # been matched to its query.
        for piece in _frame_pieces(data):
            start = _start_after(piece, self._in_start, ended=False)
            decoder.checksum_enabled = self.checksum if start == b"#" else self._reply_mode()
            self._in_start = _start_after(piece, self._in_start)
            self._take(decoder.feed(piece), out)
        return out

    def end(self) -> list[tuple[str, Event]]:
        """The events of the end of each direction's stream (unfinished text, a truncated
        frame), with their direction."""
        return [("out", event) for event in self._out.end()] + [
            ("in", event) for event in self._in.end()
        ]

    def _let_go_timed_out(self, now_s: float) -> None:
        """Let go the awaited queries whose reply would come after the host's timeout (P20):
        their deadlines run in the order they were sent, so these are the oldest."""
        awaited = self._awaited
        timeout_s = self.reply_timeout_s
        while awaited and max(awaited[0].sent_s, self._progress_s) + timeout_s < now_s:
            self._timed_out.append(awaited.popleft())

    def _reply_mode(self) -> bool:
        """The mode of the next reply: its query's, else (a reply to nothing) the current."""
        return self._awaited[0].checksum if self._awaited else self.checksum

    def _one_reply_mode(self) -> bool:
        mode = self.checksum
        return all(awaited.checksum == mode for awaited in self._awaited)

    def _take(self, events: list[Event], out: list[tuple[Event, Answer | None]]) -> None:
        for decoded in events:
            event = self._in_the_other_mode(decoded) if isinstance(decoded, BadFrame) else decoded
            answered = None
            if isinstance(event, Frame):
                message = event.message
                if message.kind is Kind.COMMAND:
                    command = Command(message.name, message.values)
                    if command.spec.replies:  # (in the mode before the command's own change)
                        self._awaited.append(
                            _Awaited(
                                command.name,
                                deque(command.spec.replies),
                                self.checksum,
                                self._at_s,
                            )
                        )
                    setting = command.setting
                    if setting is not None and setting[0] is Setting.CHECKSUM:
                        self.checksum = setting[1]
                else:
                    answered = self._answered(event)
            out.append((event, answered))

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

    def _answered(self, event: Frame) -> Answer | None:
        """The query that ``event`` answers, taken off the awaited list; ``None`` if none.

        The controller answers in order (P4): the queries before the one answered will never
        be, and are let go. A reply of no awaited query's name is late if a query of its name
        timed out (the oldest such one answered, those before it let go)."""
        name = event.message.name
        found = _take_answered(self._awaited, name)
        if found is not None:
            if self._timed_out:
                self._timed_out.clear()  # (answered in order: theirs will not come now)
            self._progress_s = self._at_s
            return Answer(found.query, found.sent_s)
        found = _take_answered(self._timed_out, name)
        return None if found is None else Answer(found.query, found.sent_s, late=True)


def _take_answered(queries: deque[_Awaited], name: str) -> _Awaited | None:
    """The oldest of ``queries`` whose next reply is ``name``, that reply taken off it (and the
    query too once it has all its replies), the queries before it let go; ``None`` if none."""
    for index, awaited in enumerate(queries):
        if awaited.names[0] == name:
            awaited.names.popleft()
            for _ in range(index):
                queries.popleft()
            if not awaited.names:
                queries.popleft()
            return awaited
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
