"""The asyncio client when its callers give up: a query cancelled at every point (waiting for a
slot, for a checksum switch, for its reply; by ``wait_for``, ``asyncio.timeout`` or a failing
``TaskGroup``), ``close()`` cancelled or called twice, many tasks at once on a lossy line, and
event hooks that raise or call back into the client.

After each, no later query gets a reply meant for another (P20), no ``max_in_flight`` slot is
lost, the client stays usable, and no task or future is left with an exception nobody retrieved.
"""

from __future__ import annotations

import asyncio
import gc
import random
import socket
import sys
import threading
from collections.abc import AsyncIterator, Awaitable, Callable, Coroutine, Iterator
from typing import Any

import pytest

import rovlink.aio
import rovlink.aio.client
from rovlink.aio import AsyncClient, ConnectionLostError, QueryTimeoutError, Sensors
from rovlink.client.events import BytesReceived, BytesSent, ClientEvent, ReplyReceived
from rovlink.client.links import Link, PortLink, SocketLink
from rovlink.client.url import Endpoint
from rovlink.protocol import Response, encode, get_algorithm
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    NO_REPLY_TIMEOUT_S,
    client_options,
    wait_until,
    wait_until_async,
)
from tests.client.fake_controller import FakeController

pytestmark = pytest.mark.integration

Timeouts = (TimeoutError, asyncio.TimeoutError)  # one class from Python 3.11 on


@pytest.fixture
async def loop_errors() -> AsyncIterator[list[dict[str, Any]]]:
    """What the loop's exception handler got (``Task exception was never retrieved``…); checked
    empty after the test, once the garbage holding such tasks and futures is collected."""
    loop = asyncio.get_running_loop()
    errors: list[dict[str, Any]] = []
    loop.set_exception_handler(lambda _, context: errors.append(context))
    yield errors
    gc.collect()
    await asyncio.sleep(0)
    loop.set_exception_handler(None)
    assert [context.get("message") for context in errors] == []


@pytest.fixture
def pair() -> Iterator[tuple[FakeController, socket.socket]]:
    """A fake whose ``$qd.N!`` numbers the queries it received, and the client's end."""
    fake, sock = FakeController.on_socketpair()
    fake.qd_counts_queries = True
    yield fake, sock
    fake.close()


async def _client(sock: socket.socket, max_in_flight: int = 8, **overrides: Any) -> AsyncClient:
    options = client_options(**overrides)
    link = SocketLink(sock, "socket pair")
    return await AsyncClient(link, options, max_in_flight=max_in_flight).open()


async def _arrived(fake: FakeController, predicate: Callable[[FakeController], bool]) -> None:
    assert await asyncio.to_thread(fake.wait_for, predicate, CONDITION_TIMEOUT_S)


async def _assert_usable(fake: FakeController, client: AsyncClient, max_in_flight: int) -> None:
    """Nothing is left in flight, every slot is free, and the next query gets its own reply."""
    assert await wait_until_async(lambda: client._session.pending == ())
    assert not client._session.resynchronising
    assert client._in_flight.free == max_in_flight, "a max_in_flight slot was lost"
    depth = await asyncio.wait_for(client.depth_cm(), CONDITION_TIMEOUT_S)
    assert depth == fake.query_count, "the reply to an earlier query was taken for this one"


# -- one query, cancelled at each point ------------------------------------------------------


async def test_cancelled_while_waiting_for_a_slot(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]]
) -> None:
    fake, sock = pair
    fake.late_delay_s = 0.2
    client = await _client(sock, max_in_flight=1)
    fake.then("late")  # the first query holds the only slot until its reply comes
    first = asyncio.ensure_future(client.depth_cm())
    await _arrived(fake, lambda f: f.query_count == 1)
    queued = asyncio.ensure_future(client.heading_deg())
    await asyncio.sleep(0.01)
    assert not queued.done()
    queued.cancel()
    assert await first == 1
    with pytest.raises(asyncio.CancelledError):
        await queued
    assert "#qhe!" not in fake.frames()  # it never reached the wire
    await _assert_usable(fake, client, 1)
    await client.close()


async def test_cancelled_while_awaiting_its_reply(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]]
) -> None:
    fake, sock = pair
    fake.late_delay_s = 0.3
    client = await _client(sock, max_in_flight=2)
    fake.then("late")
    with pytest.raises(Timeouts):
        await asyncio.wait_for(client.depth_cm(), 0.05)
    # Its reply ($qd.1!) is still on its way: the next query must get $qd.2!, not it.
    assert await asyncio.wait_for(client.depth_cm(), CONDITION_TIMEOUT_S) == 2
    await _assert_usable(fake, client, 2)
    await client.close()


async def test_a_cancelled_query_keeps_its_slot_until_its_reply_comes(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]]
) -> None:
    """Its frame is on the wire whether its caller waits or not: the line never carries more
    than ``max_in_flight`` queries (before, the slot was given back at once, and the next
    query went out while the cancelled one was still unanswered)."""
    fake, sock = pair
    fake.late_delay_s = 0.3
    events: list[ClientEvent] = []
    client = await _client(sock, max_in_flight=1, on_event=events.append)
    fake.then("late")
    with pytest.raises(Timeouts):
        await asyncio.wait_for(client.depth_cm(), 0.05)
    assert client._in_flight.free == 0
    assert await asyncio.wait_for(client.depth_cm(), CONDITION_TIMEOUT_S) == 2
    wire = [
        (event.direction, event.data)
        for event in events
        if isinstance(event, (BytesSent, BytesReceived))
    ]
    assert wire[-4:] == [  # (after the checksum mode frame of the connection)
        ("out", b"#qd!"),
        ("in", b"$qd.1!"),
        ("out", b"#qd!"),
        ("in", b"$qd.2!"),
    ]
    await _assert_usable(fake, client, 1)
    await client.close()


@pytest.mark.parametrize("first", ["typed", "raw"])
async def test_a_raw_query_waits_for_a_slot_and_keeps_it_as_any_query(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]], first: str
) -> None:
    """Before, ``send_raw`` took no ``max_in_flight`` slot: a raw query went on the wire beside
    as many queries as the line was meant to carry (a console's ``#qsa!`` beside a
    ``telemetry`` loop's eight), and its slot was not held when its caller was cancelled."""
    fake, sock = pair
    client = await _client(sock, max_in_flight=1)
    fake.then("hold")
    on_the_wire = asyncio.ensure_future(
        client.depth_cm() if first == "typed" else client.send_raw("#qd!")
    )
    await _arrived(fake, lambda f: f.query_count == 1)
    sent = client.counters.frames_sent
    second = asyncio.ensure_future(
        client.send_raw("#qhe!") if first == "typed" else client.heading_deg()
    )
    for _ in range(3):  # (the call writes before its first wait, if it may)
        await asyncio.sleep(0)
    assert client.counters.frames_sent == sent, "a second query on a line that carries one"
    on_the_wire.cancel()  # cancelled on the wire: it keeps the slot until its reply comes
    for _ in range(3):
        await asyncio.sleep(0)
    assert client.counters.frames_sent == sent
    fake.release()
    replies = await asyncio.wait_for(second, CONDITION_TIMEOUT_S)
    assert replies == ((Response("qhe", (275,)),) if first == "typed" else 275)
    with pytest.raises(asyncio.CancelledError):
        await on_the_wire
    await _assert_usable(fake, client, 1)
    await client.close()


async def test_cancelled_reply_wait_then_timed_out_is_fenced(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]]
) -> None:
    """A cancelled query whose reply then comes after its timeout: the late reply is discarded
    (P20), not handed to a query sent after the timeout."""
    fake, sock = pair
    # Its reply comes 0.2 s after its timeout and 0.2 s before the next query's.
    fake.late_delay_s = 0.6
    client = await _client(sock, max_in_flight=2, timeout_s=0.4, retries=0)
    fake.then("late")
    with pytest.raises(Timeouts):
        await asyncio.wait_for(client.depth_cm(), 0.05)
    assert await wait_until_async(lambda: client.counters.timeouts == 1)
    assert await asyncio.wait_for(client.depth_cm(), CONDITION_TIMEOUT_S) == fake.query_count
    assert client.counters.late_replies == 1
    await _assert_usable(fake, client, 2)
    await client.close()


#: The ways a caller's deadline cancels a query; ``asyncio.timeout`` exists from 3.11 on.
DEADLINES = ["wait_for", *(["asyncio.timeout"] if sys.version_info >= (3, 11) else [])]
#: The ways a failing sibling task cancels the others: by hand (as a supervisor does on any
#: Python), and ``asyncio.TaskGroup`` from 3.11 on.
GROUPS = ["by hand", *(["TaskGroup"] if sys.version_info >= (3, 11) else [])]


async def _within(deadline: str, seconds: float, awaitable: Awaitable[object]) -> None:
    if deadline == "wait_for":
        await asyncio.wait_for(awaitable, seconds)
    elif sys.version_info >= (3, 11):  # (mypy checks as 3.10)
        async with asyncio.timeout(seconds):
            await awaitable


async def _as_a_group(group: str, coroutines: list[Coroutine[Any, Any, object]]) -> None:
    """Run the coroutines as tasks until one fails; then cancel the others and raise its error
    (inside an ExceptionGroup with a TaskGroup)."""
    if group == "TaskGroup" and sys.version_info >= (3, 11):
        async with asyncio.TaskGroup() as task_group:
            for coroutine in coroutines:
                task_group.create_task(coroutine)
        return
    tasks = [asyncio.ensure_future(coroutine) for coroutine in coroutines]
    done, running = await asyncio.wait(tasks, return_when=asyncio.FIRST_EXCEPTION)
    for task in running:
        task.cancel()
    await asyncio.gather(*running, return_exceptions=True)
    for task in done:
        if not task.cancelled() and task.exception() is not None:
            for other in done:  # (retrieved: no "exception was never retrieved" later)
                if not other.cancelled():
                    other.exception()
            raise task.exception()  # type: ignore[misc]


@pytest.mark.parametrize("deadline", DEADLINES)
async def test_cancelled_by_the_callers_deadline(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]], deadline: str
) -> None:
    fake, sock = pair
    fake.late_delay_s = 0.2
    client = await _client(sock, max_in_flight=3, timeout_s=0.5)
    fake.then("late")
    with pytest.raises(Timeouts):
        await _within(deadline, 0.05, client.sensors())
    await _assert_usable(fake, client, 3)
    await client.close()


@pytest.mark.parametrize("group", GROUPS)
async def test_cancelled_by_a_failing_sibling_task(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]], group: str
) -> None:
    fake, sock = pair
    fake.late_delay_s = 0.2
    client = await _client(sock, max_in_flight=3, timeout_s=0.5)

    async def fail_soon() -> None:
        await asyncio.sleep(0.02)
        raise KeyError("a sibling task failed")

    fake.then("drop", "late")
    coroutines: list[Coroutine[Any, Any, object]] = [client.depth_cm() for _ in range(6)]
    # (three on the wire, three waiting for a slot)
    with pytest.raises(Exception) as caught:  # noqa: PT011 - the KeyError, or a group of it
        await _as_a_group(group, [*coroutines, client.sensors(), fail_soon()])
    if group == "TaskGroup":
        assert caught.group_contains(KeyError)
    else:
        assert isinstance(caught.value, KeyError)
    await _assert_usable(fake, client, 3)
    await client.close()


async def test_cancelled_while_waiting_for_a_checksum_switch(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]]
) -> None:
    fake, sock = pair
    fake.late_delay_s = 0.2
    client = await _client(sock, max_in_flight=2)
    fake.then("late")
    on_the_wire = asyncio.ensure_future(client.depth_cm())
    await _arrived(fake, lambda f: f.query_count == 1)
    switch = asyncio.ensure_future(client.set_checksum(True))  # waits for that reply
    await asyncio.sleep(0)
    waiting = asyncio.ensure_future(client.heading_deg())  # waits for the switch
    await asyncio.sleep(0.01)
    waiting.cancel()
    assert await on_the_wire == 1
    await switch
    with pytest.raises(asyncio.CancelledError):
        await waiting
    assert client.checksum_enabled
    assert "#qhe!" not in fake.frames()
    await _assert_usable(fake, client, 2)
    assert fake.bad_frames == []
    await client.close()


async def test_a_checksum_switch_cancelled_while_it_drains(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]]
) -> None:
    """The switch is not sent, the queries that waited for it go on in the old mode, and a
    later switch works."""
    fake, sock = pair
    fake.late_delay_s = 0.2
    client = await _client(sock, max_in_flight=2)
    fake.then("late")
    on_the_wire = asyncio.ensure_future(client.depth_cm())
    await _arrived(fake, lambda f: f.query_count == 1)
    switch = asyncio.ensure_future(client.set_checksum(True))
    await asyncio.sleep(0)
    waiting = asyncio.ensure_future(client.heading_deg())
    await asyncio.sleep(0.01)
    switch.cancel()
    assert await waiting == 275
    assert await on_the_wire == 1
    assert not client.checksum_enabled
    assert "#crcon!" not in fake.frames()
    await client.set_checksum(True)
    assert client.checksum_enabled
    await _assert_usable(fake, client, 2)
    assert fake.bad_frames == []
    await client.close()


# -- two checksum switches back to back ------------------------------------------------------


class _Wire:
    """The controller's end of a socket pair, played by the test: what the host wrote."""

    def __init__(self, sock: socket.socket) -> None:
        sock.setblocking(False)
        self.sock = sock
        self.seen = b""

    async def until(self, predicate: Callable[[bytes], bool]) -> bytes:
        loop = asyncio.get_running_loop()
        while not predicate(self.seen):
            data = await asyncio.wait_for(loop.sock_recv(self.sock, 4096), CONDITION_TIMEOUT_S)
            assert data, f"the host closed the line; it wrote {self.seen!r}"
            self.seen += data
        return self.seen


async def test_a_query_woken_as_one_switch_ends_waits_for_the_next_switch(
    loop_errors: list[dict[str, Any]],
) -> None:
    """A query waiting for a checksum switch is woken when it ends; if another switch starts
    before the query runs, it must wait for that one too. Before the fix it went on the wire
    while the second switch drained, in the first switch's mode, and its reply — sent by the
    controller in that mode — came after the second switch and failed as corrupt."""
    host_end, controller_end = socket.socketpair()
    wire = _Wire(controller_end)
    client = await AsyncClient(
        SocketLink(host_end, "socket pair"), client_options(retries=0)
    ).open()
    try:
        await wire.until(lambda seen: seen == b"#crcoff!")  # the connection's mode
        roll = asyncio.ensure_future(client.roll_deg())
        await wire.until(lambda seen: seen.endswith(b"#qro!"))
        switch_on = asyncio.ensure_future(client.set_checksum(True))  # drains roll
        await asyncio.sleep(0)
        depth = asyncio.ensure_future(client.depth_cm())  # wakes first, as switch_on ends
        await asyncio.sleep(0)
        switch_off = asyncio.ensure_future(client.set_checksum(False))  # then drains depth
        await asyncio.sleep(0)
        heading = asyncio.ensure_future(client.heading_deg())  # must wait for switch_off
        await asyncio.sleep(0)
        controller_end.send(b"$qro.-1!")
        await wire.until(lambda seen: seen.endswith(b"#crcon!#qd8C!") or b"#qhe" in seen)
        controller_end.send(encode(Response("qd", (7,)), get_algorithm("crc8")))
        seen = await wire.until(lambda seen: b"#qhe" in seen and seen.count(b"#crcoff!") == 2)
        # Answered as a controller would: in the mode the query arrived in (P3).
        checksummed = b"#qhe6D!" in seen
        reply = Response("qhe", (275,))
        controller_end.send(encode(reply, get_algorithm("crc8") if checksummed else None))
        assert seen == b"#crcoff!#qro!#crcon!#qd8C!#crcoff!#qhe!"
        assert await asyncio.wait_for(heading, CONDITION_TIMEOUT_S) == 275
        assert (await roll, await depth) == (-1, 7)
        await switch_on
        await switch_off
        assert client.counters.bad_frames == 0
    finally:
        await client.close()
        controller_end.close()


# -- many tasks on a lossy line ---------------------------------------------------------------


@pytest.mark.parametrize("checksum", [False, True])
async def test_many_tasks_on_a_lossy_line_each_get_their_own_reply_or_an_error(
    pair: tuple[FakeController, socket.socket],
    loop_errors: list[dict[str, Any]],
    checksum: bool,
) -> None:
    """Queries of one name and of several (``qsa`` with its six replies), while the controller
    drops, corrupts and delays replies and callers give up at random: every call returns the
    reply to its own query or raises QueryTimeoutError, and none hangs."""
    fake, sock = pair
    fake.late_delay_s = 0.15  # longer than the timeout: its replies come late (P20)
    rng = random.Random(20240611 + checksum)
    actions = ["reply"] * 30 + ["drop"] * 2 + ["corrupt"] * 2 + ["late", "debug", "noise"]
    events: list[ClientEvent] = []
    client = await _client(
        sock, max_in_flight=4, timeout_s=0.1, retries=2, checksum=checksum, on_event=events.append
    )
    fake.then(*rng.choices(actions, k=2000))
    methods = ["depth_cm", "depth_cm", "depth_cm", "heading_deg", "roll_deg", "sensors"]
    calls = [rng.choice(methods) for _ in range(150)]
    tasks = [asyncio.ensure_future(getattr(client, method)()) for method in calls]
    loop = asyncio.get_running_loop()
    for task in rng.sample(tasks, 25):
        loop.call_later(rng.uniform(0.0, 0.5), task.cancel)
    _, hanging = await asyncio.wait(tasks, timeout=30.0)
    assert not hanging, f"{len(hanging)} calls never returned"
    # The queries the host wrote, in order: the fake numbers them 1, 2, … in the same order.
    written = [
        event
        for event in events
        if isinstance(event, BytesSent) and event.command is not None
        if event.command.spec.is_query
    ]
    depths = []
    outcomes = {"answered": 0, "timed out": 0, "cancelled": 0}
    for method, task in zip(calls, tasks, strict=True):
        if task.cancelled():
            outcomes["cancelled"] += 1
            continue
        error = task.exception()
        if error is not None:
            assert isinstance(error, QueryTimeoutError), repr(error)
            outcomes["timed out"] += 1
            continue
        outcomes["answered"] += 1
        result = task.result()
        if method == "heading_deg":
            assert result == 275
        elif method == "roll_deg":
            assert result == -1
        else:
            depth = result.depth_cm if isinstance(result, Sensors) else result
            if isinstance(result, Sensors):
                assert (result.heading_deg, result.roll_deg, result.pitch_deg) == (275, -1, 15)
            # $qd.N! answers the N-th query. A qsa's six are its own; a depth may be a qsa's
            # first reply when the reply of the query ahead was dropped: without sequence
            # numbers that cannot be told apart (P20 protects from late replies, not this).
            sent = written[depth - 1].command
            assert sent is not None
            kinds = ("qsa",) if isinstance(result, Sensors) else ("qd", "qsa")
            assert sent.name in kinds, (method, depth, written[depth - 3 : depth + 2])
            depths.append(depth)
    assert len(depths) == len(set(depths)), "one reply went to two callers"
    assert outcomes["answered"] > 100, outcomes
    replies = [event for event in events if isinstance(event, ReplyReceived)]
    assert replies
    await _assert_usable(fake, client, 4)
    await client.close()


# -- close ------------------------------------------------------------------------------------


async def test_close_cancelled_while_draining_still_releases_the_port(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]]
) -> None:
    """Before the fix a cancelled close() (``wait_for``, ``asyncio.timeout``, a TaskGroup)
    left the port open and its timer running, the waiting query unsettled, and the next
    close() returned at once without releasing anything."""
    fake, sock = pair
    client = await _client(sock, timeout_s=CONDITION_TIMEOUT_S, keepalive_s=0.05)
    fake.then("drop")
    waiting = asyncio.ensure_future(client.depth_cm())
    await _arrived(fake, lambda f: f.query_count == 1)
    with pytest.raises(Timeouts):
        await asyncio.wait_for(client.close(), 0.05)  # the drain waits for the dropped reply
    assert client.closed
    assert sock.fileno() == -1, "the port is still open"
    assert client._timer is None, "a timer is left running"
    with pytest.raises(ConnectionLostError):
        await asyncio.wait_for(waiting, CONDITION_TIMEOUT_S)
    await asyncio.wait_for(client.close(), CONDITION_TIMEOUT_S)  # closing again is harmless
    with pytest.raises(ConnectionLostError):
        await client.depth_cm()


async def test_close_cancelled_while_the_reader_thread_stops_still_closes_the_port(
    loop_errors: list[dict[str, Any]],
) -> None:
    """A port without a descriptor (``sim://``) is read by a thread, which close() waits for;
    cancelled then, close() left the port open before the fix."""
    rov = await rovlink.aio.connect("sim://", keepalive=None, timeout=CONDITION_TIMEOUT_S)
    link = rov._link
    assert isinstance(link, PortLink)
    closing = asyncio.ensure_future(rov.close())
    await asyncio.sleep(0)  # nothing to drain: it now waits for the reader thread
    closing.cancel()
    with pytest.raises(asyncio.CancelledError):
        await closing
    assert not link.port.is_open, "the port is still open"
    await asyncio.wait_for(rov.close(), CONDITION_TIMEOUT_S)


async def test_a_second_close_returns_once_the_port_is_released(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]]
) -> None:
    fake, sock = pair
    client = await _client(sock, timeout_s=NO_REPLY_TIMEOUT_S, retries=0)
    fake.then("drop")
    waiting = asyncio.ensure_future(client.depth_cm())
    await _arrived(fake, lambda f: f.query_count == 1)
    first = asyncio.ensure_future(client.close())
    await asyncio.sleep(0)
    await asyncio.wait_for(client.close(), CONDITION_TIMEOUT_S)
    assert sock.fileno() == -1, "the second close() returned while the first was draining"
    await first
    with pytest.raises((QueryTimeoutError, ConnectionLostError)):
        await waiting


async def test_leaving_async_with_while_queries_are_in_flight(
    pair: tuple[FakeController, socket.socket], loop_errors: list[dict[str, Any]]
) -> None:
    """The queries on the wire are answered before the port closes; a cancelled block sends
    ``#stop!`` first."""
    fake, sock = pair
    fake.late_delay_s = 0.1
    client = await _client(sock, max_in_flight=8)
    fake.then("late")
    queries: list[asyncio.Future[int]] = []

    async def program() -> None:
        async with client:
            await client.move(90, 30)
            queries.extend(asyncio.ensure_future(client.depth_cm()) for _ in range(5))
            await asyncio.sleep(0)
            await asyncio.sleep(CONDITION_TIMEOUT_S)  # cancelled here

    task = asyncio.ensure_future(program())
    await _arrived(fake, lambda f: f.query_count == 5)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    assert sorted(await asyncio.gather(*queries)) == [1, 2, 3, 4, 5]
    await _arrived(fake, lambda f: "#stop!" in f.frames())
    assert client.closed
    assert sock.fileno() == -1


# -- event hooks ------------------------------------------------------------------------------


async def test_event_hooks_that_raise_or_use_the_client(
    pair: tuple[FakeController, socket.socket],
    loop_errors: list[dict[str, Any]],
    caplog: pytest.LogCaptureFixture,
) -> None:
    fake, sock = pair
    spawned: list[asyncio.Future[int]] = []
    seen: list[ClientEvent] = []
    client: AsyncClient | None = None

    def raising(event: ClientEvent) -> None:
        raise RuntimeError("a bug in the hook")

    def reentrant(event: ClientEvent) -> None:
        assert client is not None
        seen.append(event)
        assert client.counters.frames_sent >= 1
        if isinstance(event, BytesSent) and event.command is not None:
            client.frame_for(event.command)
        if isinstance(event, ReplyReceived) and len(spawned) < 3:
            spawned.append(asyncio.ensure_future(client.heading_deg()))

    client = await _client(sock, on_event=raising)
    client.subscribe(reentrant)
    client.subscribe(raising)
    fake.then("corrupt")
    assert await client.depth_cm() == 3  # the corrupt reply (1) is retried after a fence (2)
    assert await wait_until_async(lambda: len(spawned) == 3 and all(f.done() for f in spawned))
    assert [future.result() for future in spawned] == [275, 275, 275]
    assert any("on_event callback failed" in record.getMessage() for record in caplog.records)
    await _assert_usable(fake, client, 8)
    await client.close()
    assert any(isinstance(event, ReplyReceived) for event in seen)


async def test_leaving_by_an_error_delivers_the_stop_behind_a_full_send_buffer() -> None:
    # A controller slow to read (a busy serial-to-network bridge): the client's writes pile
    # up in its buffer, and the #stop! sent on leaving by an error is the last of them. Closing
    # dropped the buffer, #stop! with it.
    host_end, controller_end = socket.socketpair()
    host_end.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
    controller_end.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    rov = await AsyncClient(SocketLink(host_end, "slow reader"), client_options()).open()
    received = bytearray()

    def read_once_closing() -> None:  # the controller catches up only as the client closes
        wait_until(lambda: rov.closed)
        with controller_end:
            while chunk := controller_end.recv(65536):
                received.extend(chunk)

    reader = threading.Thread(target=read_once_closing)
    reader.start()

    async def stream_set_points_then_fail() -> None:
        async with rov:
            await rov.start()
            for index in range(1000):
                await rov.move(index % 360, 40)
            assert rov._transport._buffer  # type: ignore[attr-defined]  # (really behind)
            raise RuntimeError("the program fails")

    with pytest.raises(RuntimeError, match="the program fails"):
        await stream_set_points_then_fail()
    await asyncio.to_thread(reader.join, CONDITION_TIMEOUT_S)
    assert received.endswith(b"#stop!")
    assert received.count(b"#th.") == 1000


async def test_a_close_cancelled_as_its_send_buffer_drains_is_cancelled() -> None:
    """On Python 3.10, ``asyncio.wait_for`` returns the result of what it waits for if that is
    done when the cancellation comes (bpo-37658): a close() cancelled by its caller's deadline
    just as the port took the last of its buffer returned as if not cancelled, and the caller
    ran on past its own deadline (a TaskGroup's sibling, a shutdown that must end)."""
    host_end, controller_end = socket.socketpair()
    host_end.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
    controller_end.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    rov = await AsyncClient(SocketLink(host_end, "slow reader"), client_options()).open()
    for index in range(1000):
        await rov.move(index % 360, 40)
    transport = rov._transport
    assert transport._buffer  # type: ignore[attr-defined]  # (really behind)
    closing = asyncio.ensure_future(rov.close())
    assert await wait_until_async(lambda: transport._drained is not None)  # type: ignore[attr-defined]
    # The deadline comes as the buffer drains: in the same turn of the loop.
    transport._drained.add_done_callback(lambda _: closing.cancel())  # type: ignore[attr-defined]
    with controller_end:
        reader = threading.Thread(target=lambda: _read_to_the_end(controller_end))
        reader.start()
        with pytest.raises(asyncio.CancelledError):
            await asyncio.wait_for(asyncio.shield(closing), CONDITION_TIMEOUT_S)
        await asyncio.to_thread(reader.join, CONDITION_TIMEOUT_S)
    assert rov.closed
    with pytest.raises(ConnectionLostError, match="closed"):
        await rov.stop()  # the port was released all the same


def _read_to_the_end(sock: socket.socket) -> None:
    while sock.recv(65536):
        pass


async def test_a_cancelled_connect_leaves_no_port_open(monkeypatch: pytest.MonkeyPatch) -> None:
    def simulators() -> int:
        return sum(thread.name.startswith("rovlink-sim") for thread in threading.enumerate())

    opened, cancelled = threading.Event(), threading.Event()
    real_open_link = rovlink.aio.client.open_link  # type: ignore[attr-defined]

    def open_link_slowly(endpoint: Endpoint) -> Link:  # cancelled while the port opens
        link = real_open_link(endpoint)
        opened.set()
        cancelled.wait(CONDITION_TIMEOUT_S)
        return link

    monkeypatch.setattr(rovlink.aio.client, "open_link", open_link_slowly)
    before = simulators()
    connecting = asyncio.ensure_future(rovlink.aio.connect("sim://"))
    assert await asyncio.to_thread(opened.wait, CONDITION_TIMEOUT_S)
    connecting.cancel()
    cancelled.set()
    with pytest.raises(asyncio.CancelledError):
        await connecting
    assert await wait_until_async(lambda: simulators() == before)
