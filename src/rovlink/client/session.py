"""The sans-I/O heart of both clients: encode commands, match replies to pending queries.

A :class:`Session` owns the checksum mode, the decoder of the controller's byte stream, the
first-in-first-out queue of queries waiting for replies and the counters. It never touches a
port, a thread or a clock: the blocking and the asyncio clients feed it bytes and the time, write
the bytes it returns, and wake whoever waits on the queries it settles.

Matching (P4, P12): the controller answers queries in the order they arrive, each with the
replies the command table lists (``qsa``: six). A reply goes to the oldest pending query if it is
the reply that query expects next. If instead it is the first reply of a later query, the queries
before that one lost their replies (the controller dropped them) and are settled as ``lost`` at
once rather than after their timeout. Anything else is stray: a late reply to a query that
already timed out, or a frame nobody asked for.

Timeouts: a query's deadline is ``timeout_s`` after it was sent or after the last reply that
moved the queue, whichever is later — so a deep pipeline on a slow line is not timed out while
replies keep coming, and a dead link times everything out ``timeout_s`` after it went quiet.
"""

from __future__ import annotations

from collections import deque

from rovlink.client.counters import LinkCounters
from rovlink.protocol import (
    DEFAULT_ALGORITHM,
    BadFrame,
    ChecksumAlgorithm,
    Command,
    Decoder,
    Event,
    Frame,
    Kind,
    Reason,
    Response,
    Text,
    encode,
    get_algorithm,
)
from rovlink.protocol.text_enum import StrEnum

__all__ = ["Outcome", "PendingQuery", "Received", "Session"]

# A damaged reply (rather than a frame of another kind): the query it belonged to failed.
_CORRUPT_REASONS = frozenset({
    Reason.CHECKSUM, Reason.MALFORMED, Reason.RANGE, Reason.TOO_LONG, Reason.TRUNCATED,
})


_QUERY_BYTES_CACHED = 64


class Outcome(StrEnum):
    """What became of one attempt of a query."""

    PENDING = "pending"
    ANSWERED = "answered"
    TIMEOUT = "timeout"  # nothing came in time
    CORRUPT = "corrupt"  # its reply failed the checksum or was malformed
    LOST = "lost"  # the controller answered a later query first
    DISCONNECTED = "disconnected"


# Plain names for the members used per reply: an enum member costs a descriptor call to look up.
_PENDING = Outcome.PENDING
_ANSWERED = Outcome.ANSWERED


class PendingQuery:
    """One query on the wire, waiting for its replies."""

    __slots__ = ("command", "expected", "keepalive", "outcome", "responses", "sent_at", "waiter")

    def __init__(self, command: Command, sent_at: float, keepalive: bool = False) -> None:
        self.command = command
        self.sent_at = sent_at
        self.keepalive = keepalive
        #: The names of the replies, in order.
        self.expected: tuple[str, ...] = command.spec.replies
        self.responses: list[Response] = []
        self.outcome = _PENDING
        #: The client's handle to wake the caller (an ``asyncio.Future``), if it needs one.
        self.waiter: object = None

    def __repr__(self) -> str:
        return f"PendingQuery({self.command}, {self.outcome.value}, {self.responses})"

    @property
    def settled(self) -> bool:
        """Whether the attempt is over, one way or the other."""
        return self.outcome is not _PENDING


class Received:
    """What one chunk of received bytes did."""

    __slots__ = ("settled", "unsolicited")

    def __init__(self) -> None:
        #: Queries answered or failed by it.
        self.settled: list[PendingQuery] = []
        #: Everything that answered nothing: debug text, noise, dropped frames, stray replies.
        self.unsolicited: list[Event] = []


class Session:
    """State of one connection, without I/O. Not thread-safe: its owner serialises calls.

    >>> session = Session(timeout_s=0.5)
    >>> data, query = session.query(Command("qd"), now=0.0)
    >>> data
    b'#qd!'
    >>> session.receive(b"$qd.42!", now=0.001).settled[0].responses
    [Response(name='qd', values=(42,))]
    """

    def __init__(
        self,
        *,
        checksum_enabled: bool = False,
        algorithm: str | ChecksumAlgorithm = DEFAULT_ALGORITHM,
        timeout_s: float = 0.5,
    ) -> None:
        self._algorithm = get_algorithm(algorithm)
        self._checksum_enabled = checksum_enabled
        self._decoder = Decoder(checksum_enabled=checksum_enabled, algorithm=self._algorithm)
        self._raw_decoder = Decoder(algorithm=self._algorithm)
        self._pending: deque[PendingQuery] = deque()
        # Queries are few and repeat: their bytes in the current mode, encoded once.
        self._query_bytes: dict[Command, bytes] = {}
        self._last_query: Command | None = None  # the last query encoded, and its bytes
        self._last_query_bytes = b""
        self.timeout_s = timeout_s
        self.counters = LinkCounters()
        self.last_sent_at = float("-inf")
        self._last_progress_at = float("-inf")

    # -- state --------------------------------------------------------------------------------

    @property
    def checksum_enabled(self) -> bool:
        """Whether frames carry checksums in both directions now."""
        return self._checksum_enabled

    @property
    def algorithm(self) -> ChecksumAlgorithm:
        """The checksum algorithm used while the checksum mode is on."""
        return self._algorithm

    @property
    def pending(self) -> tuple[PendingQuery, ...]:
        """Queries waiting for replies, oldest first."""
        return tuple(self._pending)

    def deadline(self, query: PendingQuery) -> float:
        """When ``query`` times out unless a reply moves the queue before."""
        return max(query.sent_at, self._last_progress_at) + self.timeout_s

    def next_deadline(self) -> float | None:
        """The earliest deadline of the pending queries, if any."""
        if not self._pending:
            return None
        # Deadlines share the last-progress term, so the oldest query's is the earliest.
        return self.deadline(self._pending[0])

    # -- sending ------------------------------------------------------------------------------

    def frame_for(self, command: Command) -> bytes:
        """The bytes this side writes for ``command`` in the current checksum mode.

        A command honoured bare (``#stop!``) is always written bare: it then works even when the
        controller's checksum mode is not the one this side believes (a lost ``#crcon!``, P3).

        Example::

            Session().frame_for(Command("qd"))  # b"#qd!"; b"#qd8C!" in checksum mode
        """
        checksummed = self._checksum_enabled and not command.spec.honoured_bare
        return encode(command, self._algorithm if checksummed else None)

    def command(self, command: Command, now: float) -> bytes:
        """The bytes of a command that expects no reply; ``crcon``/``crcoff`` switch the mode."""
        if command.spec.is_query:
            raise ValueError(f"{command} is a query: use Session.query")
        data = self.frame_for(command)
        self._count_sent(data, now)
        if command.name == "crcon":
            self._set_mode(True)
        elif command.name == "crcoff":
            self._set_mode(False)
        return data

    def query(self, command: Command, now: float, *, keepalive: bool = False,
              ) -> tuple[bytes, PendingQuery]:
        """The bytes of a query, and its entry at the back of the queue.

        Write the bytes before anything else is written: the queue's order is the wire's.
        (Or write :meth:`query_bytes` first and queue the query before any reply can be fed.)
        """
        data = self.query_bytes(command)
        counters = self.counters
        counters.frames_sent += 1
        counters.bytes_sent += len(data)
        self.last_sent_at = now
        pending = PendingQuery(command, now, keepalive)
        self._pending.append(pending)
        if keepalive:
            self.counters.keepalives += 1
        return data, pending

    def query_bytes(self, command: Command) -> bytes:
        """The bytes of a query in the current checksum mode (without queueing it).

        Example::

            Session().query_bytes(Command("qd"))  # b"#qd!"
        """
        # The same query object again (a polling loop): no hashing (a dataclass hashes in Python).
        if command is self._last_query:
            return self._last_query_bytes
        data = self._query_bytes.get(command)
        if data is None:
            if not command.spec.is_query:
                raise ValueError(f"{command} expects no reply: use Session.command")
            data = self.frame_for(command)
            if len(self._query_bytes) < _QUERY_BYTES_CACHED:
                self._query_bytes[command] = data
        self._last_query = command
        self._last_query_bytes = data
        return data

    def raw(self, frame: bytes, now: float) -> PendingQuery | None:
        """Account for a raw frame sent as it is; a query in it joins the queue.

        The frame is read as the controller will read it, in the current checksum mode.
        """
        self._raw_decoder.checksum_enabled = self._checksum_enabled
        self._raw_decoder.reset()
        events = self._raw_decoder.feed(frame)
        self._count_sent(frame, now)
        if len(events) != 1 or not isinstance(events[0], Frame):
            return None
        message = events[0].message
        if message.kind is not Kind.COMMAND:
            return None
        command = Command(message.name, message.values)
        if command.name in ("crcon", "crcoff"):
            self._set_mode(command.name == "crcon")
        if not command.spec.is_query:
            return None
        pending = PendingQuery(command, now)
        self._pending.append(pending)
        return pending

    # -- receiving ----------------------------------------------------------------------------

    def receive(self, data: bytes, now: float) -> Received:
        """Decode bytes from the controller; settle the queries they answer or break."""
        counters = self.counters
        counters.bytes_received += len(data)
        result = Received()
        pending = self._pending
        for event in self._decoder.feed(data):
            if isinstance(event, Frame):
                message = event.message
                if isinstance(message, Response):
                    counters.frames_received += 1
                    # The usual case inline: the reply the oldest query expects next.
                    head = pending[0] if pending else None
                    if head is not None:
                        responses = head.responses
                        expected = head.expected
                        if expected[len(responses)] == message.name:
                            responses.append(message)
                            self._last_progress_at = now
                            if len(responses) == len(expected):
                                pending.popleft()
                                head.outcome = _ANSWERED
                                counters.replies += 1
                                result.settled.append(head)
                            continue
                    if self._deliver(message, now, result.settled):
                        continue
                counters.stray_frames += 1
            elif isinstance(event, Text):
                counters.text_lines += 1
            else:
                self._bad_frame(event, result.settled)
            result.unsolicited.append(event)
        return result

    def expire(self, now: float) -> list[PendingQuery]:
        """Settle as timed out every query whose deadline has passed."""
        expired = [query for query in self._pending if self.deadline(query) <= now]
        for query in expired:
            self._settle(query, Outcome.TIMEOUT)
            self.counters.timeouts += 1
        return expired

    def disconnect(self) -> list[PendingQuery]:
        """Settle every pending query as disconnected (the link is gone)."""
        settled = list(self._pending)
        for query in settled:
            self._settle(query, Outcome.DISCONNECTED)
        return settled

    # -- internals ----------------------------------------------------------------------------

    def _count_sent(self, data: bytes, now: float) -> None:
        self.counters.frames_sent += 1
        self.counters.bytes_sent += len(data)
        self.last_sent_at = now

    def _set_mode(self, enabled: bool) -> None:
        self._checksum_enabled = enabled
        self._decoder.checksum_enabled = enabled
        self._query_bytes.clear()
        self._last_query = None

    def _settle(self, query: PendingQuery, outcome: Outcome) -> None:
        pending = self._pending
        if pending[0] is query:
            pending.popleft()
        else:
            pending.remove(query)
        query.outcome = outcome

    def _deliver(self, response: Response, now: float, settled: list[PendingQuery]) -> bool:
        pending = self._pending
        while pending:
            head = pending[0]
            responses = head.responses
            if head.expected[len(responses)] == response.name:
                self._append(head, response, now, settled)
                return True
            if not responses:
                break
            # A half-received reply (qsa) broken by a frame that does not belong in it.
            self._settle(head, Outcome.CORRUPT)
            settled.append(head)
        for index in range(1, len(pending)):
            if pending[index].expected[0] == response.name:
                for lost in list(pending)[:index]:
                    self._settle(lost, Outcome.LOST)
                    settled.append(lost)
                self._append(pending[0], response, now, settled)
                return True
        return False

    def _append(self, query: PendingQuery, response: Response, now: float,
                settled: list[PendingQuery]) -> None:
        query.responses.append(response)
        self._last_progress_at = now
        if len(query.responses) == len(query.expected):
            self._settle(query, _ANSWERED)
            self.counters.replies += 1
            settled.append(query)

    def _bad_frame(self, event: BadFrame, settled: list[PendingQuery]) -> None:
        self.counters.bad_frames += 1
        if event.reason is Reason.CHECKSUM:
            self.counters.checksum_errors += 1
        if event.raw[:1] == b"$" and event.reason in _CORRUPT_REASONS and self._pending:
            head = self._pending[0]
            self._settle(head, Outcome.CORRUPT)
            settled.append(head)
