"""The asyncio client against a scripted fake controller on a socket pair."""

from __future__ import annotations

import asyncio
import logging
import math
import random
import socket
import time
from collections.abc import Awaitable, Callable
from typing import Any

import pytest

import rovlink.aio
from rovlink.aio import AsyncClient, ConnectionLostError, InvalidArgumentError, QueryTimeoutError
from rovlink.client.links import SocketLink
from rovlink.protocol import Command, Event, Response, Text, get_algorithm
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    NO_REPLY_TIMEOUT_S,
    client_options,
    wait_until_async,
)
from tests.client.fake_controller import FakeController
from tests.client.method_cases import QUERY_CASES, SET_CASES, checksummed

MakeAsyncClient = Callable[..., Awaitable[AsyncClient]]


async def _arrived(fake: FakeController, predicate: Callable[[FakeController], bool]) -> bool:
    return await asyncio.to_thread(fake.wait_for, predicate)


async def _sent_after_connect(fake: FakeController, count: int) -> bytes:
    assert await _arrived(fake, lambda f: len(f.commands) >= 1 + count)
    raw = bytes(fake.raw)
    for connect_frame in (b"#crcon!", b"#crcoff!"):
        if raw.startswith(connect_frame):
            return raw[len(connect_frame) :]
    raise AssertionError(f"no checksum mode frame first: {raw!r}")


@pytest.mark.parametrize(("method", "args", "kwargs", "frames"), SET_CASES)
@pytest.mark.parametrize("checksum", [False, True])
async def test_set_commands_send_exact_frames(
    fake: FakeController,
    make_async_client: MakeAsyncClient,
    method: str,
    args: tuple[Any, ...],
    kwargs: dict[str, Any],
    frames: list[bytes],
    checksum: bool,
) -> None:
    client = await make_async_client(checksum=checksum)
    assert await getattr(client, method)(*args, **kwargs) is None
    if checksum:
        frames = [checksummed(f) for f in frames]
    assert await _sent_after_connect(fake, len(frames)) == b"".join(frames)


@pytest.mark.parametrize(("method", "frame", "expected"), QUERY_CASES)
@pytest.mark.parametrize("checksum", [False, True])
async def test_queries_send_exact_frames_and_decode_replies(
    fake: FakeController,
    make_async_client: MakeAsyncClient,
    method: str,
    frame: bytes,
    expected: Any,
    checksum: bool,
) -> None:
    client = await make_async_client(checksum=checksum)
    assert await getattr(client, method)() == expected
    if checksum:
        frame = frame[:-1] + get_algorithm("crc8").digits(frame[1:-1]) + b"!"
    assert await _sent_after_connect(fake, 1) == frame


async def test_invalid_arguments_send_nothing(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client()
    with pytest.raises(InvalidArgumentError, match="hold_depth: depth_cm must be in 0–9999"):
        await client.hold_depth(12000)
    with pytest.raises(InvalidArgumentError, match="p must be in 0–99"):
        await client.set_depth_pid(p=100, i=1)
    await client.stop()
    assert await _sent_after_connect(fake, 1) == b"#stop!"


async def test_many_concurrent_queries_are_matched_in_order(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    fake.qd_counts_queries = True
    client = await make_async_client(max_in_flight=16)
    depths = await asyncio.gather(*(client.depth_cm() for _ in range(300)))
    assert sorted(depths) == list(range(1, 301))
    assert client.counters.replies == 300
    assert client.counters.retries == 0


async def test_many_concurrent_mixed_queries_get_their_own_replies(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client(max_in_flight=8)
    rng = random.Random(7)
    cases = [rng.choice(QUERY_CASES) for _ in range(200)]
    results = await asyncio.gather(*(getattr(client, method)() for method, _, _ in cases))
    assert results == [expected for _, _, expected in cases]


async def test_a_query_with_no_reply_times_out_after_its_retries(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client(retries=1, timeout_s=NO_REPLY_TIMEOUT_S)
    fake.then(*["drop"] * 10)  # a silent controller: the fences (P20) go unanswered too
    with pytest.raises(QueryTimeoutError) as caught:
        await client.roll_deg()
    assert caught.value.query == Command("qro")
    assert caught.value.failures == ("timeout", "timeout")
    assert caught.value.port == "socket pair"
    assert str(caught.value).endswith("(2 attempts: timeout, timeout) on socket pair")
    counters = client.counters
    assert counters.retries == 1
    # The unanswered fences (P20) time out too.
    assert counters.timeouts >= 2
    assert counters.fences >= 1
    assert fake.frames().count("#qro!") == 2


async def test_a_corrupt_reply_is_retried_at_once(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client(retries=1)
    fake.then("corrupt")
    assert await client.roll_deg() == -1
    counters = client.counters
    assert (counters.timeouts, counters.retries, counters.bad_frames) == (0, 1, 1)


async def test_a_lost_reply_among_many_in_flight_is_retried(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client()
    fake.then("reply", "drop")
    depth, heading, roll = await asyncio.gather(
        client.depth_cm(), client.heading_deg(), client.roll_deg()
    )
    assert (depth, heading, roll) == (123, 275, -1)
    # The controller answered roll before heading: heading was lost at once, not timed out.
    assert client.counters.timeouts == 0
    assert client.counters.retries == 1


async def test_checksum_switch_waits_for_queries_in_flight(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client()
    before = [asyncio.ensure_future(client.sensors()) for _ in range(10)]
    await asyncio.sleep(0)  # let them reach the wire
    switch = asyncio.ensure_future(client.set_checksum(True))
    after = [asyncio.ensure_future(client.depth_cm()) for _ in range(10)]
    await asyncio.gather(*before, switch, *after)
    assert client.checksum_enabled
    assert client.counters.retries == 0
    assert fake.bad_frames == []
    # Every query asked for after the switch goes out in the new mode. (Calls that waited behind
    # it go out as the event loop wakes them: a depth handed a freed slot just as the switch
    # ended may go before a sensors() that had waited for the switch itself.)
    raw = bytes(fake.raw)
    assert raw.count(b"#qd8C!") == 10
    assert b"#qd!" not in raw


async def test_debug_text_goes_to_the_callback_and_the_log(
    fake: FakeController,
    make_async_client: MakeAsyncClient,
    caplog: pytest.LogCaptureFixture,
) -> None:
    seen: list[Event] = []
    client = await make_async_client(on_stray=seen.append)
    fake.then("debug")
    with caplog.at_level(logging.INFO, logger="rovlink.client"):
        assert await client.pitch_deg() == 15
        assert await wait_until_async(lambda: len(seen) >= 2)
    assert [type(event) for event in seen] == [Text, Text]
    assert any("depth pid" in record.getMessage() for record in caplog.records)


async def test_disconnect_fails_pending_and_later_calls(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client(timeout_s=5.0)
    fake.then("drop", "close")
    first = asyncio.ensure_future(client.depth_cm())
    second = asyncio.ensure_future(client.heading_deg())
    for future in (first, second):
        with pytest.raises(ConnectionLostError):
            await future
    assert client.closed
    with pytest.raises(ConnectionLostError):
        await client.stop()


async def test_close_fails_waiting_queries(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    # Every attempt is dropped, and there are enough of them for the query to be still
    # waiting however late close() comes.
    client = await make_async_client(timeout_s=NO_REPLY_TIMEOUT_S, retries=10)
    fake.then(*["drop"] * 11)
    waiting = asyncio.ensure_future(client.depth_cm())
    assert await _arrived(fake, lambda f: "#qd!" in f.frames())
    await client.close()
    with pytest.raises(ConnectionLostError):
        await waiting


async def test_keepalive(fake: FakeController, make_async_client: MakeAsyncClient) -> None:
    client = await make_async_client(keepalive_s=0.02)
    assert await _arrived(fake, lambda f: f.frames().count("#qd!") >= 3)
    assert client.counters.keepalives >= 3


async def test_telemetry_as_fast_as_possible(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client()
    readings = []
    async for reading in client.telemetry(None):
        readings.append(reading)
        if len(readings) == 50:
            break
    assert all(reading.heading_deg == 275 for reading in readings)


async def test_closing_after_telemetry_lets_the_polls_in_flight_be_answered(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client(max_in_flight=8)
    count = 0
    async for _ in client.telemetry(None):
        count += 1
        # Stop while polls are in flight (after 20 readings; a loaded machine may first let
        # the pipeline drain for a moment).
        if count >= 20 and fake.frames().count("#qsa!") > count:
            break
    await client.close()
    # Every #qsa! on the wire got its reply before the port closed: none is left over.
    assert client.counters.replies == fake.frames().count("#qsa!") > count


async def test_telemetry_keeps_its_rate(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client()
    started = time.monotonic()
    count = 0
    async for _ in client.telemetry(50):
        count += 1
        if count == 6:
            break
    elapsed_s = time.monotonic() - started
    # Six polls at 50 Hz start 0.1 s apart at the least, however fast the replies come; and
    # however slow they come, no more polls went out than the rate allows in the time it took.
    assert elapsed_s >= 5 / 50 - 0.005
    assert 6 <= fake.frames().count("#qsa!") <= 1 + elapsed_s * 50 + 0.01


async def test_telemetry_skips_a_reading_that_timed_out(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    # The dropped poll costs the whole timeout: a short one would put the replies that follow
    # at risk on a loaded machine.
    client = await make_async_client(retries=0, max_in_flight=1)
    fake.then("drop")
    readings = []
    async for reading in client.telemetry(None):
        readings.append(reading)
        if len(readings) == 2:
            break
    assert client.counters.timeouts == 1


async def test_telemetry_rejects_a_bad_rate(make_async_client: MakeAsyncClient) -> None:
    client = await make_async_client()
    for rate_hz in (0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="rate_hz must be a positive number"):
            async for _ in client.telemetry(rate_hz):
                pass
    # A wrong type is a TypeError, as for the connection's settings (before: a ValueError; and a
    # rate of NaN polled with no pause).
    for wrong in ("10", True):
        with pytest.raises(TypeError, match="rate_hz must be a positive number"):
            async for _ in client.telemetry(wrong):  # type: ignore[arg-type]
                pass


async def test_send_and_send_raw(
    fake: FakeController,
    make_async_client: MakeAsyncClient,
) -> None:
    client = await make_async_client()
    assert await client.send(Command("q.l")) == (Response("q.l", (0,)),)
    assert await client.send_raw("#qro!") == (Response("qro", (-1,)),)
    assert await client.send_raw("#nonsense!") == ()
    # "#nonsense!" is no command: wait for its bytes rather than for a command.
    assert await _arrived(fake, lambda f: bytes(f.raw).endswith(b"#nonsense!"))
    assert await _sent_after_connect(fake, 2) == b"#q.l!#qro!#nonsense!"


async def test_leaving_async_with_by_an_error_stops_the_robot(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client()

    async def failing_program() -> None:
        async with client:
            await client.move(90, 30)
            raise KeyError("bug")

    with pytest.raises(KeyError):
        await failing_program()
    assert await _arrived(fake, lambda f: f.frames()[-1:] == ["#stop!"])
    assert client.closed


async def test_bad_options_are_rejected_before_connecting() -> None:
    import rovlink.aio

    with pytest.raises(ValueError, match="max_in_flight"):
        rovlink.aio.connect("sim://", max_in_flight=0)
    # A value of the wrong type is a TypeError, as every other setting's is (it was a ValueError).
    for wrong_type in (1.5, "8", True, None):
        with pytest.raises(TypeError, match=r"max_in_flight must be an integer ≥ 1, got "):
            rovlink.aio.connect("sim://", max_in_flight=wrong_type)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="timeout must be a positive number"):
        rovlink.aio.connect("sim://", timeout=-1)
    with pytest.raises(ValueError, match="unknown sim option"):
        rovlink.aio.connect("sim://?bogus=1")


@pytest.mark.integration
async def test_a_query_queued_behind_max_in_flight_fails_when_the_tcp_link_is_lost() -> None:
    """A caller waiting for a free slot (max_in_flight) while the TCP link is lost fails with
    ConnectionLostError once it has the slot, instead of queueing its query on the dead link,
    where nothing would ever settle it (a write to a peer that has closed still succeeds)."""
    server = socket.create_server(("127.0.0.1", 0))
    host_end = socket.create_connection(server.getsockname())
    controller_end, _ = server.accept()
    server.close()
    fake = FakeController(controller_end.detach())
    options = client_options(retries=0)
    client = await AsyncClient(SocketLink(host_end, "tcp"), options, max_in_flight=1).open()
    try:
        fake.then("drop")  # the first query stays on the wire, holding the only slot
        first = asyncio.ensure_future(client.depth_cm())
        assert await asyncio.to_thread(fake.wait_for, lambda f: "#qd!" in f.frames())
        second = asyncio.ensure_future(client.heading_deg())  # waits for the slot
        for _ in range(5):
            await asyncio.sleep(0)
        assert not second.done()
        fake.close()  # the controller goes away (FIN)
        with pytest.raises(ConnectionLostError):
            await first
        try:
            await asyncio.wait_for(second, 3.0)  # settles at once when the bug is fixed
        except ConnectionLostError:
            pass  # as it should: the link is gone
        except (TimeoutError, asyncio.TimeoutError):
            pending = [str(query.command) for query in client._session.pending]
            pytest.fail(f"the queued query never settled after the link was lost: {pending}")
        assert client._session.pending == ()
    finally:
        await client.close()
        fake.close()


async def test_a_query_queued_behind_max_in_flight_is_not_left_in_the_session_on_reconnect() -> (
    None
):
    """With reconnect=True, a caller that waited for a slot while the link was lost leaves no
    query in the session's queue: none takes a reply meant for a query on the new link, and no
    retry or timeout is counted that nothing on the wire caused."""
    fakes: list[FakeController] = []

    def open_pair() -> SocketLink:
        fake, host_end = FakeController.on_socketpair()
        fakes.append(fake)
        return SocketLink(host_end, f"socket pair {len(fakes)}")

    options = client_options(timeout_s=0.5, retries=2, reconnect=True)
    client = await AsyncClient(open_pair(), options, max_in_flight=1, reopen=open_pair).open()
    try:
        fakes[0].then("drop")
        first = asyncio.ensure_future(client.depth_cm())
        assert await asyncio.to_thread(fakes[0].wait_for, lambda f: "#qd!" in f.frames())
        second = asyncio.ensure_future(client.heading_deg())  # waits for the slot
        for _ in range(5):
            await asyncio.sleep(0)
        assert not second.done()
        fakes[0].close()  # unplugged
        for future in (first, second):
            with pytest.raises(ConnectionLostError):
                await future
        stale = [str(query.command) for query in client._session.pending]
        assert stale == [], "a query that no caller waits for is queued for the new link"
        await asyncio.wait_for(client._link_ready.wait(), CONDITION_TIMEOUT_S)
        assert await client.heading_deg() == 275
        assert client.counters.timeouts == 0
        assert client.counters.retries == 0
    finally:
        await client.close()
        for fake in fakes:
            fake.close()


async def test_a_connect_not_awaited_says_to_await_it() -> None:
    # (Before: "'_Connecting' object has no attribute 'depth_cm'", a private class's name.)
    connecting = rovlink.aio.connect("sim://")
    with pytest.raises(AttributeError, match=r"no 'depth_cm': await it first \(rov = await rov"):
        connecting.depth_cm  # type: ignore[attr-defined]  # noqa: B018 (mypy says so too)


def test_a_connect_in_a_plain_with_says_to_use_async_with() -> None:
    # (Before: "'_Connecting' object does not support the context manager protocol", or on
    # Python 3.10 "AttributeError: __enter__".)
    with (
        pytest.raises(TypeError, match=r"use async with rovlink\.aio\.connect\(url\) as rov"),
        rovlink.aio.connect("sim://"),  # type: ignore[attr-defined]  # (what mypy says)
    ):
        pass
