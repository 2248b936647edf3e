"""The sans-I/O heart of both clients: every protocol decision of the host side, without I/O.

A :class:`Session` owns the checksum mode, the decoder of the controller's byte stream, the queue
of queries waiting for replies, the counters, and the host's rules of PROTOCOL.md: matching
(P4, P12, P20), resynchronisation after a timeout (P20), suspected resets (P21), keep-alive (P17)
and expiring motion (P23). It never touches a port, a thread or a clock: the drivers feed it bytes
and the time, write the bytes it hands them, in order, and wake whoever waits on the queries it
settles. Every rule is therefore tested with byte strings and a fake clock.

Bytes out. :meth:`Session.query` and :meth:`Session.command` return the bytes to write for a
command, preceded by anything the session itself has due (a fence, a mode frame, zero thrust):
its *outbox*. :meth:`Session.tick` (at :meth:`Session.next_deadline`) may fill the outbox too;
the driver writes :meth:`Session.take_outbox` then. Whoever writes next writes the outbox first,
so the wire's order is always the queue's.

Matching (P4, P12). The controller answers queries in the order they arrive, each with the replies
the command table lists (``qsa``: six). A reply goes to the oldest pending query if it is the
reply that query expects next. If instead it is the first reply of a later query, the queries
before it lost their replies (the controller dropped them) and are settled as ``lost`` at once.

Late replies and fences (P20). The protocol has no sequence numbers, so after a query times out
its reply may still come and cannot be told from the reply of a later query of the same name.
When a query fails that way, the session fails with it every query on the wire that expects a
reply of one of the same names, and in turn of theirs (``resync``; the caller retries them),
marks all those names *late*, and writes a *fence*: a query of a name that is not late. Until
the fence's reply arrives, every reply of a late name is a
:class:`~rovlink.client.events.LateReply`, counted and discarded; the controller answers in
order, so nothing sent before the fence can arrive after its reply. If the fence fails, a query
sent behind it whose reply was discarded so fails with it (no query waits for a reply the
session has thrown away). When
every name is late (a ``qsa`` timed out), no fence can be told apart: the session then holds new
queries back until the line has been quiet for twice ``timeout_s`` (:attr:`Session.quiet_window_s`)
— nothing is sent, so nothing new can be confused with what is still on its way.

Resets (P21). After ``reset_after_timeouts`` consecutive timeouts the session suspects the
controller reset (it comes back with checksum mode off, locked): it re-asserts its checksum mode
(``#crcon!``/``#crcoff!`` are recognised in either mode) before the fence, and reports
:class:`~rovlink.client.events.ResetSuspected`: once until a reply comes, though the mode is
re-asserted after every ``reset_after_timeouts`` timeouts (a board still booting loses some).

Timeouts: a query's deadline is ``timeout_s`` after it was sent or after the last reply that
moved the queue, whichever is later — so a deep pipeline on a slow line is not timed out while
replies keep coming, and a dead link times everything out ``timeout_s`` after it went quiet.
"""

from __future__ import annotations

from collections import deque

from rovlink.client.counters import LinkCounters
from rovlink.client.errors import SupersededByStopError
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
    Setting,
    Text,
    encode,
    get_algorithm,
    setting_command,
)
from rovlink.protocol.text_enum import StrEnum
from rovlink.protocol.visible import visible

__all__ = ["FENCE_QUERIES", "KEEPALIVE_QUERY", "Outcome", "PendingQuery", "Received", "Session"]

# A damaged reply (rather than a frame of another kind): the query it belonged to failed.
_CORRUPT_REASONS = frozenset(
    {
        Reason.CHECKSUM,
        Reason.MALFORMED,
        Reason.RANGE,
        Reason.TOO_LONG,
        Reason.TRUNCATED,
    }
)

_QUERY_BYTES_CACHED = 64

#: The query sent when the link has been idle: any valid frame feeds the controller's watchdog
#: (P17), and a query also proves the controller is still answering.
KEEPALIVE_QUERY = Command("qd")
_STOP = Command("stop")
#: How many keep-alives after a ``#stop!`` carry it again, until something moves or unlocks: a
#: ``#stop!`` lost on a noisy line has no reply to miss, and the keep-alive then fed a robot
#: that drove on (P17 never tripped). Idempotent on a robot that got it.
STOP_REPEATS = 2
#: Fence candidates, in order of preference: single-reply queries.
FENCE_QUERIES = (
    Command("qhe"),
    Command("qd"),
    Command("qro"),
    Command("qpi"),
    Command("qr"),
    Command("q.l"),
)


class Outcome(StrEnum):
    """What became of one attempt of a query."""

    PENDING = "pending"
    ANSWERED = "answered"
    TIMEOUT = "timeout"  # nothing came in time
    CORRUPT = "corrupt"  # its reply failed the checksum or was malformed
    LOST = "lost"  # the controller answered a later query first
    RESYNC = "resync"  # on the wire when a query of the same reply name failed (P20)
    DISCONNECTED = "disconnected"
    ABANDONED = "abandoned"  # its caller gave up (Ctrl-C) before its reply was settled


_NEVER = float("inf")
# Plain names for the members used per reply: an enum member costs a descriptor call to look up.
_PENDING = Outcome.PENDING
_ANSWERED = Outcome.ANSWERED


def _is_motion_command(command: Command | None) -> bool:
    return command is not None and command.spec.motion and not command.spec.is_query


class PendingQuery:
    """One query on the wire (or held back, during a quiet-line resynchronisation)."""

    # What most queries keep as it is starts as a class default, not a slot: a polling loop
    # makes one of these a query, and every attribute set in __init__ costs it.
    #: A keep-alive of the session's (P17).
    keepalive: bool = False
    #: The checksum mode it went out in, once the mode has changed behind it: its replies
    #: come in that mode (P3). None: the session's mode now.
    sent_checksummed: bool | None = None
    #: Sent by the session itself (a keep-alive or a fence): nobody waits for it.
    internal: bool = False
    #: A query sent again after an attempt of it failed (not a new one of the program's).
    retry: bool = False
    outcome: Outcome = _PENDING
    #: The client's handle to wake the caller (an ``asyncio.Future``), if it needs one.
    waiter: object = None

    # (Exactly these arguments, no defaults: the interpreter then makes one without the generic
    # call path, 60 ns less on 3.13.)
    def __init__(self, command: Command, sent_at: float) -> None:
        self.command = command
        self.sent_at = sent_at
        #: The names of the replies, in order.
        self.expected: tuple[str, ...] = command.spec.replies
        self.responses: list[Response] = []

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

    # Slots: the hot path reads and writes these per query, and an instance of more than 30
    # attributes loses the interpreter's fast attribute access.
    __slots__ = (
        "_algorithm",
        "_checksum_enabled",
        "_consecutive_timeouts",
        "_decoder",
        "_direct_mode",
        "_direction_deg",
        "_fence",
        "_fragment",
        "_fragment_head",
        "_held",
        "_last_progress_at",
        "_last_query",
        "_last_query_bytes",
        "_late_names",
        "_late_program_names",
        "_late_reply_at",
        "_locked_as_sent",
        "_motion_renewed_at",
        "_moved_since_stop",
        "_old_mode_queries",
        "_outbox",
        "_pending",
        "_power_percent",
        "_query_bytes",
        "_quiet_until",
        "_raw_decoder",
        "_readying",
        "_reset_reported_at",
        "_stop_on_reopen",
        "_stop_repeats_due",
        "_stops_asked",
        "_unsure_motion",
        "_vertical_percent",
        "counters",
        "events",
        "keepalive_s",
        "last_sent_at",
        "motion_timeout_s",
        "notices",
        "own_queries",
        "reset_after_timeouts",
        "reset_notices",
        "timeout_s",
    )

    def __init__(
        self,
        *,
        checksum_enabled: bool = False,
        algorithm: str | ChecksumAlgorithm = DEFAULT_ALGORITHM,
        timeout_s: float = 0.5,
        keepalive_s: float | None = None,
        motion_timeout_s: float | None = None,
        reset_after_timeouts: int = 2,
        record_events: bool = False,
    ) -> None:
        self._algorithm = get_algorithm(algorithm)
        self._checksum_enabled = checksum_enabled
        self._decoder = Decoder(checksum_enabled=checksum_enabled, algorithm=self._algorithm)
        # The queries on the wire when the checksum mode changed, oldest first: their replies
        # come in the mode they were sent in (P3), which the decoder takes until they settle.
        self._old_mode_queries: tuple[PendingQuery, ...] = ()
        self._raw_decoder = Decoder(algorithm=self._algorithm)
        self._pending: deque[PendingQuery] = deque()
        # Queries are few and repeat: their bytes in the current mode, encoded once.
        self._query_bytes: dict[Command, bytes] = {}
        self._last_query: Command | None = None  # the last query encoded, and its bytes
        self._last_query_bytes = b""
        self.timeout_s = timeout_s
        self.keepalive_s = keepalive_s or None
        self.motion_timeout_s = motion_timeout_s or None
        self.reset_after_timeouts = reset_after_timeouts
        #: Whether a suspected reset is a notice (a warning the driver logs) besides an event:
        #: not while the driver confirms the checksum mode on connecting, where timeouts mean
        #: a controller on another algorithm or without the mode, which its error then says.
        self.reset_notices = True
        #: Whether the queries asked now are the driver's own (its confirmation of the checksum
        #: mode on connecting): their frames are ``by_session``, as a fence's are, and a replay
        #: of a recording leaves them out (it was resent as the program's).
        self.own_queries = False
        self.counters = LinkCounters()
        self.last_sent_at = float("-inf")
        self._last_progress_at = float("-inf")
        # Bytes the session has due, and the queries among them, in wire order.
        self._outbox: list[tuple[bytes, PendingQuery | None, Command | None]] = []
        # P20: reply names that are late until the fence is answered (or the line is quiet).
        self._late_names: set[str] = set()
        # Those of them that a program's query failed with (the rest: keep-alives', fences').
        self._late_program_names: set[str] = set()
        # When a reply of each name was last discarded as late.
        self._late_reply_at: dict[str, float] = {}
        self._fence: PendingQuery | None = None
        self._quiet_until: float | None = None  # holding queries until then (no fence possible)
        self._held: deque[PendingQuery] = deque()
        # A fragment decoded at the end of a read, and the oldest query then (see _bad_frame).
        self._fragment: BadFrame | None = None
        self._fragment_head: PendingQuery | None = None
        self._consecutive_timeouts = 0
        # P21: when a suspected reset was last reported; reported again only after a reply.
        self._reset_reported_at: float | None = None
        #: A #stop! asked for while the link was down: the reopened link's first frame.
        self._stop_on_reopen = False
        self._stops_asked = 0  # stop() calls so far (see stop_asked)
        #: A reopened link is open and being readied (P21): a #stop! goes on it at once.
        self._readying = False
        # P23: the motion as last sent, and when it was last renewed; the vertical mode as
        # last sent (None: not known, as on a link reopened to a board that may have reset).
        self._direct_mode: bool | None = None
        self._direction_deg = 0
        self._power_percent = 0
        self._vertical_percent = 0
        self._motion_renewed_at = float("-inf")
        # A command that moves or unlocks was sent since the last #stop! (close() stops then),
        # and whether the motors are locked as last sent (None: not known, as on connecting).
        self._moved_since_stop = False
        self._locked_as_sent: bool | None = None
        self._stop_repeats_due = 0
        # The names of motion commands (th, mvs) whose write failed with the link: on that
        # axis the controller may drive on with the thrust before, or with theirs.
        self._unsure_motion: set[str] = set()
        #: Events since the driver last took them (only while someone subscribes).
        self.events: list[ClientEvent] | None = [] if record_events else None
        #: The rare events a driver logs as warnings whether or not anyone subscribes.
        self.notices: list[ClientEvent] = []

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
        """Queries waiting for replies, oldest first (held ones last)."""
        return (*self._pending, *self._held)

    @property
    def resynchronising(self) -> bool:
        """Whether replies of some names are being discarded as late (P20)."""
        return bool(self._late_names)

    @property
    def on_the_wire(self) -> tuple[PendingQuery, ...]:
        """The queries written and waiting for replies, oldest first: :attr:`pending`, less
        those held back and those still due in the outbox (a fence not yet written)."""
        unwritten = {id(entry[1]) for entry in self._outbox}
        return tuple(query for query in self._pending if id(query) not in unwritten)

    @property
    def has_outbox(self) -> bool:
        """Whether the session has bytes due that the driver should write now."""
        return bool(self._outbox)

    def deadline(self, query: PendingQuery) -> float:
        """When ``query`` times out unless a reply moves the queue before."""
        if query.outcome is _PENDING and query in self._held:
            return float("inf")  # not on the wire yet: it cannot time out
        return max(query.sent_at, self._last_progress_at) + self.timeout_s

    @property
    def quiet_window_s(self) -> float:
        """How long the line must be quiet before queries held back for it go out (P20): twice
        ``timeout_s``. A controller that stalled answering a query sent just before the timeout
        may owe that reply for up to one timeout more: a window of one timeout released the
        retries into it."""
        return 2.0 * self.timeout_s

    def next_deadline(self) -> float | None:
        """When :meth:`tick` has something to do next, if ever."""
        # (Called per query by the drivers: no list, no generator.)
        due = _NEVER
        pending = self._pending
        if pending:
            # Deadlines share the last-progress term, so the oldest query's is the earliest.
            head = pending[0]
            progress = self._last_progress_at
            due = (head.sent_at if head.sent_at > progress else progress) + self.timeout_s
        quiet_until = self._quiet_until
        if quiet_until is not None and quiet_until < due:
            due = quiet_until
        if self.motion_timeout_s and (self._power_percent or self._vertical_percent):
            due = min(due, self._motion_renewed_at + self.motion_timeout_s)
        if self.keepalive_s:
            due = min(due, self.last_sent_at + self.keepalive_s)
        return None if due == _NEVER else due

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

    @property
    def stops_asked(self) -> int:
        """How many times the program has asked for a stop (:meth:`stop_asked`): a driver
        notes it when a command is asked for, and hands it to :meth:`command` or :meth:`raw`
        with the command."""
        return self._stops_asked

    @property
    def moved_since_stop(self) -> bool:
        """Whether a command that moves the robot or unlocks its motors (``Spec.moves_or_unlocks``)
        was sent since the last ``#stop!``: a driver that closes sends one then. A motion
        command sent after a ``#stop!`` and before a ``#start!`` does not count: the controller
        drops it (P7).

        >>> session = Session()
        >>> _ = session.command(Command("th", (90, 40)), now=0.0)
        >>> session.moved_since_stop
        True
        >>> _ = session.command(Command("stop"), now=1.0)
        >>> session.moved_since_stop
        False
        """
        return self._moved_since_stop

    def stop_asked(self) -> None:
        """The program called ``stop()`` (before its ``#stop!`` is written, which may wait).

        A command that moves the robot or unlocks its motors (``Spec.moves_or_unlocks``) asked
        for before that, and not yet handed out, is superseded: :meth:`command` and :meth:`raw`
        raise :class:`~rovlink.client.errors.SupersededByStopError` for it rather than let it
        follow the ``#stop!`` and undo it. Queries and the other commands still go.

        >>> session = Session()
        >>> asked_at = session.stops_asked  # a start() is asked for, and waits to be written
        >>> session.stop_asked()  # meanwhile, a stop() from another thread
        >>> session.command(Command("start"), now=0.0, stops_seen=asked_at)
        Traceback (most recent call last):
        ...
        rovlink.client.errors.SupersededByStopError: #start! not sent: ...
        >>> session.command(Command("mgmp", (180,)), now=0.0, stops_seen=asked_at)
        b'#mgmp.180!'
        """
        self._stops_asked += 1

    def _check_not_superseded(self, command: Command, stops_seen: int | None) -> None:
        if (
            stops_seen is not None
            and stops_seen != self._stops_asked
            and command.spec.moves_or_unlocks
        ):
            raise SupersededByStopError(command)

    def command(
        self,
        command: Command,
        now: float,
        *,
        stops_seen: int | None = None,
        by_session: bool = False,
    ) -> bytes:
        """The bytes to write for a command that expects no reply (after anything due).

        ``crcon``/``crcoff`` switch the session's mode with the controller's. ``stops_seen``:
        :attr:`stops_asked` when the program asked for the command; a command that moves or
        unlocks raises :class:`~rovlink.client.errors.SupersededByStopError` if a stop was
        asked for since (see :meth:`stop_asked`), and nothing is sent. ``by_session``: the
        driver sends it of itself (the mode frame on connecting), not the program.
        """
        if command.spec.is_query:
            raise ValueError(f"{command} is a query: use Session.query")
        self._check_not_superseded(command, stops_seen)
        data = self.take_outbox(now)  # (first: what is due goes, and is accounted, first)
        data += self._account(command, self.frame_for(command), now, by_session=by_session)
        self._track(command, now)
        return data

    def motion_as_sent(self) -> tuple[int, int, int]:
        """The motion as last sent: direction, horizontal and vertical thrust (for
        :meth:`write_interrupted`)."""
        return self._direction_deg, self._power_percent, self._vertical_percent

    def write_interrupted(self, before: tuple[int, int, int]) -> None:
        """The write of the last command was interrupted (a Ctrl-C), so it may or may not have
        reached the controller: a thrust that it would have cleared is kept as sent (``before``,
        from :meth:`motion_as_sent`), so that an expiry (P23) or a reopened link still zeroes
        what the controller may have. Believing it zero let the keep-alive feed a robot that
        drove on."""
        direction_deg, power_percent, vertical_percent = before
        if power_percent and not self._power_percent:
            self._direction_deg, self._power_percent = direction_deg, power_percent
        if vertical_percent and not self._vertical_percent:
            self._vertical_percent = vertical_percent

    def write_failed(self, data: bytes) -> None:
        """Bytes this session handed out were cut off by the loss of the link: the commands
        among them may or may not have reached the controller. A motion command among them
        (zero thrust of an expired motion, P23, included) leaves its axis's thrust unknown, so
        a reopened link zeroes that axis first; a ``#stop!`` among them is sent first on it.
        Believing them delivered let a reopened link's probes feed the watchdog (P17) of a
        controller driving on.

        >>> session = Session()
        >>> _ = session.command(Command("th", (90, 40)), now=0.0)
        >>> session.write_failed(session.command(Command("th", (90, 0)), now=1.0))
        >>> session.rest_frames()
        b'#th.90.0!'
        """
        for command in self._commands_in(data):
            if command == _STOP:
                self._stop_on_reopen = True
            elif _is_motion_command(command):
                self._unsure_motion.add(command.name)

    def _commands_in(self, data: bytes) -> list[Command]:
        """The commands in bytes this session wrote, in either checksum mode (a mode frame
        among them switched it halfway)."""
        commands = []
        for checksum_enabled in (False, True):
            decoder = Decoder(checksum_enabled=checksum_enabled, algorithm=self._algorithm)
            commands += [
                Command(event.message.name, event.message.values)
                for event in decoder.feed(data)
                if isinstance(event, Frame) and event.message.kind is Kind.COMMAND
            ]
        return commands

    def query(
        self, command: Command, now: float, *, retry: bool = False
    ) -> tuple[bytes, PendingQuery]:
        """The bytes to write for a query (after anything due), and its entry in the queue.

        Write the bytes before anything else is written: the queue's order is the wire's.
        While a quiet-line resynchronisation holds queries back, the query is queued to be sent
        later (by :meth:`tick`) and only what is due is returned. ``retry``: the query again,
        after an attempt of it failed (its event says so: a recording's replay sends it once).
        """
        pending = PendingQuery(command, now)
        if retry:
            pending.retry = True
        if self._quiet_until is not None:
            self._held.append(pending)
            return self.take_outbox(now), pending
        data = self.take_outbox(now) if self._outbox else b""
        frame = self.query_bytes(command)
        self._account(command, frame, now, by_session=self.own_queries, retry=retry)
        self._pending.append(pending)
        return data + frame, pending

    def fast_query(self, command: Command, now: float) -> tuple[bytes, PendingQuery] | None:
        """:meth:`query` when nothing is due and nothing held (the usual case), else ``None``.

        For drivers that write the bytes the moment they have them.
        """
        if self._outbox or self._quiet_until is not None:
            return None
        # (query_bytes's own shortcut, without the call: a polling loop's query again)
        data = self._last_query_bytes if command is self._last_query else self.query_bytes(command)
        counters = self.counters
        counters.frames_sent += 1
        counters.bytes_sent += len(data)
        self.last_sent_at = now
        if self.events is not None:
            self.events.append(BytesSent(now, data, command, self.own_queries))
        pending = PendingQuery(command, now)
        self._pending.append(pending)
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

    def raw_command(self, frame: bytes) -> Command | None:
        """The command a raw frame carries, read as the controller will read it in the current
        checksum mode (``None``: text or a broken frame); more than one is a ValueError.

        >>> Session().raw_command(b"#qd!"), Session().raw_command(b"hello")
        (Command(name='qd', values=()), None)
        """
        self._raw_decoder.checksum_enabled = self._checksum_enabled
        self._raw_decoder.reset()
        commands = [
            Command(event.message.name, event.message.values)
            for event in self._raw_decoder.feed(frame)
            if isinstance(event, Frame) and event.message.kind is Kind.COMMAND
        ]
        if len(commands) > 1:  # (the motion and the replies of all of them would go untracked)
            listed = ", ".join(str(command) for command in commands)
            raise ValueError(
                f"send_raw sends one frame at a time: '{visible(frame.decode('latin-1'))}' holds "
                f"{len(commands)} commands ({listed}); send each on its own"
            )
        return commands[0] if commands else None

    def raw(
        self, frame: bytes, now: float, *, stops_seen: int | None = None
    ) -> tuple[bytes, PendingQuery | None]:
        """The bytes to write for a raw frame sent as it is (after anything due); a query in it
        joins the queue. Text or broken frames around it go as they are; more than one command
        frame is a ValueError (nothing is sent). ``stops_seen``: as for :meth:`command`.

        The frame is read as the controller will read it, in the current checksum mode, so that
        a raw ``#crcon!`` switches the session too and a raw query is matched like any other.
        """
        command = self.raw_command(frame)
        if command is not None:
            self._check_not_superseded(command, stops_seen)
        data = self.take_outbox(now) + self._account(command, frame, now)
        if command is None:
            return data, None
        self._track(command, now)
        if not command.spec.is_query:
            return data, None
        pending = PendingQuery(command, now)
        self._pending.append(pending)
        return data, pending

    def take_outbox(self, now: float) -> bytes:
        """The bytes the session has due (empty if none), to be written now, before anything else.

        Their queries' deadlines start now.
        """
        if not self._outbox:
            return b""
        parts = []
        for data, pending, command in self._outbox:
            if pending is None or pending.internal:
                self._account(command, data, now, by_session=True)
            else:  # a program's query, held back during a resynchronisation (P20)
                self._account(command, data, now, retry=pending.retry)
            if pending is not None:
                pending.sent_at = now
            parts.append(data)
        self._outbox.clear()
        return b"".join(parts)

    def take_outbox_when_closing(self, now: float) -> bytes:
        """:meth:`take_outbox` for a driver that is closing: only the zero thrust of an expired
        motion (P23) is to be written, so that the robot stops as it would without the close.
        A fence, a keep-alive or a mode frame would start what nobody follows any more: they
        are dropped (their queries settle when the driver disconnects).
        """
        stops = [entry for entry in self._outbox if _is_motion_command(entry[2])]
        self._outbox.clear()
        return b"".join(
            self._account(command, data, now, by_session=True) for data, _, command in stops
        )

    # -- receiving ----------------------------------------------------------------------------

    def receive(self, data: bytes, now: float) -> Received:
        """Decode bytes from the controller; settle the queries they answer or break."""
        if self._old_mode_queries:
            return self._receive_across_mode_change(data, now)
        return self._receive_events(self._decoder.feed(data), data, now)

    def _receive_across_mode_change(self, data: bytes, now: float) -> Received:
        """:meth:`receive` while queries sent before a checksum mode change are unsettled:
        the bytes are decoded a frame at a time, each in the mode of the oldest query still
        waiting (P3: a mode change never reaches back)."""
        result = Received()
        rest = data
        while rest:
            if self._decode_in_reply_mode():
                end = rest.find(b"!") + 1 or len(rest)
                piece, rest = rest[:end], rest[end:]
            else:
                piece, rest = rest, b""
            part = self._receive_events(self._decoder.feed(piece), piece, now)
            result.settled += part.settled
            result.unsolicited += part.unsolicited
        self._decode_in_reply_mode()
        return result

    def _decode_in_reply_mode(self) -> bool:
        """Put the decoder in the mode of the oldest query on the wire still waiting; whether
        a query sent before a mode change still waits."""
        waiting = self._old_mode_queries
        while waiting and waiting[0].settled:
            waiting = waiting[1:]
        self._old_mode_queries = waiting
        mode = waiting[0].sent_checksummed if waiting else None
        self._decoder.checksum_enabled = self._checksum_enabled if mode is None else mode
        return bool(waiting)

    def _receive_events(self, decoded: list[Event], data: bytes, now: float) -> Received:
        """:meth:`receive` once ``data`` is decoded (into ``decoded``)."""
        counters = self.counters
        counters.bytes_received += len(data)
        events = self.events
        if events is not None:
            events.append(BytesReceived(now, data))
        result = Received()
        if self._fragment is not None and decoded:
            self._decide_fragment(decoded[0], now, result.settled)
        pending = self._pending
        late_names = self._late_names
        for index, event in enumerate(decoded):
            if isinstance(event, Frame):
                message = event.message
                if isinstance(message, Response):
                    counters.frames_received += 1
                    self._consecutive_timeouts = 0
                    if late_names and message.name in late_names:
                        self._late(message, now)
                        continue
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
                                if head is self._fence:
                                    self._end_resync()
                                if events is not None:
                                    events.append(
                                        ReplyReceived(now, head.command, tuple(responses))
                                    )
                                if not head.internal:
                                    result.settled.append(head)
                            continue
                    if self._deliver(message, now, result.settled):
                        continue
                counters.stray_frames += 1
            elif isinstance(event, Text):
                counters.text_lines += 1
                if not event.text.isprintable():
                    counters.noise_bytes += len(event.text)
            else:
                following = decoded[index + 1] if index + 1 < len(decoded) else None
                self._bad_frame(event, following, now, result.settled)
            result.unsolicited.append(event)
            if events is not None:
                events.append(Unsolicited(now, event))
        return result

    def receive_reply(self, data: bytes, now: float) -> PendingQuery | Received:
        """:meth:`receive`, with a shortcut for a driver's usual case: ``data``, read as it
        arrived, is exactly the one reply frame that completes the oldest query on the wire,
        and nothing else is going on (no resynchronisation, no events to record). Then that
        query is settled and returned; anything else is received as :meth:`receive` does, and
        its result returned.

        >>> session = Session()
        >>> _, query = session.query(Command("qd"), now=0.0)
        >>> session.receive_reply(b"$qd.7!", now=0.001) is query, query.responses
        (True, [Response(name='qd', values=(7,))])
        >>> _, query = session.query(Command("qd"), now=0.002)
        >>> session.receive_reply(b"boot\\r\\n$qd.8!", now=0.003).settled == [query]
        True
        """
        pending = self._pending
        if self.events is not None or self._late_names or not pending or self._old_mode_queries:
            return self.receive(data, now)
        query = pending[0]
        expected = query.expected
        if len(expected) != 1 or query.responses:
            return self.receive(data, now)
        decoder = self._decoder
        reply = decoder.reply_message(data, expected[0])
        if reply is None:  # not that reply, whole, or one reply_message leaves to the rest
            message = decoder.frame_message(data)
            if message is None:  # not one whole frame of values: nothing read yet
                return self.receive(data, now)
            if type(message) is not Response or message.name != expected[0]:
                return self._receive_events([Frame(message, data)], data, now)
            reply = message
        # What _receive_events does for this frame, in the same order.
        counters = self.counters
        counters.bytes_received += len(data)
        counters.frames_received += 1
        self._consecutive_timeouts = 0
        query.responses.append(reply)
        self._last_progress_at = now
        pending.popleft()
        query.outcome = _ANSWERED
        counters.replies += 1
        return query

    # -- time ---------------------------------------------------------------------------------

    def tick(self, now: float) -> list[PendingQuery]:
        """Do what is due at ``now``: time out queries, end a quiet-line wait, expire motion,
        keep the link alive. Returns the queries settled; afterwards, write :meth:`take_outbox`.
        """
        settled = self.expire(now)
        if self._quiet_until is not None and now >= self._quiet_until:
            self._end_resync()
            self._release_held(now)
        if (
            self.motion_timeout_s
            and (self._power_percent or self._vertical_percent)
            and now - self._motion_renewed_at >= self.motion_timeout_s
        ):
            self._expire_motion(now)
        if self.keepalive_s and not self._outbox and now - self.last_sent_at >= self.keepalive_s:
            self.counters.keepalives += 1
            if self._quiet_until is None:
                if self._stop_repeats_due:
                    self._stop_repeats_due -= 1
                    self._outbox.append((self.frame_for(_STOP), None, _STOP))
                pending = PendingQuery(KEEPALIVE_QUERY, now)
                pending.keepalive = pending.internal = True
                self._pending.append(pending)
                self._outbox.append((self.query_bytes(KEEPALIVE_QUERY), pending, KEEPALIVE_QUERY))
            else:
                # Waiting for a quiet line (P20), no query may go: the checksum mode as it is
                # (no reply, no change) keeps the controller's link-loss failsafe fed instead.
                # Else a timed-out qsa left the line silent for its timeout and the wait, 1.5 s
                # by default, and a damaged frame or two around that gap tripped the failsafe.
                self._outbox.append(self._mode_entry())
        return settled

    def expire(self, now: float) -> list[PendingQuery]:
        """Settle as timed out the query whose deadline has passed, and resynchronise (P20)."""
        settled: list[PendingQuery] = []
        while self._pending and self.deadline(self._pending[0]) <= now:
            self.counters.timeouts += 1
            self._consecutive_timeouts += 1
            settled += self._fail(self._pending[0], Outcome.TIMEOUT, now)
            if self._consecutive_timeouts >= self.reset_after_timeouts:
                self._suspect_reset(now)
        return settled

    def abandon(self, query: PendingQuery, now: float) -> list[PendingQuery]:
        """Give up a query whose caller has gone (a Ctrl-C) before its reply was settled.

        Whether its frame reached the wire, or its reply was read and went with the caller, is
        not known: it fails as abandoned and the session resynchronises (P20), so that no later
        query takes a reply meant for it. A query held back (not on the wire) is only dropped.
        Returns the other queries settled with it (resynchronised), for their callers.

        >>> session = Session()
        >>> _, query = session.query(Command("qd"), now=0.0)
        >>> session.abandon(query, now=0.1), query.outcome.value, session.resynchronising
        ([], 'abandoned', True)
        """
        if query.outcome is not _PENDING:
            return []
        if query in self._held:
            self._held.remove(query)
            query.outcome = Outcome.ABANDONED
            return []
        if query not in self._pending:
            return []
        return [other for other in self._fail(query, Outcome.ABANDONED, now) if other is not query]

    def disconnect(self) -> list[PendingQuery]:
        """Settle every pending query as disconnected (the link is gone)."""
        settled = [*self._pending, *self._held]
        for query in settled:
            query.outcome = Outcome.DISCONNECTED
        self._pending.clear()
        self._held.clear()
        self._outbox.clear()
        return [query for query in settled if not query.internal]

    def count_outside(self, now: float, *, sent: bytes = b"", received: bytes = b"") -> None:
        """Count bytes a driver moved outside the session (the readiness probe, P21), so that
        the link counters stay whole and a recording of the wire has every byte."""
        counters = self.counters
        counters.frames_sent += sent.count(b"!")
        counters.bytes_sent += len(sent)
        counters.bytes_received += len(received)
        events = self.events
        if events is not None:
            if sent:
                events.append(BytesSent(now, sent, None, by_session=True))
            if received:
                events.append(BytesReceived(now, received))

    def rest_frames(self) -> bytes:
        """Zero thrust for the motion as last sent, in the current checksum mode (empty if it is
        at rest): what a reopened link carries first, before its readiness probe (P21).

        A board that reset is at rest (P21), but a link that dropped and came back (a TCP
        connection, a loose cable) may find the controller still driving the thrust last sent,
        in the mode it was in, and every probe would feed its link-loss watchdog (P17). The
        motion stays as last sent: a reopened link that fails gets these again on the next
        one, until :meth:`link_ready`.

        >>> session = Session()
        >>> _ = session.command(Command("th", (90, 40)), now=0.0)
        >>> session.rest_frames()
        b'#th.90.0!'
        >>> session.stop_while_reconnecting(now=1.0)  # no link open: kept for the next one
        b''
        >>> session.rest_frames()
        b'#stop!'
        """
        return b"".join(self.frame_for(command) for command in self._rest_commands())

    def link_reopened(self) -> bytes:
        """A lost link is open again and being readied (its readiness probe, P21): the bytes it
        carries first (:meth:`rest_frames`, to be written before the probe). Until
        :meth:`link_ready` or :meth:`reopen_failed`, :meth:`stop_while_reconnecting` returns a
        ``#stop!`` to write on it at once."""
        self._readying = True
        return self.rest_frames()

    def reopen_failed(self) -> None:
        """The reopened link failed before it was ready: it is closed, and a ``#stop!`` asked
        for from now on waits for the next one."""
        self._readying = False

    def stop_while_reconnecting(self, now: float) -> bytes:
        """``#stop!`` asked for while the link is being reopened: the bytes to write now.

        While the reopened link is being readied (:meth:`link_reopened`), the ``#stop!`` to
        write on it at once: the controller may be driving the thrust last sent while it
        answers the probe slowly, and the stop has no reply to confuse the probe's. While no
        link is open, nothing: the stop is the reopened link's first frame (in place of zero
        thrust: it clears every set-point, P7). Either way it is sent once more when the link
        is ready (:meth:`reset_link`), before anything the program sends afterwards: a board
        still booting loses its input (P21).

        >>> session = Session()
        >>> _ = session.command(Command("th", (90, 40)), now=0.0)
        >>> session.link_reopened()
        b'#th.90.0!'
        >>> session.stop_while_reconnecting(now=1.0)
        b'#stop!'
        """
        self._stop_on_reopen = True
        if not self._readying:
            return b""
        data = self._account(_STOP, self.frame_for(_STOP), now)
        self._track(_STOP, now)
        return data

    def hand_over_stop(self) -> None:
        """``#stop!`` asked for while the reopened link is busy with another write (a line
        that takes nothing holds it until the write gives up): kept, as while no link is open,
        and the writer asks :meth:`stop_while_reconnecting` for its bytes next."""
        self._stop_on_reopen = True

    def reset_link(self) -> None:
        """Start afresh on a reopened link that answered: no partial frame, nothing late, and
        nothing due but the checksum mode, then zero thrust if the motion last sent was not at
        rest (write :meth:`take_outbox` next, then call :meth:`link_ready`).

        The mode comes first: the readiness probe left the controller in plain mode (P21), in
        which a checksummed frame is dropped. The motion a program or a pilot commanded before
        the loss is never resumed unasked. (The queries of the old link were settled by
        :meth:`disconnect`.)
        """
        self._decoder.reset()
        self._old_mode_queries = ()
        self._decode_in_reply_mode()
        self._fragment = self._fragment_head = None
        self._outbox.clear()
        self._end_resync()
        self._consecutive_timeouts = 0
        self._reset_reported_at = None
        self._outbox.append(self._mode_entry())
        for command in self._rest_commands():
            self._outbox.append((self.frame_for(command), None, command))

    def link_ready(self) -> None:
        """The reopened link is the connection's now: :meth:`reset_link`'s bytes were written
        on it. Only now are a stop asked for while it was down, and the motion as last sent,
        taken as done: a link that fails on that write (:meth:`reopen_failed`) leaves the next
        one to carry them first again."""
        self._stop_on_reopen = self._readying = False
        self._unsure_motion.clear()
        self._power_percent = self._vertical_percent = 0
        self._direct_mode = None

    def note_link(self, state: str, detail: str, now: float) -> None:
        """Record a change of the link itself (``lost``, ``reconnected``) for the drivers."""
        self._note(LinkState(now, state, detail))

    def record_events(self) -> None:
        """Start recording events (for a subscriber that arrives after the connection)."""
        if self.events is None:
            self.events = []

    def take_events(self) -> list[ClientEvent]:
        """The events since the last call (empty unless the session records them)."""
        events = self.events
        if not events:
            return []
        self.events = []
        return events

    def take_notices(self) -> list[ClientEvent]:
        """The notices (suspected resets, expired motion) since the last call."""
        notices = self.notices
        if not notices:
            return []
        self.notices = []
        return notices

    # -- internals ----------------------------------------------------------------------------

    def _note(self, event: ClientEvent) -> None:
        self.notices.append(event)
        if self.events is not None:
            self.events.append(event)

    def _account(
        self,
        command: Command | None,
        data: bytes,
        now: float,
        *,
        by_session: bool = False,
        retry: bool = False,
    ) -> bytes:
        counters = self.counters
        counters.frames_sent += 1
        counters.bytes_sent += len(data)
        if retry:  # (counted as written: one held back and never sent was no retry)
            counters.retries += 1
        self.last_sent_at = now
        if self.events is not None:
            self.events.append(BytesSent(now, data, command, by_session, retry))
        setting = command.setting if command is not None else None
        if setting is not None and setting[0] is Setting.CHECKSUM:
            self._set_mode(setting[1], now)
        return data

    def _set_mode(self, enabled: bool, now: float) -> None:
        if enabled != self._checksum_enabled and self.events is not None:
            self.events.append(ModeChanged(now, Setting.CHECKSUM, enabled))
        previous = self._checksum_enabled
        self._checksum_enabled = enabled
        if enabled != previous:
            # The replies of the queries on the wire come in the mode they were sent in (P3).
            waiting = tuple(query for query in self.on_the_wire if not query.settled)
            for query in waiting:
                if query.sent_checksummed is None:
                    query.sent_checksummed = previous
            self._old_mode_queries = waiting
        self._decode_in_reply_mode()
        self._query_bytes.clear()
        self._last_query = None

    def _track(self, command: Command, now: float) -> None:
        """Keep the motion as sent, for P23 (``mvd`` holds a depth: it is not relayed thrust)."""
        spec = command.spec
        # (A motion command while the motors are locked as last sent is dropped, P7: unless a
        # #start! follows it, it moves nothing.)
        if spec.moves_or_unlocks and (self._locked_as_sent is not True or not spec.motion):
            self._moved_since_stop = True
            self._stop_repeats_due = 0
        name = command.name
        if name == "th":
            self._direction_deg, self._power_percent = command.values
            if self._power_percent:
                self._motion_renewed_at = now
        elif name == "mvs":
            (self._vertical_percent,) = command.values
            if self._vertical_percent:
                self._motion_renewed_at = now
        elif command.setting is not None:
            # Cleared only where the controller surely clears it: a belief of thrust it no
            # longer has costs a needless zero; a belief of none where it has some would let it
            # drive on. So not on #start! (while unlocked it changes nothing, P7) nor on
            # #mvdirect to the mode it is in, or to an unknown one (P9).
            setting, value = command.setting
            if setting is Setting.LOCKED:
                self._locked_as_sent = value
            if setting is Setting.LOCKED and value:  # stop: every set-point cleared (P7)
                self._power_percent = self._vertical_percent = 0
                self._moved_since_stop = False
                self._stop_repeats_due = STOP_REPEATS
            elif setting is Setting.DIRECT_MODE:
                if self._direct_mode is not None and value != self._direct_mode:
                    self._vertical_percent = 0  # a change of mode sets it to 0 (P9)
                self._direct_mode = value

    def _rest_commands(self) -> list[Command]:
        """What a reopened link carries first: a ``#stop!`` asked for while it was down, else
        zero thrust for the motion as last sent (none if it is at rest)."""
        return [_STOP] if self._stop_on_reopen else self._zeroing_commands()

    def _zeroing_commands(self) -> list[Command]:
        """The commands that bring the motion as last sent to rest (none if it is)."""
        commands = []
        unsure = self._unsure_motion
        if self._power_percent or "th" in unsure:
            commands.append(Command("th", (self._direction_deg, 0)))
        if self._vertical_percent or "mvs" in unsure:
            commands.append(Command("mvs", (0,)))
        return commands

    def _expire_motion(self, now: float) -> None:
        commands = self._zeroing_commands()
        self._power_percent = self._vertical_percent = 0
        for command in commands:
            self._outbox.append((self.frame_for(command), None, command))
        self.counters.motion_expiries += 1
        self._note(MotionExpired(now, tuple(commands)))

    def _suspect_reset(self, now: float) -> None:
        """P21: re-assert the checksum mode (before any fence) and report the suspicion, once
        until a reply comes: a board still booting loses the first re-assertion, so it is
        repeated, but a silent line is one suspected reset, not one per pair of timeouts."""
        reported_at = self._reset_reported_at
        # (>=: a reply read at the very clock reading of the report came after it, as a
        # report is made at a deadline, which is after the last reply.)
        if reported_at is None or self._last_progress_at >= reported_at:
            self._reset_reported_at = now
            self.counters.resets_suspected += 1
            suspected = ResetSuspected(now, self._consecutive_timeouts)
            if self.reset_notices:
                self._note(suspected)
            elif self.events is not None:
                self.events.append(suspected)
        self._consecutive_timeouts = 0
        self._outbox.insert(0, self._mode_entry())

    def _mode_entry(self) -> tuple[bytes, None, Command]:
        """The outbox entry that asserts the checksum mode as it is (``#crcon!``/``#crcoff!``:
        no reply; a controller in that mode already is unchanged)."""
        mode = setting_command(Setting.CHECKSUM, self._checksum_enabled)
        return self.frame_for(mode), None, mode

    def _fail(self, query: PendingQuery, outcome: Outcome, now: float) -> list[PendingQuery]:
        """``query`` failed while its reply may still come: fail every query on the wire that
        expects a reply of the same names, and so on with theirs, mark all those names late,
        and fence (P20)."""
        late = set(query.expected[len(query.responses) :])
        query.outcome = outcome
        self._spread_failure(late)
        fence = self._fence
        if fence is not None and fence.outcome is not _PENDING:
            # The fence failed (its own reply lost): a query written after it whose reply came
            # meanwhile, while its name was late, had that reply discarded, and fails too.
            for other in self._pending:
                names = other.expected[len(other.responses) :]
                if other.outcome is _PENDING and any(
                    self._late_reply_at.get(name, -_NEVER) >= other.sent_at for name in names
                ):
                    other.outcome = Outcome.RESYNC
                    late.update(names)
            self._spread_failure(late)
        failed = [query]
        failed += (other for other in self._pending if other.outcome is Outcome.RESYNC)
        for other in failed:
            if not other.internal:
                self._late_program_names.update(other.expected[len(other.responses) :])
        fence = self._fence
        if fence is not None:
            if fence.outcome is not _PENDING:
                self._fence = None
            else:
                # A fence covers only what was written before it: a failed query written after
                # it (abandoned) has its reply after the fence's, so another fence must follow.
                # The old one stays a plain query of the session's.
                after_fence = False
                for other in self._pending:
                    if other is fence:
                        after_fence = True
                    elif after_fence and other.outcome is not _PENDING:
                        self._fence = None
                        break
        self._pending = deque(other for other in self._pending if other.outcome is _PENDING)
        self._late_names |= late
        if self.events is not None:
            for other in failed:
                self.events.append(QueryFailed(now, other.command, other.outcome.value))
        self._start_fence(now)
        return [other for other in failed if not other.internal]

    def _spread_failure(self, late: set[str]) -> None:
        """Fail (resync) every query on the wire that expects a name in ``late``, adding its
        names to ``late``, until none is left: its reply would be discarded as late, and it
        would time out though the controller answered."""
        spreading = True
        while spreading:
            spreading = False
            for other in self._pending:
                names = other.expected[len(other.responses) :]
                if other.outcome is _PENDING and late.intersection(names):
                    other.outcome = Outcome.RESYNC
                    late.update(names)
                    spreading = True

    def _start_fence(self, now: float) -> None:
        if self._fence is not None or self._quiet_until is not None:
            return  # a fence is on its way (its reply ends the resynchronisation) or we wait
        for candidate in FENCE_QUERIES:
            if candidate.name not in self._late_names:
                fence = PendingQuery(candidate, now)
                fence.internal = True
                self._fence = fence
                self._pending.append(fence)
                self._outbox.append((self.query_bytes(candidate), fence, candidate))
                self.counters.fences += 1
                return
        self._quiet_until = now + self.quiet_window_s

    def _end_resync(self) -> None:
        self._late_names.clear()
        self._late_program_names.clear()
        self._fence = None
        self._quiet_until = None

    def _release_held(self, now: float) -> None:
        while self._held:
            pending = self._held.popleft()
            pending.sent_at = now
            self._pending.append(pending)
            self._outbox.append((self.query_bytes(pending.command), pending, pending.command))

    def _late(self, response: Response, now: float) -> None:
        self.counters.late_replies += 1
        self._late_reply_at[response.name] = now
        if self._quiet_until is not None:
            self._quiet_until = now + self.quiet_window_s  # not quiet yet
        if self.events is not None:
            by_session = response.name not in self._late_program_names
            self.events.append(LateReply(now, response, by_session))

    def _settle(self, query: PendingQuery, outcome: Outcome) -> None:
        pending = self._pending
        if pending[0] is query:
            pending.popleft()
        else:
            pending.remove(query)
        query.outcome = outcome
        if query is self._fence:
            self._fence = None

    def _deliver(self, response: Response, now: float, settled: list[PendingQuery]) -> bool:
        """Give ``response``, which is not the next reply the oldest query expects, to the query
        it answers (P20); False if it answers none (a stray).

        The controller answers in order, so the queries on the wire before the one it answers
        will get no reply (``lost``). A ``qsa``'s six replies share their names with the single
        queries, so a reply that some query on the wire expects after another of its replies is
        ambiguous: it may be that query's, whose earlier reply was lost (or taken by an earlier
        single query), or a later query's. It goes to neither: that query fails and its names
        are fenced, so that the rest of its reply, still on its way, answers nobody.
        """
        pending = self._pending
        name = response.name
        while pending:
            head = pending[0]
            responses = head.responses
            if not responses:
                break
            expected = head.expected
            if expected[len(responses)] == name:
                self._append(head, response, now, settled)
                return True
            if name in expected[len(responses) + 1 :]:
                # The head's own later reply, one before it lost: the rest may still come.
                settled.extend(self._fail(head, Outcome.CORRUPT, now))
                self._late(response, now)
                return True
            # A half-received reply (qsa) cut short by a later query's: no more of it will come.
            self._settle(head, Outcome.CORRUPT)
            self._report_failure(head, now, settled)
        for index, query in enumerate(pending):
            expected = query.expected
            if name not in expected:
                continue
            for lost in list(pending)[:index]:
                self._settle(lost, Outcome.LOST)
                self._report_failure(lost, now, settled)
            if expected[0] == name:
                self._append(query, response, now, settled)
            else:
                settled.extend(self._fail(query, Outcome.CORRUPT, now))
                self._late(response, now)
            return True
        return False

    def _report_failure(self, query: PendingQuery, now: float, settled: list[PendingQuery]) -> None:
        if self.events is not None:
            self.events.append(QueryFailed(now, query.command, query.outcome.value))
        if not query.internal:
            settled.append(query)
        elif self._late_names and self._fence is None:
            # The fence itself failed (its reply damaged, or a later one first): another one,
            # or the late names would stay late until a query of theirs timed out.
            self._start_fence(now)

    def _is_noise_before_reply(self, event: BadFrame, following: Event | None) -> bool:
        """Whether a damaged frame is line noise rather than the oldest query's reply: a
        fragment that never ended with ``!`` (cut short by a start character, a line end or
        noise, or overlong), followed at once by the whole reply that query expects next,
        which no other query on the wire expects and which cannot be late (no
        resynchronisation). The controller answers a query once, so the whole reply is the
        query's, and the fragment before it was noise that began with a ``$``; taking the
        fragment for the reply would throw the good reply away as a stray.
        """
        if event.raw.endswith(b"!") or self._late_names or type(following) is not Frame:
            return False
        message = following.message
        if type(message) is not Response:
            return False
        name = message.name
        head, *others = self._pending
        remaining = head.expected[len(head.responses) :]
        return (
            remaining[0] == name
            and name not in remaining[1:]
            and not any(name in other.expected[len(other.responses) :] for other in others)
        )

    def _append(
        self, query: PendingQuery, response: Response, now: float, settled: list[PendingQuery]
    ) -> None:
        query.responses.append(response)
        self._last_progress_at = now
        if len(query.responses) == len(query.expected):
            is_fence = query is self._fence
            self._settle(query, _ANSWERED)
            self.counters.replies += 1
            if is_fence:
                self._end_resync()
            if self.events is not None:
                self.events.append(ReplyReceived(now, query.command, tuple(query.responses)))
            if not query.internal:
                settled.append(query)

    def _bad_frame(
        self, event: BadFrame, following: Event | None, now: float, settled: list[PendingQuery]
    ) -> None:
        """A damaged frame (``following``: the event decoded right after it, if any)."""
        self.counters.bad_frames += 1
        self.counters.noise_bytes += len(event.raw)
        if event.reason is Reason.CHECKSUM:
            self.counters.checksum_errors += 1
        if event.raw[:1] != b"$" or event.reason not in _CORRUPT_REASONS or not self._pending:
            return
        if following is None and self._decoder.buffered_bytes and not event.raw.endswith(b"!"):
            # A fragment cut short by the start of a frame whose rest is still on its way
            # (a serial port's reads split frames anywhere): that frame decides, as it would
            # have in the same read (_is_noise_before_reply), when it is whole.
            self._fragment = event
            self._fragment_head = self._pending[0]
            return
        if not self._is_noise_before_reply(event, following):
            # Most likely the head's reply, damaged; but it may be noise that began with a "$"
            # (or, while resynchronising, a late reply), and the head's own reply still to
            # come, as may a qsa's remaining replies. None of them may be taken for a later
            # query's (P20): the head fails and its names are fenced.
            settled.extend(self._fail(self._pending[0], Outcome.CORRUPT, now))

    def _decide_fragment(self, first: Event, now: float, settled: list[PendingQuery]) -> None:
        """Decide on a fragment left undecided by the last read (:meth:`_bad_frame`), now that
        ``first``, the event after it, is decoded; dropped if the query it followed is no
        longer the oldest on the wire (settled meanwhile: timed out, abandoned, lost)."""
        fragment, head = self._fragment, self._fragment_head
        self._fragment = self._fragment_head = None
        if fragment is None or not self._pending or self._pending[0] is not head:
            return
        if not self._is_noise_before_reply(fragment, first):
            settled.extend(self._fail(head, Outcome.CORRUPT, now))
