"""P20: a reply that comes after its query timed out is never handed to a later query.

The controller here stalls for 0.35 s on the first query and then answers everything in order,
numbering its ``qd`` replies by the queries it received; the program asks ``depth_cm()`` eight
times, 0.1 s apart, with a 0.25 s timeout. Before the session resynchronised after a timeout,
the late reply went to the next query: ``[timeout, 2, 1, 3, 5, 6, 7, 8]``.
"""

from __future__ import annotations

import asyncio
import time

import pytest

from rovlink.client.errors import QueryTimeoutError
from rovlink.client.events import ClientEvent, LateReply
from tests.client.fake_controller import FakeController
from tests.client.test_aio import MakeAsyncClient
from tests.client.test_blocking import MakeClient

TIMEOUT_S = 0.5  # (the field report's 0.25 s and 0.35 s, doubled for a loaded machine)
STALL_S = 0.7
CALLS = 8
PAUSE_S = 0.1  # the program's own pace between calls, as in the field report


def _check(results: list[int | None], late: list[ClientEvent], late_count: int) -> None:
    assert results[0] is None  # the first query timed out
    values = [value for value in results if value is not None]
    # Never the stalled reply (number 1), never out of order, never twice.
    assert 1 not in values
    assert values == sorted(set(values))
    assert len(values) >= CALLS // 2  # (on a loaded machine another query may time out too)
    assert late_count >= 1
    late_values = [event.response.values for event in late if isinstance(event, LateReply)]
    assert late_values[0] == (1,)


def test_the_blocking_client_discards_a_late_reply(
    fake: FakeController, make_client: MakeClient
) -> None:
    events: list[ClientEvent] = []
    client = make_client(timeout_s=TIMEOUT_S, retries=0, on_event=events.append)
    fake.qd_counts_queries = True
    fake.late_delay_s = STALL_S
    fake.then("late")
    results: list[int | None] = []
    for _ in range(CALLS):
        try:
            results.append(client.depth_cm())
        except QueryTimeoutError:
            results.append(None)
        time.sleep(PAUSE_S)
    _check(results, events, client.counters.late_replies)


async def test_the_asyncio_client_discards_a_late_reply(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    events: list[ClientEvent] = []
    client = await make_async_client(timeout_s=TIMEOUT_S, retries=0, on_event=events.append)
    fake.qd_counts_queries = True
    fake.late_delay_s = STALL_S
    fake.then("late")
    results: list[int | None] = []
    for _ in range(CALLS):
        try:
            results.append(await client.depth_cm())
        except QueryTimeoutError:
            results.append(None)
        await asyncio.sleep(PAUSE_S)
    _check(results, events, client.counters.late_replies)


@pytest.mark.parametrize("chunk", [1, 3, 1000])
def test_session_fence_byte_by_byte_and_whole(chunk: int) -> None:
    from rovlink.client.session import Outcome, Session
    from rovlink.protocol import Command

    session = Session(timeout_s=0.25)
    _, first = session.query(Command("qd"), now=0.0)
    assert session.tick(now=0.25) == [first]
    assert first.outcome is Outcome.TIMEOUT
    data, second = session.query(Command("qd"), now=0.35)
    assert data == b"#qhe!#qd!"  # the fence goes first
    stream = b"$qd.1!$qhe.90!$qd.3!"
    for start in range(0, len(stream), chunk):
        session.receive(stream[start : start + chunk], now=0.36)
    assert second.outcome is Outcome.ANSWERED
    assert second.responses[0].values == (3,)
    assert session.counters.late_replies == 1
    assert not session.resynchronising
