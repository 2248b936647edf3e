"""The sans-I/O session: replies matched in order, timeouts on a simulated clock, counters."""

from __future__ import annotations

import pytest

from rovlink.client.errors import SupersededByStopError
from rovlink.client.events import BytesSent, LateReply
from rovlink.client.session import FENCE_QUERIES, STOP_REPEATS, Outcome, PendingQuery, Session
from rovlink.protocol import COMMANDS, Command, Response, Spec, Text, encode

QSA_REPLY = b"$qd.120!$qr.530!$q.l.0!$qro.-1!$qpi.+3!$qhe.275!"


def test_replies_go_to_queries_in_order() -> None:
    session = Session()
    _, first = session.query(Command("qd"), now=0.0)
    _, second = session.query(Command("qd"), now=0.0)
    received = session.receive(b"$qd.1!$qd.2!", now=0.01)
    assert received.settled == [first, second]
    assert first.responses[0].values == (1,)
    assert second.responses[0].values == (2,)
    assert session.pending == ()


def test_qsa_collects_its_six_replies_across_chunks() -> None:
    session = Session()
    _, query = session.query(Command("qsa"), now=0.0)
    assert session.receive(QSA_REPLY[:20], now=0.001).settled == []
    assert len(query.responses) == 2
    assert session.receive(QSA_REPLY[20:], now=0.002).settled == [query]
    assert [r.name for r in query.responses] == ["qd", "qr", "q.l", "qro", "qpi", "qhe"]


def test_a_reply_to_a_later_query_settles_the_earlier_ones_as_lost() -> None:
    session = Session()
    _, depth = session.query(Command("qd"), now=0.0)
    _, heading = session.query(Command("qhe"), now=0.0)
    received = session.receive(b"$qhe.90!", now=0.01)
    assert received.settled == [depth, heading]
    assert depth.outcome is Outcome.LOST
    assert heading.outcome is Outcome.ANSWERED


def test_a_qsa_reply_cut_short_is_corrupt_and_the_frame_goes_on_to_the_next_query() -> None:
    session = Session()
    _, sensors = session.query(Command("qsa"), now=0.0)
    _, depth = session.query(Command("qd"), now=0.0)
    # qsa got two replies, then a frame it does not expect any more: the next query's, so the
    # rest of qsa will not come (the controller answers in order).
    received = session.receive(b"$qd.1!$qr.2!$qd.3!", now=0.01)
    assert sensors.outcome is Outcome.CORRUPT
    assert depth.outcome is Outcome.ANSWERED
    assert depth.responses[0].values == (3,)
    assert received.settled == [sensors, depth]
    assert not session.resynchronising


def test_a_qsa_reply_with_a_gap_answers_no_later_query() -> None:
    """A frame that the half-answered qsa still expects, after a gap, is most likely its own
    (one frame lost on the line), though it may be a later query's: it goes to neither, and
    the rest of qsa's reply, still on its way, is discarded as late (P20)."""
    session = Session()
    _, sensors = session.query(Command("qsa"), now=0.0)
    _, roll = session.query(Command("qro"), now=0.0)
    received = session.receive(b"$qd.1!$qr.2!$qro.+5!$qpi.+1!$qhe.90!", now=0.01)
    assert sensors.outcome is Outcome.CORRUPT
    assert roll.outcome is Outcome.RESYNC  # its caller retries it
    assert received.settled == [sensors, roll]
    assert session.counters.late_replies == 3
    assert session.counters.stray_frames == 0


def test_a_dropped_reply_before_qsa_queries_hands_none_of_their_replies_to_a_later_query() -> None:
    """On the wire ``qd`` (its reply dropped), ``qsa``, ``qsa``, ``qhe``, ``qd``. The first
    qsa's ``$qd`` is taken by the ``qd`` before it (P20 cannot tell); its ``$qr`` then shows the
    first qsa lost its start, so the qsa replies that follow answer nobody: before, its
    ``$qhe`` settled both qsa as lost, and the second qsa's ``$qd`` answered the last ``qd``,
    sent after it."""
    session = Session(timeout_s=0.5)
    queries = [
        session.query(Command(name), now=0.0)[1] for name in ("qd", "qsa", "qsa", "qhe", "qd")
    ]
    qsa = b"$qd.%d!$qr.530!$q.l.0!$qro.-1!$qpi.+15!$qhe.275!"
    session.receive(qsa % 2 + qsa % 3 + b"$qhe.275!$qd.5!", now=0.01)
    assert [query.outcome for query in queries] == [
        Outcome.ANSWERED,
        Outcome.CORRUPT,
        Outcome.RESYNC,
        Outcome.RESYNC,
        Outcome.RESYNC,
    ]
    assert queries[0].responses[0].values == (2,)
    # Every fence name is late: new queries wait for a quiet line (P20), and then go out.
    _, later = session.query(Command("qd"), now=0.02)
    assert session.take_outbox(now=0.02) == b""
    quiet_s = session.quiet_window_s
    assert session.tick(now=0.01 + quiet_s - 0.01) == []
    assert session.take_outbox(now=0.01 + quiet_s - 0.01) == b""  # not quiet long enough yet
    assert session.tick(now=0.01 + quiet_s) == []
    assert session.take_outbox(now=0.01 + quiet_s) == b"#qd!"
    session.receive(b"$qd.6!", now=0.02 + quiet_s)
    assert later.responses[0].values == (6,)


def test_a_reply_stalled_past_the_timeout_answers_no_query_released_after_a_quiet_wait() -> None:
    """On the wire ``qsa`` (its reply dropped) and, just before it times out, ``qd``, whose
    reply the controller holds back a while. The qsa's timeout makes every name late, so the
    retries wait for a quiet line; the stalled ``$qd`` came ``timeout_s`` after that began, the
    retried qsa was on the wire by then and took it as its own depth (a flaky field report:
    ``sensors()`` returned the previous ``depth_cm()``'s reply)."""
    session = Session(timeout_s=0.1)
    _, qsa = session.query(Command("qsa"), now=0.0)
    _, depth = session.query(Command("qd"), now=0.09)
    assert session.tick(now=0.1) == [qsa, depth]  # qsa timed out; qd fails with it (resync)
    _, retried = session.query(Command("qsa"), now=0.1, retry=True)
    assert session.take_outbox(now=0.1) == b""  # held for a quiet line
    # The controller stalled as it answered qd at 0.09, for longer than the timeout itself: its
    # reply comes after a window of one timeout from the qsa's failure would have ended.
    session.tick(now=0.21)
    session.receive(b"$qd.2!", now=0.22)
    assert not retried.settled
    assert retried.responses == []
    assert session.counters.late_replies == 1
    # Still no new query on the wire until the line has been quiet again; then the retry goes.
    assert session.take_outbox(now=0.22) == b""
    deadline = session.next_deadline()
    assert deadline is not None
    session.tick(now=deadline)
    assert session.take_outbox(now=deadline) == b"#qsa!"
    session.receive(QSA_REPLY, now=deadline + 0.01)
    assert retried.outcome is Outcome.ANSWERED
    assert retried.responses[0].values == (120,)


def test_a_query_whose_name_another_failed_query_made_late_fails_with_them_at_once() -> None:
    """On the wire ``qro`` (its reply dropped), ``qhe``, ``qsa``. The qro's timeout fails the
    qsa (it expects a ``$qro`` too), and the qsa's names are late from then on, ``qhe`` among
    them: the ``qhe`` on the wire must fail with them (resync) and be retried after the
    resynchronisation. Before, it was left pending, its reply was discarded as late, and it
    timed out a whole timeout later, counted as a timeout of a controller that had answered."""
    session = Session(timeout_s=0.5)
    _, roll = session.query(Command("qro"), now=0.0)
    _, heading = session.query(Command("qhe"), now=0.0)
    _, sensors = session.query(Command("qsa"), now=0.0)
    assert session.tick(now=0.5) == [roll, heading, sensors]
    assert (roll.outcome, heading.outcome, sensors.outcome) == (
        Outcome.TIMEOUT,
        Outcome.RESYNC,
        Outcome.RESYNC,
    )
    assert session.pending == ()
    session.receive(b"$qhe.275!" + QSA_REPLY, now=0.51)
    assert session.tick(now=1.2) == []
    assert session.counters.timeouts == 1
    assert session.counters.late_replies == 7


def test_a_query_sent_behind_a_fence_whose_reply_is_lost_fails_with_the_fence() -> None:
    """``qd`` times out, and the fence ``qhe`` goes out; the program's next ``qd`` goes behind
    it. The fence's reply is lost, so the ``$qd`` that answers the new query comes while ``qd``
    is still late, and is discarded. When the fence times out, that query fails with it
    (resync) and is retried behind the next fence. Before, it was left waiting and timed out
    too: with the fence, two timeouts in a row, and a controller reset was suspected (P21),
    though the controller had answered."""
    session = Session(timeout_s=0.5)
    session.query(Command("qd"), now=0.0)
    session.tick(now=0.5)
    assert session.take_outbox(now=0.5) == b"#qhe!"
    _, depth = session.query(Command("qd"), now=0.6)
    session.receive(b"$qd.7!", now=0.61)  # (the fence's $qhe was lost)
    assert session.counters.late_replies == 1
    assert session.tick(now=1.1) == [depth]
    assert depth.outcome is Outcome.RESYNC
    assert session.take_outbox(now=1.1) == b"#qro!"
    assert session.counters.timeouts == 2
    assert session.counters.resets_suspected == 0


def test_a_fence_that_fails_is_followed_by_another() -> None:
    session = Session(timeout_s=0.5)
    session.query(Command("qd"), now=0.0)
    session.expire(now=0.5)  # qd late: the fence qhe goes out
    assert session.take_outbox(now=0.5) == b"#qhe!"
    session.receive(b"$qhe.9000!", now=0.51)  # the fence's reply, damaged (out of range)
    # Another fence goes out at once: the late name does not wait for another timeout. The
    # damaged reply may have been a late one, and the fence's own still to come: qhe is late too.
    assert session.take_outbox(now=0.51) == b"#qro!"
    _, later = session.query(Command("qd"), now=0.52)
    # A late qd, the first fence's qhe (late), the new fence's reply, the new qd.
    session.receive(b"$qd.1!$qhe.90!$qro.+5!$qd.2!", now=0.53)
    assert later.responses[0].values == (2,)
    assert session.counters.late_replies == 2


def test_damaged_late_replies_are_not_taken_for_the_replies_of_queries_on_the_wire() -> None:
    # While resynchronising a damaged reply may be a late one: the oldest query's own reply may
    # still come, and must not answer the next query of its name (a stale value, P20).
    session = Session(timeout_s=0.5)
    session.query(Command("qd"), now=0.0)
    session.query(Command("qd"), now=0.0)
    session.expire(now=0.5)  # both qd late: the fence qhe goes out
    data, first = session.query(Command("qr"), now=0.5)
    assert data == b"#qhe!#qr!"
    _, second = session.query(Command("qr"), now=0.5)
    # The two late qd arrive damaged, the fence's reply is dropped, then the two qr replies.
    received = session.receive(b"$qd.x!$qd.y!$qr.1!$qr.2!", now=0.51)
    assert Outcome.ANSWERED not in (first.outcome, second.outcome)  # (they are retried)
    assert set(received.settled) == {first, second}
    assert session.take_outbox(now=0.51) == b"#qro!"  # a fence after them both


def test_a_query_abandoned_after_the_fence_went_out_is_fenced_again() -> None:
    # The fence answers for what was written before it; an abandoned query written after it
    # needs another fence, or its reply answers the next query of its name (stale, P20).
    session = Session(timeout_s=0.5)
    _, depth = session.query(Command("qd"), now=0.0)
    session.abandon(depth, now=0.01)  # the fence qhe is due
    data, roll = session.query(Command("qro"), now=0.02)
    assert data == b"#qhe!#qro!"
    session.abandon(roll, now=0.03)
    data, later = session.query(Command("qro"), now=0.04)
    assert data == b"#qhe!#qro!"  # another fence, after the abandoned qro
    # A late qd, the first fence's qhe, the abandoned qro (late), the new fence's, the new qro.
    session.receive(b"$qd.1!$qhe.2!$qro.-5!$qhe.3!$qro.+7!", now=0.05)
    assert later.outcome is Outcome.ANSWERED
    assert later.responses[0].values == (7,)


def test_a_bad_checksum_makes_the_oldest_query_corrupt() -> None:
    session = Session(checksum_enabled=False)
    session.command(Command("crcon"), now=0.0)
    _, query = session.query(Command("qd"), now=0.0)
    received = session.receive(b"$qd.12300!", now=0.01)
    assert query.outcome is Outcome.CORRUPT
    assert received.settled == [query]
    assert session.counters.checksum_errors == 1
    assert session.counters.bad_frames == 1


def test_unknown_replies_and_text_are_unsolicited_and_settle_nothing() -> None:
    session = Session()
    _, query = session.query(Command("qd"), now=0.0)
    received = session.receive(b"boot ok\r\n$zz.1!$qhe.5!", now=0.01)
    assert received.settled == []
    assert query.outcome is Outcome.PENDING
    assert isinstance(received.unsolicited[0], Text)
    assert session.counters.text_lines == 1
    assert session.counters.stray_frames == 1  # $qhe answers nothing pending


def test_deadline_counts_from_sending_then_from_the_last_progress() -> None:
    session = Session(timeout_s=0.5)
    _, first = session.query(Command("qd"), now=0.0)
    _, second = session.query(Command("qd"), now=0.1)
    assert session.deadline(first) == pytest.approx(0.5)
    session.receive(b"$qd.1!", now=0.45)
    # The queue moved at 0.45: the second query waits a full timeout from there.
    assert session.deadline(second) == pytest.approx(0.95)
    assert session.expire(now=0.9) == []
    assert session.expire(now=0.95) == [second]
    assert second.outcome is Outcome.TIMEOUT
    assert session.counters.timeouts == 1


def test_a_dead_link_times_every_query_out_together() -> None:
    session = Session(timeout_s=0.5)
    queries = [session.query(Command("qd"), now=0.01 * n)[1] for n in range(5)]
    assert session.expire(now=0.55) == queries
    # Only the fence is left (P20): a query of another name, due to be written now.
    assert [query.command.name for query in session.pending] == ["qhe"]
    assert session.take_outbox(now=0.55) == b"#qhe!"
    assert session.next_deadline() == pytest.approx(1.05)


def test_checksum_mode_switches_both_directions() -> None:
    session = Session()
    assert session.command(Command("crcon"), now=0.0) == b"#crcon!"
    data, query = session.query(Command("qd"), now=0.0)
    assert data == b"#qd8C!"
    session.receive(b"$qd.12313!", now=0.01)
    assert query.responses[0].values == (123,)
    assert session.command(Command("crcoff"), now=0.0) == b"#crcoff!"
    assert session.query(Command("qd"), now=0.0)[0] == b"#qd!"


def test_raw_frames_are_counted_and_a_raw_query_waits_for_its_reply() -> None:
    session = Session()
    assert session.raw(b"#bogus!", now=0.0) == (b"#bogus!", None)
    data, query = session.raw(b"#qd!", now=0.0)
    assert data == b"#qd!"
    assert query is not None
    assert query.command == Command("qd")
    assert session.counters.frames_sent == 2


def test_disconnect_settles_everything() -> None:
    session = Session()
    _, query = session.query(Command("qd"), now=0.0)
    assert session.disconnect() == [query]
    assert query.outcome is Outcome.DISCONNECTED


def test_commands_and_queries_are_not_interchangeable() -> None:
    session = Session()
    with pytest.raises(ValueError, match="is a query"):
        session.command(Command("qd"), now=0.0)
    with pytest.raises(ValueError, match="expects no reply"):
        session.query(Command("stop"), now=0.0)


def test_an_abandoned_query_is_fenced_so_its_reply_goes_to_no_later_query() -> None:
    session = Session()
    _, abandoned = session.query(Command("qd"), now=0.0)
    assert session.abandon(abandoned, now=0.01) == []
    assert abandoned.outcome is Outcome.ABANDONED
    assert session.resynchronising
    data, later = session.query(Command("qd"), now=0.02)
    assert data == b"#qhe!#qd!"  # the fence first (P20)
    session.receive(b"$qd.1!$qhe.90!$qd.2!", now=0.03)
    assert later.responses[0].values == (2,)
    assert session.counters.late_replies == 1
    assert not session.resynchronising


def test_abandoning_fails_the_queries_of_the_same_name_on_the_wire_with_it() -> None:
    session = Session()
    _, first = session.query(Command("qd"), now=0.0)
    _, second = session.query(Command("qd"), now=0.0)
    _, heading = session.query(Command("qhe"), now=0.0)
    assert session.abandon(first, now=0.01) == [second]
    assert second.outcome is Outcome.RESYNC
    assert heading.outcome is Outcome.PENDING


def test_abandoning_a_settled_or_held_query_sends_nothing() -> None:
    session = Session()
    _, answered = session.query(Command("qd"), now=0.0)
    session.receive(b"$qd.1!", now=0.01)
    assert session.abandon(answered, now=0.02) == []
    assert answered.outcome is Outcome.ANSWERED
    assert not session.resynchronising
    # A quiet-line wait (every fence name late) holds new queries back: one abandoned there
    # never reaches the wire.
    session = Session(timeout_s=0.5)
    for fence in FENCE_QUERIES:
        session.query(fence, now=0.0)
    session.expire(now=0.5)
    _, held = session.query(Command("qd"), now=0.6)
    assert session.pending == (held,)
    session.abandon(held, now=0.7)
    assert held.outcome is Outcome.ABANDONED
    assert not session.pending
    assert session.tick(now=0.5 + session.quiet_window_s) == []
    assert not session.resynchronising  # the wait ended, with nothing to send
    assert session.take_outbox(now=0.5 + session.quiet_window_s) == b""


def test_a_fence_not_yet_written_is_not_on_the_wire() -> None:
    session = Session()
    _, query = session.query(Command("qd"), now=0.0)
    session.abandon(query, now=0.01)
    (fence,) = session.pending
    assert not session.on_the_wire
    session.take_outbox(now=0.02)
    assert session.on_the_wire == (fence,)


def test_a_fragment_cut_short_right_before_the_reply_is_noise_not_the_reply() -> None:
    # Noise that begins with a "$" and is cut short by the reply's own "$": the controller
    # answers a query once, so the whole frame is the reply (before, the query failed as corrupt
    # and its good reply was dropped as a stray).
    session = Session()
    _, query = session.query(Command("qd"), now=0.0)
    received = session.receive(b"$qd.1$qd.37!", now=0.01)
    assert received.settled == [query]
    assert query.outcome is Outcome.ANSWERED
    assert query.responses[0].values == (37,)
    assert session.counters.bad_frames == 1  # the fragment, counted as noise
    assert not session.resynchronising


_FRAGMENT_THEN_REPLY = b"$qd.1$qd.37!"


@pytest.mark.parametrize("cut", range(1, len(_FRAGMENT_THEN_REPLY)))
def test_a_fragment_cut_short_by_a_reply_split_across_reads_is_noise_too(cut: int) -> None:
    # A serial port's reads split frames anywhere; when the read ends right after the "$" that
    # cuts the fragment short, the frame that "$" begins decides once it is whole (before, the
    # query failed and was retried after a fence).
    session = Session()
    _, query = session.query(Command("qd"), now=0.0)
    first = session.receive_reply(_FRAGMENT_THEN_REPLY[:cut], now=0.01)
    assert not query.settled
    assert not isinstance(first, PendingQuery)
    assert not first.settled
    second = session.receive_reply(_FRAGMENT_THEN_REPLY[cut:], now=0.02)
    settled = [second] if isinstance(second, PendingQuery) else second.settled
    assert settled == [query]
    assert query.outcome is Outcome.ANSWERED
    assert query.responses[0].values == (37,)
    assert session.counters.bad_frames == 1
    assert not session.resynchronising


@pytest.mark.parametrize(
    ("reads", "why"),
    [
        ((b"$qd.1x!$qd.37!",), "a whole damaged frame is the reply, damaged"),
        ((b"$qd.1$qhe.5!",), "followed by a reply of another name"),
        ((b"$qd.1", b"$", b"qhe.5!"), "followed, reads later, by a reply of another name"),
        ((b"$qd.1$", b"boot\r\n"), "followed by a line of text"),
    ],
)
def test_a_damaged_reply_still_fails_the_query_when_it_may_be_the_reply(
    reads: tuple[bytes, ...], why: str
) -> None:
    session = Session()
    _, query = session.query(Command("qd"), now=0.0)
    for data in reads:
        session.receive(data, now=0.01)
    assert query.outcome is Outcome.CORRUPT, why


def test_a_fragment_undecided_when_its_query_times_out_decides_nothing_more() -> None:
    # The frame after it is still incomplete at the deadline: the query times out and its name
    # is fenced, so when that frame completes it is late, never the retry's reply (P20).
    session = Session(timeout_s=0.5)
    _, query = session.query(Command("qd"), now=0.0)
    session.receive(b"$qd.1$qd.", now=0.01)
    assert session.tick(now=0.6) == [query]
    assert query.outcome is Outcome.TIMEOUT
    _, retry = session.query(Command("qd"), now=0.6)
    received = session.receive(b"37!", now=0.61)
    assert not received.settled
    assert retry.outcome is Outcome.PENDING
    assert session.counters.late_replies == 1


def test_a_fragment_before_a_reply_another_query_also_expects_answers_neither() -> None:
    # Two qd on the wire. The fragment may be the first one's reply cut short, and the whole
    # frame the second one's; or noise, and the whole frame the first one's, which must not go
    # to the second (a value read before it was sent, P20). Both are retried after a fence.
    session = Session()
    _, first = session.query(Command("qd"), now=0.0)
    _, second = session.query(Command("qd"), now=0.0)
    received = session.receive(b"$qd.1$qd.37!", now=0.01)
    assert received.settled == [first, second]
    assert (first.outcome, second.outcome) == (Outcome.CORRUPT, Outcome.RESYNC)
    assert session.counters.late_replies == 1
    assert session.take_outbox(now=0.01) == b"#qhe!"


def test_the_reply_after_a_damaged_frame_goes_to_no_later_query() -> None:
    # A damaged frame taken for the oldest query's reply may have been noise: its own reply
    # can still come, after the caller has sent the query again (P20).
    session = Session()
    _, first = session.query(Command("qd"), now=0.0)
    session.receive(b"$qd.1x!", now=0.01)  # damaged: the query fails, the caller retries
    assert first.outcome is Outcome.CORRUPT
    _, retry = session.query(Command("qd"), now=0.02)
    session.receive(b"$qd.5!", now=0.03)  # the first one's reply after all
    assert retry.outcome is Outcome.PENDING
    assert session.counters.late_replies == 1
    session.receive(b"$qhe.90!$qd.6!", now=0.04)  # the fence's reply, then the retry's
    assert retry.responses[0].values == (6,)


def test_a_silent_line_is_one_suspected_reset_until_a_reply_comes() -> None:
    session = Session(timeout_s=0.5)
    written = []
    now = 0.0
    for _ in range(12):  # nothing answers: queries and fences time out one after another
        if not session.pending:
            session.query(Command("qd"), now=now)
        now += 0.5
        session.tick(now)
        written.append(session.take_outbox(now))
    assert session.counters.timeouts >= 10
    assert sum(data.startswith(b"#crcoff!") for data in written) >= 4  # re-asserted each time
    assert session.counters.resets_suspected == 1
    # The controller answers what is on the wire, then falls silent again: another reset.
    replies = {"qd": b"$qd.5!", "qhe": b"$qhe.5!", "qro": b"$qro.+5!", "qpi": b"$qpi.+5!"}
    replies |= {"qr": b"$qr.5!", "q.l": b"$q.l.0!"}
    answered = session.pending
    session.receive(b"".join(replies[query.command.name] for query in answered), now=now)
    assert answered
    assert all(query.outcome is Outcome.ANSWERED for query in answered)
    for _ in range(4):
        if not session.pending:
            session.query(Command("qd"), now=now)
        now += 0.5
        session.tick(now)
    assert session.counters.resets_suspected == 2


def test_a_reply_at_the_clock_reading_of_a_reset_report_ends_that_silence() -> None:
    # A coarse clock (15.6 ms on some systems) reads the same for the report and the fence's
    # reply; the next silence must still be reported.
    session = Session(timeout_s=0.5)
    session.query(Command("qd"), now=0.0)
    session.tick(0.5)  # the qd times out: fence qhe
    session.tick(1.0)  # the fence times out: a reset suspected, fence qro
    assert session.counters.resets_suspected == 1
    session.receive(b"$qro.+1!", now=1.0)  # answered at the same clock reading
    now = 1.0
    for _ in range(4):
        if not session.pending:
            session.query(Command("qd"), now=now)
        now += 0.5
        session.tick(now)
    assert session.counters.resets_suspected == 2


def test_a_stop_while_a_reopened_link_is_readied_is_written_at_once_and_again_when_ready() -> None:
    session = Session()
    session.command(Command("th", (90, 40)), now=0.0)
    session.disconnect()  # the link is lost: a stop waits for the next one
    assert session.stop_while_reconnecting(now=1.0) == b""
    assert session.link_reopened() == b"#stop!"  # its first frame, before the probe
    session.reopen_failed()  # that one failed before it was ready
    assert session.stop_while_reconnecting(now=2.0) == b""
    assert session.link_reopened() == b"#stop!"
    sent = session.counters.frames_sent
    # While the probe waits for its answer: at once, counted, and the motion at rest.
    assert session.stop_while_reconnecting(now=3.0) == b"#stop!"
    assert session.counters.frames_sent == sent + 1
    assert session.motion_as_sent() == (90, 0, 0)
    session.reset_link()  # the controller answered: mode, then the stop once more
    assert session.take_outbox(now=4.0) == b"#crcoff!#stop!"
    session.reopen_failed()  # ... but that write failed: the next link carries it first again
    assert session.link_reopened() == b"#stop!"
    session.reset_link()
    assert session.take_outbox(now=5.0) == b"#crcoff!#stop!"
    session.link_ready()  # written: done
    assert session.rest_frames() == b""
    assert session.stop_while_reconnecting(now=6.0) == b""  # (no link being readied)


# -- a stop supersedes the unlock and motion commands asked for before it ----------------------


def _a_command_of(spec: Spec) -> Command:
    return Command(spec.name, tuple(argument.minimum for argument in spec.arguments))


@pytest.mark.parametrize(
    "spec", [spec for spec in COMMANDS if not spec.is_query], ids=lambda spec: spec.name
)
def test_a_stop_supersedes_exactly_the_commands_that_move_or_unlock(spec: Spec) -> None:
    session = Session()
    command = _a_command_of(spec)
    asked_at = session.stops_asked
    session.stop_asked()
    expected = spec.name in {"start", "mvs", "mvd", "th", "h+", "h-"}
    assert spec.moves_or_unlocks is expected
    if expected:
        with pytest.raises(SupersededByStopError) as raised:
            session.command(command, now=0.0, stops_seen=asked_at)
        assert raised.value.command == command
        with pytest.raises(SupersededByStopError):
            session.raw(session.frame_for(command), now=0.0, stops_seen=asked_at)
        assert session.counters.frames_sent == 0  # nothing half-sent
    else:
        assert session.command(command, now=0.0, stops_seen=asked_at) == session.frame_for(command)
    # Asked for after the stop, or by a driver that does not say when: sent.
    assert session.command(command, now=1.0, stops_seen=session.stops_asked)
    assert session.command(command, now=2.0)


def test_a_query_held_back_for_a_quiet_line_goes_out_as_the_programs() -> None:
    # Released from a quiet-line wait, it went out as a frame of the session's own: a recording
    # took it for a fence, and a replay left it out.
    session = Session(timeout_s=0.5)
    session.events = []
    for fence in FENCE_QUERIES:
        session.query(fence, now=0.0)
    session.expire(now=0.5)
    session.query(Command("qd"), now=0.6)
    session.query(Command("qr"), now=0.6, retry=True)
    session.tick(now=0.5 + session.quiet_window_s)
    assert session.take_outbox(now=0.5 + session.quiet_window_s) == b"#qd!#qr!"
    sent = [event for event in session.take_events() if isinstance(event, BytesSent)]
    assert [(e.data, e.by_session, e.retry) for e in sent[-2:]] == [
        (b"#qd!", False, False),
        (b"#qr!", False, True),
    ]


@pytest.mark.parametrize("checksum", [False, True])
def test_a_quiet_line_wait_keeps_the_link_alive_with_the_checksum_mode_as_it_is(
    checksum: bool,
) -> None:
    # Every name late (a qsa timed out): no query may go until the line is quiet. Before, the
    # keep-alive waited too, and the line was silent for the timeout and the wait (1.5 s by
    # default): a damaged frame or two around that gap tripped the controller's 2 s failsafe.
    session = Session(timeout_s=0.5, keepalive_s=1.0)
    if checksum:
        session.command(Command("crcon"), now=0.0)
    session.query(Command("qsa"), now=0.0)
    session.tick(now=0.5)
    assert session.resynchronising
    assert session.next_deadline() == 1.0  # the keep-alive, before the wait ends at 1.5
    assert session.tick(now=1.0) == []
    assert session.take_outbox(now=1.0) == (b"#crcon!" if checksum else b"#crcoff!")
    assert session.counters.keepalives == 1
    assert session.pending == ()  # nothing to wait for: the frame has no reply
    assert session.checksum_enabled is checksum
    assert session.resynchronising  # the wait goes on, to its end
    session.tick(now=1.5)
    assert not session.resynchronising


def _keepalive_bytes(session: Session, now: float) -> bytes:
    """What the session writes at its keep-alive due at ``now``, its query answered."""
    session.tick(now=now)
    data = session.take_outbox(now=now)
    session.receive(b"$qd.0!", now=now)
    return data


def test_the_keep_alives_after_a_stop_carry_it_again() -> None:
    # A #stop! lost on a noisy line has no reply to miss: before, the keep-alive then fed the
    # controller's link-loss failsafe (P17) while the robot drove on, and the host showed it
    # stopped.
    session = Session(timeout_s=0.5, keepalive_s=1.0)
    session.command(Command("start"), now=0.0)
    session.command(Command("th", (90, 50)), now=0.0)
    session.command(Command("stop"), now=0.5)
    sent = [_keepalive_bytes(session, now=1.5 + step) for step in range(STOP_REPEATS + 1)]
    assert sent == [b"#stop!#qd!"] * STOP_REPEATS + [b"#qd!"]


@pytest.mark.parametrize("unlocked", [False, True])
def test_a_stop_is_carried_again_until_something_moves_or_unlocks(unlocked: bool) -> None:
    session = Session(timeout_s=0.5, keepalive_s=1.0)
    session.command(Command("stop"), now=0.0)
    assert _keepalive_bytes(session, now=1.0) == b"#stop!#qd!"
    # A motion frame while locked as sent moves nothing if the stop arrived (P7), and if it was
    # lost the next stop is what brings the robot to rest: only an unlock ends the repeats.
    session.command(Command("start") if unlocked else Command("th", (0, 30)), now=1.2)
    assert _keepalive_bytes(session, now=2.2) == (b"#qd!" if unlocked else b"#stop!#qd!")


def test_a_late_reply_says_whether_it_answers_a_query_of_the_sessions_own() -> None:
    # Before, a keep-alive's reply that came after it timed out was a LateReply like any
    # other: the console showed it to the pilot as the late answer to a query they never typed.
    session = Session(timeout_s=0.5, keepalive_s=1.0, record_events=True)
    session.tick(now=1.0)
    assert session.take_outbox(now=1.0) == b"#qd!"  # the keep-alive
    session.tick(now=1.5)  # it times out: qd is late, fenced by qhe
    assert session.take_outbox(now=1.5) == b"#qhe!"
    session.receive(b"$qd.5!$qhe.10!", now=1.6)
    late = [event for event in session.take_events() if isinstance(event, LateReply)]
    assert [(event.response.values, event.by_session) for event in late] == [((5,), True)]
    # A program's query that times out: its late reply is the program's.
    session.query(Command("qd"), now=2.0)
    session.tick(now=2.5)
    session.take_outbox(now=2.5)
    session.receive(b"$qd.6!$qhe.11!", now=2.6)
    late = [event for event in session.take_events() if isinstance(event, LateReply)]
    assert [(event.response.values, event.by_session) for event in late] == [((6,), False)]


@pytest.mark.parametrize("byte_by_byte", [False, True])
@pytest.mark.parametrize("enabled", [True, False])
def test_replies_to_queries_sent_before_a_mode_change_are_read_in_their_own_mode(
    enabled: bool, byte_by_byte: bool
) -> None:
    # P3: in `#qd!#crcon!` the qd reply is plain, in `#qd8C!#crcoff!` it carries a checksum;
    # a query sent after the mode frame is answered in the new mode.
    session = Session(checksum_enabled=not enabled)
    _, before = session.query(Command("qd"), now=0.0)
    session.command(Command("crcon" if enabled else "crcoff"), now=0.0)
    _, after = session.query(Command("qr"), now=0.0)
    old, new = (None, "crc8") if enabled else ("crc8", None)
    data = encode(Response("qd", (123,)), old) + encode(Response("qr", (5,)), new)
    for chunk in [data[i : i + 1] for i in range(len(data))] if byte_by_byte else [data]:
        session.receive(chunk, now=0.01)
    assert before.responses == [Response("qd", (123,))]
    assert after.responses == [Response("qr", (5,))]
    assert session.counters.bad_frames == 0


def test_after_a_mode_change_the_new_mode_holds_once_the_old_queries_are_settled() -> None:
    session = Session()
    _, before = session.query(Command("qd"), now=0.0)
    session.command(Command("crcon"), now=0.0)
    session.receive(b"$qd.1!", now=0.01)
    _, after = session.query(Command("qd"), now=0.02)
    session.receive(b"$qd.2!", now=0.03)  # plain: now dropped
    assert before.outcome is Outcome.ANSWERED
    assert after.outcome is Outcome.CORRUPT


@pytest.mark.parametrize(
    ("modes", "replies_checksummed"),
    [
        (["crcon", "crcon"], [False, True, True]),  # a mode asserted again (P21) changes nothing
        (["crcon", "crcoff"], [False, True, False]),
        (["crcoff", "crcon"], [True, False, True]),
    ],
)
def test_each_reply_is_read_in_the_mode_its_query_went_out_in(
    modes: list[str], replies_checksummed: list[bool]
) -> None:
    session = Session(checksum_enabled=replies_checksummed[0])
    queries = [session.query(Command("qd"), now=0.0)[1]]
    for mode in modes:
        session.command(Command(mode), now=0.0)
        queries.append(session.query(Command("qd"), now=0.0)[1])
    data = b"".join(
        encode(Response("qd", (value,)), "crc8" if checksummed else None)
        for value, checksummed in enumerate(replies_checksummed)
    )
    session.receive(data, now=0.01)
    assert [query.responses for query in queries] == [
        [Response("qd", (value,))] for value in range(3)
    ]


def test_a_suspected_reset_re_asserts_the_mode_and_never_unlocks_or_moves_again() -> None:
    # P21: after a reset the controller is locked; a host re-asserts its checksum mode and
    # never assumes the robot is still unlocked (no #start!, no motion sent again of itself).
    session = Session(timeout_s=0.5, checksum_enabled=True)
    written = session.command(Command("start"), now=0.0)
    written += session.command(Command("th", (0, 50)), now=0.0)
    assert written == b"#start3F!#th.0.5098!"
    now = 0.0
    after_start = b""
    for _ in range(6):  # nothing answers
        if not session.pending:
            after_start += session.query(Command("qd"), now=now)[0]
        now += 0.5
        session.tick(now)
        after_start += session.take_outbox(now)
    assert session.counters.resets_suspected == 1
    assert b"#crcon!" in after_start
    assert b"#start" not in after_start
    assert b"#th." not in after_start


def test_a_keepalive_written_ahead_of_a_mode_frame_is_answered_in_the_old_mode() -> None:
    # The drivers send #crcon! once the program's queries are answered, but a keep-alive due
    # then goes out first in the same write: its plain reply must not be a bad frame that
    # starts a resynchronisation (P3, P17).
    session = Session(keepalive_s=1.0)
    session.tick(1.5)
    assert session.command(Command("crcon"), now=1.5) == b"#qd!#crcon!"
    session.receive(b"$qd.5!", now=1.51)
    assert session.counters.bad_frames == 0
    assert session.counters.replies == 1
    assert not session.pending
