"""``Session.receive_reply``, with its shortcut for a reply read whole, does exactly what
``Session.receive`` does with the same bytes."""

from __future__ import annotations

import re

from hypothesis import event, given, settings
from hypothesis import strategies as st

from rovlink.client.session import Outcome, PendingQuery, Received, Session
from rovlink.protocol import ALGORITHMS, Command, Frame, Response, get_algorithm

_QUERIES = [Command("qd"), Command("qhe"), Command("qsa")]
_CHUNKS = [
    b"$qd.7!",
    b"$qd.8!",
    b"$qhe.90!",
    b"$qd.120!$qr.530!$q.l.0!$qro.-1!$qpi.+3!$qhe.275!",
    b"$qd.12!debug\r\n",
    b"$qd.",
    b"9!",
    b"$qr.5!",
    b"noise\x00\r\n",
    b"",
]
_REPLIES = {"qd": b"$qd.7!", "qhe": b"$qhe.90!"}
# Steps: send a query, read a chunk (with receive_reply on one session), let time pass.
_STEPS = st.lists(
    st.one_of(
        st.tuples(st.just("query"), st.sampled_from(_QUERIES)),
        st.tuples(st.just("read"), st.sampled_from(_CHUNKS)),
        st.tuples(st.just("read"), st.just(None)),  # the reply the oldest query expects
        # Read as they are, in any mode: no checksum, a wrong one, a lower-case one, too long.
        st.tuples(
            st.just("read as sent"),
            st.sampled_from(
                [b"$qd.7!", b"$qd.700!", b"$qd.7F3!", b"$qhe.90b5!", b"$qd." + b"0" * 60 + b"7!"]
            ),
        ),
        st.tuples(st.just("wait"), st.sampled_from([0.1, 0.1, 0.1, 0.6])),  # 0.6: a timeout
    ),
    max_size=40,
)


def _state(session: Session, queries: list[PendingQuery]) -> object:
    return (
        session.counters.as_dict(),
        [(query.outcome, query.responses) for query in queries],
        [(query.command, query.outcome) for query in session.pending],
        session.resynchronising,
        session.next_deadline(),
        len(session.notices),
        None if session.events is None else len(session.events),
    )


def _checksummed(chunk: bytes, algorithm: str) -> bytes:
    """``chunk`` with every whole frame in it checksummed by ``algorithm``: the same stream as
    a controller in checksum mode sends it (text, noise and a split frame left as they are)."""
    return re.sub(
        rb"\$([^$!]*)!",
        lambda match: b"$" + match[1] + get_algorithm(algorithm).digits(match[1]) + b"!",
        chunk,
    )


#: Checksum mode off, or on with each algorithm; chunks with a wrong checksum are added for it.
_MODES = st.sampled_from([None, None, *sorted(ALGORITHMS)])


@settings(max_examples=500)
@given(_STEPS, st.sampled_from([False, False, False, True]), _MODES)  # (events: never shortcut)
def test_receive_reply_is_receive(
    steps: list[tuple[str, object]], events: bool, algorithm: str | None
) -> None:
    def session() -> Session:
        return Session(
            record_events=events,
            checksum_enabled=algorithm is not None,
            algorithm=algorithm or "crc8",
        )

    def wire(chunk: bytes) -> bytes:
        return chunk if algorithm is None else _checksummed(chunk, algorithm)

    shortcut, reference = session(), session()
    shortcut_queries: list[PendingQuery] = []
    reference_queries: list[PendingQuery] = []
    shortcut_replies = 0
    now = 0.0
    for action, argument in steps:
        now += 0.001
        if action == "query":
            assert isinstance(argument, Command)
            shortcut_queries.append(shortcut.query(argument, now)[1])
            reference_queries.append(reference.query(argument, now)[1])
        elif action in ("read", "read as sent"):
            chunk = argument
            if chunk is None:
                name = reference.pending[0].command.name if reference.pending else "qd"
                chunk = _REPLIES.get(name, b"$qd.7!")
            assert isinstance(chunk, bytes)
            if action == "read":
                chunk = wire(chunk)
            oldest = shortcut.pending[0] if shortcut.pending else None
            result = shortcut.receive_reply(chunk, now)
            if isinstance(result, PendingQuery):
                assert result is oldest
                assert result.outcome is Outcome.ANSWERED
                shortcut_replies += 1
            reference.receive(chunk, now)
        else:
            assert isinstance(argument, float)
            now += argument
            shortcut.tick(now)
            reference.tick(now)
        assert _state(shortcut, shortcut_queries) == _state(reference, reference_queries)
    event(f"checksums: {algorithm or 'off'}")
    event(
        f"replies by the shortcut: {min(shortcut_replies, 3)}{'+' if shortcut_replies >= 3 else ''}"
    )


def test_receive_reply_settles_a_polling_loops_replies() -> None:
    session = Session()
    for depth_cm in (3, 3, 4):  # new and repeated values alike
        _, query = session.query(Command("qd"), now=0.0)
        assert session.receive_reply(b"$qd.%d!" % depth_cm, now=0.001) is query
        assert query.responses[0].values == (depth_cm,)
    assert session.pending == ()
    assert session.counters.replies == 3
    assert session.counters.bytes_received == 18


def test_receive_reply_leaves_a_six_reply_query_and_a_wrong_name_to_receive() -> None:
    session = Session()
    _, sensors = session.query(Command("qsa"), now=0.001)
    received = session.receive_reply(b"$qd.3!", now=0.002)
    assert isinstance(received, Received)
    assert received.settled == []
    assert sensors.responses == [Response("qd", (3,))]
    session.receive(b"$qr.1!$q.l.0!$qro.0!$qpi.0!$qhe.9!", now=0.003)
    _, heading = session.query(Command("qhe"), now=0.004)
    received = session.receive_reply(b"$qd.3!", now=0.005)  # not its reply: a stray frame
    assert isinstance(received, Received)
    assert [event.raw for event in received.unsolicited if isinstance(event, Frame)] == [b"$qd.3!"]
    assert session.receive_reply(b"$qhe.9!", now=0.006) is heading


def _overlong_reply() -> bytes:
    return b"$qd." + b"0" * 60 + b"12!"  # 67 bytes, P1


def test_receive_reply_does_not_answer_a_query_with_an_overlong_frame() -> None:
    """The shortcut gives an overlong reply the outcome receive gives it (dropped, P1), with
    the same counters."""
    frame = _overlong_reply()
    shortcut, reference = Session(), Session()
    _, taken = shortcut.query(Command("qd"), now=0.0)
    _, received = reference.query(Command("qd"), now=0.0)
    shortcut.receive_reply(frame, now=0.001)
    reference.receive(frame, now=0.001)
    assert (taken.outcome, taken.responses) == (received.outcome, received.responses)
    assert shortcut.counters.as_dict() == reference.counters.as_dict()
