"""P20 as a property: the session never hands a query a reply produced for another one, except
for the protocol's inherent ambiguity, and it never gets stuck.

A model controller answers the query frames it receives in order, each reply frame with a value
never used before, so that every reply the session hands a query can be traced to the query frame
it was produced for. The line may drop a query frame, and drop, damage (checksum), cut short or
delay a reply frame, or put noise that begins with a ``$`` right before one; delays keep the
order (one serial line), and the host's reads may end anywhere, even inside a frame. Callers
send single queries and ``qsa``, abandon queries (Ctrl-C) and wait, on a simulated clock; the
link may be lost and reopened.

What must hold (P20):

* A query is never answered with a reply produced for a query frame written *before* its own (a
  stale value: a late reply, or another query's).
* It may get a reply produced for a query frame written *after* its own only if its own reply of
  that name did not reach it: lost on the line (a dropped query frame, a dropped, damaged or cut
  reply),
  discarded as late (a fence whose reply was lost took a later reply of its name for its own and
  ended the resynchronisation early), or taken by an earlier query whose own reply missed it so.
  That is the inherent ambiguity of P20 (a ``qd`` whose reply was dropped takes the ``$qd`` of a
  ``qsa`` sent after it): the value is then a reading taken after the query was sent.
* Every settled query is reported to its driver exactly once (a waiter woken, a slot released),
  and once the line is clean again every query settles and the resynchronisation ends.
"""

from __future__ import annotations

import itertools
from collections import deque
from dataclasses import dataclass, field

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rovlink.client.session import Outcome, PendingQuery, Received, Session
from rovlink.protocol import Command, Decoder, Frame, Response, encode

TIMEOUT_S = 1.0
#: User queries. Not a single ``q.l``: its two values cannot tell one reply from another.
USER_QUERIES = ("qd", "qr", "qro", "qpi", "qhe", "qsa")
_VALUE_BASE = {"qd": 0, "qr": 0, "qro": -90, "qpi": -90, "qhe": 0}
_VALUE_COUNT = {"qd": 10_000, "qr": 1025, "qro": 181, "qpi": 181, "qhe": 361}
_FATES = ("ok", "ok", "ok", "ok", "drop", "corrupt", "cut", "noise", "slow")


@dataclass
class _Sent:
    """A reply frame the controller produced: for which query frame (its wire number)."""

    wire: int
    at: float


@dataclass
class _Model:
    """The controller and the line between it and the host."""

    data: st.DataObject
    clean: bool = False  # the line drops, damages and delays nothing (the end of a run)
    decoder: Decoder = field(default_factory=lambda: Decoder(checksum_enabled=True))
    wire_count: itertools.count[int] = field(default_factory=itertools.count)
    counts: dict[str, itertools.count[int]] = field(default_factory=dict)
    produced: dict[tuple[str, tuple[int, ...]], _Sent] = field(default_factory=dict)
    #: (wire number, reply name) of replies that never reached the host intact.
    lost: set[tuple[int, str]] = field(default_factory=set)
    line: deque[tuple[float, bytes, tuple[int, str]]] = field(default_factory=deque)
    #: (wire number, reply name) of replies that reached the host intact.
    arrived: set[tuple[int, str]] = field(default_factory=set)

    def fate(self) -> str:
        return "ok" if self.clean else self.data.draw(st.sampled_from(_FATES))

    def value(self, name: str) -> int:
        if name == "q.l":
            return 0
        number = next(self.counts.setdefault(name, itertools.count()))
        assert number < _VALUE_COUNT[name], "the run is too long for unique values"
        return _VALUE_BASE[name] + number

    def receive(self, data: bytes, queries: list[PendingQuery | None], now: float) -> list[int]:
        """Take the host's bytes (``queries``: the query of each query frame, in order); return
        the wire number of each query frame."""
        wires = []
        expected = deque(queries)
        for event in self.decoder.feed(data):
            assert isinstance(event, Frame), f"the host wrote a bad frame: {event}"
            command = event.message
            assert isinstance(command, Command)
            if not command.spec.is_query:
                continue
            query = expected.popleft()
            assert query is None or query.command == command, "bytes and queue disagree"
            wire = next(self.wire_count)
            wires.append(wire)
            if self.fate() == "drop":
                self.lost.update((wire, name) for name in command.spec.replies)
                continue
            for name in command.spec.replies:
                response = Response(name, (self.value(name),))
                self.produced[(name, response.values)] = _Sent(wire, now)
                frame = encode(response, "crc8")
                fate = self.fate()
                if fate in ("drop", "corrupt", "cut"):
                    self.lost.add((wire, name))
                if fate == "drop":
                    continue
                if fate == "corrupt":  # a wrong checksum: the host's decoder drops the frame
                    frame = frame[:-2] + (b"0" if frame[-2:-1] != b"0" else b"1") + b"!"
                elif fate == "cut":  # its end lost: a fragment, cut short by the next "$"
                    frame = frame[:-3]
                elif fate == "noise":  # noise that begins with a "$", right before the reply
                    frame = b"$" + frame[1:4] + frame
                delay = 0.6 * TIMEOUT_S if fate == "slow" else 0.001
                arrival = max(now + delay, self.line[-1][0] if self.line else now)
                self.line.append((arrival, frame, (wire, name)))
        assert not expected, "a query in the queue was not written"
        return wires


@dataclass
class _Harness:
    """A driver on a simulated clock: the session's bytes to the model, the model's back."""

    session: Session
    model: _Model
    use_fast_path: bool
    now: float = 0.0
    wire_of: dict[int, int] = field(default_factory=dict)  # id(query) -> its wire number
    user: list[PendingQuery] = field(default_factory=list)
    reported: set[int] = field(default_factory=set)  # ids of settled queries handed back
    abandoned: set[int] = field(default_factory=set)
    taken_from: dict[tuple[int, str], int] = field(default_factory=dict)  # -> taker's wire
    taken: set[tuple[int, str]] = field(default_factory=set)  # replies some query took

    # -- writing --------------------------------------------------------------------------

    def _outbox_queries(self) -> list[PendingQuery | None]:
        # (White-box: which query each due frame is, to trace the replies to the wire.)
        entries = self.session._outbox
        return [entry[1] for entry in entries if entry[2] is not None and entry[2].spec.is_query]

    def _write(self, data: bytes, queries: list[PendingQuery | None]) -> None:
        wires = self.model.receive(data, queries, self.now)
        for query, wire in zip(queries, wires, strict=True):
            if query is not None:
                self.wire_of[id(query)] = wire

    def flush(self) -> None:
        if self.session.has_outbox:
            queries = self._outbox_queries()
            self._write(self.session.take_outbox(self.now), queries)

    def send(self, name: str) -> None:
        session = self.session
        command = Command(name)
        queries = self._outbox_queries()
        held = session._quiet_until is not None  # (white-box: query() holds it back)
        ready = session.fast_query(command, self.now) if self.use_fast_path else None
        data, query = ready or session.query(command, self.now)
        if not held:
            queries.append(query)
        self.user.append(query)
        self._write(data, queries)
        self.check()

    def abandon(self, index: int) -> None:
        waiting = [query for query in self.user if not query.settled]
        if not waiting:
            return
        query = waiting[index % len(waiting)]
        self.abandoned.add(id(query))
        self.settled(self.session.abandon(query, self.now))
        self.flush()
        self.check()

    def reconnect(self) -> None:
        self.settled(self.session.disconnect())
        self.model.line.clear()  # a new link: nothing of the old one arrives
        self.model.decoder.reset()
        self.session.reset_link()
        self.check()

    # -- time -----------------------------------------------------------------------------

    def advance(self, until: float) -> None:
        for _ in range(10_000):
            line = self.model.line
            arrival = line[0][0] if line else float("inf")
            deadline = self.session.next_deadline()
            due = min(arrival, float("inf") if deadline is None else deadline)
            if due > until:
                break
            if arrival <= due:
                self.now = max(self.now, due)
                chunk = b""
                while line and line[0][0] <= self.now:
                    _, frame, reply = line.popleft()
                    chunk += frame
                    if reply not in self.model.lost:
                        self.model.arrived.add(reply)
                    if self.model.data.draw(st.booleans()):
                        break  # one frame at a time, or all that have arrived
                # Or in two reads cut anywhere, as a serial port's reads are.
                cut = self.model.data.draw(st.integers(0, len(chunk) - 1) | st.just(0))
                if cut:
                    self.receive(chunk[:cut])
                    self.flush()
                    self.check()
                    chunk = chunk[cut:]
                self.receive(chunk)
            else:
                # A real clock is past a deadline when a timer fires: without the nudge,
                # ``last_sent_at + keepalive_s`` may round below what ``tick`` compares.
                self.now = max(self.now, due + 1e-9)
                self.settled(self.session.tick(self.now))
            self.flush()
            self.check()
        else:
            raise AssertionError("the session keeps asking for ticks without progress")
        self.now = max(self.now, until)

    def receive(self, chunk: bytes) -> None:
        session = self.session
        before = [(query, len(query.responses)) for query in session.pending]
        if self.use_fast_path:
            result = session.receive_reply(chunk, self.now)
            if isinstance(result, PendingQuery):  # (a keep-alive of the session's: no waiter)
                settled = [] if result.internal else [result]
            else:
                settled = result.settled
        else:
            received: Received = session.receive(chunk, self.now)
            settled = received.settled
        # Who took which reply, to tell a reply taken by an earlier query from a stale one.
        for query, count in before:
            for response in query.responses[count:]:
                taker = self.wire_of.get(id(query))
                producer = self.model.produced.get((response.name, response.values))
                if taker is not None and producer is not None:
                    self.taken.add((producer.wire, response.name))
                    if producer.wire != taker:
                        self.taken_from[(producer.wire, response.name)] = taker
        self.settled(settled)

    # -- checks ---------------------------------------------------------------------------

    def settled(self, queries: list[PendingQuery]) -> None:
        for query in queries:
            assert query.settled, f"{query} handed back unsettled"
            assert not query.internal, f"{query}: the session's own query handed back"
            assert id(query) not in self.reported, f"{query} handed back twice"
            self.reported.add(id(query))
            if query.outcome is Outcome.ANSWERED:
                self.check_answer(query)

    def own_reply_missed(self, wire: int, name: str) -> bool:
        """Whether the reply ``name`` of query frame ``wire`` did not reach its query: lost on
        the line, discarded (as late: a fence whose own reply was lost took a later one for
        it and ended the resynchronisation), or taken by an earlier query that missed its own
        reply the same way."""
        for _ in range(1000):
            reply = (wire, name)
            if reply in self.model.lost or (
                reply in self.model.arrived and reply not in self.taken
            ):
                return True
            taker = self.taken_from.get(reply)
            if taker is None or taker >= wire:
                return False
            wire = taker
        raise AssertionError("a cycle of taken replies")

    def check_answer(self, query: PendingQuery) -> None:
        wire = self.wire_of[id(query)]
        assert [response.name for response in query.responses] == list(query.expected)
        for response in query.responses:
            if response.name == "q.l":
                continue  # (two values: it cannot be traced)
            producer = self.model.produced[(response.name, response.values)]
            assert producer.wire >= wire, (
                f"{query} (wire {wire}) got {response}, produced for wire {producer.wire} "
                "before it was sent: a stale value (P20)"
            )
            if producer.wire > wire:
                assert self.own_reply_missed(wire, response.name), (
                    f"{query} (wire {wire}) got {response}, produced for the later wire "
                    f"{producer.wire}, while its own reply reached the host"
                )

    def check(self) -> None:
        for query in self.user:
            if query.settled and id(query) not in self.abandoned:
                assert id(query) in self.reported, f"{query} settled but never handed back"


_OPERATIONS = st.one_of(
    st.tuples(st.just("send"), st.sampled_from(USER_QUERIES)),
    st.tuples(st.just("wait"), st.sampled_from([0.0005, 0.002, 0.3, 0.7, 1.2, 3.0])),
    st.tuples(st.just("abandon"), st.integers(0, 7)),
    st.tuples(st.just("reconnect"), st.none()),
)


@settings(
    max_examples=500,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(
    operations=st.lists(
        st.one_of(_OPERATIONS.filter(lambda op: op[0] != "reconnect"), _OPERATIONS),
        max_size=40,
    ),
    keepalive=st.sampled_from([None, 0.8]),
    use_fast_path=st.booleans(),
    data=st.data(),
)
def test_replies_are_never_stale_and_the_session_never_sticks(
    operations: list[tuple[str, object]],
    keepalive: float | None,
    use_fast_path: bool,
    data: st.DataObject,
) -> None:
    session = Session(checksum_enabled=True, timeout_s=TIMEOUT_S, keepalive_s=keepalive)
    harness = _Harness(session, _Model(data), use_fast_path)
    for operation, argument in operations:
        if operation == "send":
            assert isinstance(argument, str)
            harness.send(argument)
        elif operation == "wait":
            assert isinstance(argument, float)
            harness.advance(harness.now + argument)
        elif operation == "abandon":
            assert isinstance(argument, int)
            harness.abandon(argument)
        else:
            harness.reconnect()
    # A clean line from now on: everything settles and the resynchronisation ends.
    harness.model.clean = True
    harness.advance(harness.now + 10 * TIMEOUT_S)
    assert all(query.settled for query in harness.user), session.pending
    assert not session.resynchronising
    assert not [query for query in session.pending if not query.internal]
