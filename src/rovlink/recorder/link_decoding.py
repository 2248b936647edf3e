"""Both directions of a link decoded as its two ends read them: each reply in the checksum mode
of its query.

The controller takes ``#crcon!``/``#crcoff!`` from the next frame on (P3), and a reply carries
a checksum if the controller was in checksum mode when it took the query: so the reply to a
query sent just before ``#crcon!`` arrives after it, and is still plain. One decoder over both
directions, switching at the mode frame, reads such a reply as a bad frame. A
:class:`LinkDecoder` keeps a decoder per direction and the queries awaiting replies (answered
in order, P4), so that each reply is read in its own query's mode.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from rovlink.protocol import BadFrame, Command, Decoder, Event, Frame, Kind, Setting

__all__ = ["LinkDecoder"]

#: Queries remembered while awaiting replies; bounded so that a controller that never answers
#: cannot grow memory.
_MAX_AWAITED = 64


@dataclass(slots=True)
class _Awaited:
    """A query sent and the names of the replies it still awaits, oldest first."""

    query: str
    names: deque[str]
    #: The checksum mode in force when the controller took the query: its replies' mode (P3).
    checksum: bool
    #: When the query was seen going out (the caller's clock): its replies' round trip.
    sent_s: float = 0.0


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

    def __init__(self, *, checksum: bool = False, algorithm: str = "crc8") -> None:
        #: The checksum mode the next command is taken in, as the commands seen set it (P3).
        self.checksum = checksum
        self._out = Decoder(checksum_enabled=checksum, algorithm=algorithm)
        self._in = Decoder(checksum_enabled=checksum, algorithm=algorithm)
        self._awaited: deque[_Awaited] = deque(maxlen=_MAX_AWAITED)
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

    def feed(self, direction: str, data: bytes) -> list[tuple[Event, str | None]]:
        """The events of ``data`` seen going ``direction`` (``out``: to the controller), each
        with the query it answered (``None`` for commands, text, bad and stray frames)."""
        return [(event, query) for event, query, _ in self.feed_timed(direction, data, 0.0)]

    def feed_timed(
        self, direction: str, data: bytes, at_s: float
    ) -> list[tuple[Event, str | None, float | None]]:
        """As :meth:`feed`, for ``data`` seen at ``at_s``: each event also with when the query
        it answered was seen going out (every response of a ``qsa`` reply with its ``qsa``'s
        time, and never with the time of a query that went unanswered before it)."""
        out: list[tuple[Event, str | None, float | None]] = []
        self._at_s = at_s
        if direction == "out":
            self._take(self._out.feed(data), out)
            return out
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

    def _reply_mode(self) -> bool:
        """The mode of the next reply: its query's, else (a reply to nothing) the current."""
        return self._awaited[0].checksum if self._awaited else self.checksum

    def _one_reply_mode(self) -> bool:
        mode = self.checksum
        return all(awaited.checksum == mode for awaited in self._awaited)

    def _take(self, events: list[Event], out: list[tuple[Event, str | None, float | None]]) -> None:
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
            if answered is None:
                out.append((event, None, None))
            else:
                out.append((event, answered.query, answered.sent_s))

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

    def _answered(self, event: Frame) -> _Awaited | None:
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
