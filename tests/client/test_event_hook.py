"""The one hook: every byte both ways and every decision of the session, in order."""

from __future__ import annotations

import asyncio
import logging
import socket
import subprocess
import sys
from collections.abc import Awaitable, Callable

import pytest

from rovlink.aio import AsyncClient
from rovlink.client import Client, ClientOptions, ConnectionLostError
from rovlink.client.events import (
    BytesReceived,
    BytesSent,
    ClientEvent,
    LinkState,
    QueryFailed,
    ReplyReceived,
    Unsolicited,
)
from rovlink.client.links import SocketLink
from rovlink.protocol import BadFrame, Reason
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    NO_REPLY_TIMEOUT_S,
    ThreadCall,
    wait_until,
    wait_until_async,
)
from tests.client.fake_controller import FakeController


def test_a_subscriber_sees_the_wire_and_the_decisions_in_order(
    fake_pair: tuple[FakeController, socket.socket],
) -> None:
    fake, sock = fake_pair
    events: list[ClientEvent] = []
    options = ClientOptions(
        timeout_s=2.0,
        keepalive_s=None,
        boot_timeout_s=None,
        motion_timeout_s=None,
        checksum=True,
        on_event=events.append,
    )
    with Client(SocketLink(sock, "pair"), options) as rov:
        fake.then("corrupt")
        assert rov.depth_cm() == 123  # the corrupt reply is retried
        rov.move(90, 10)
    sent = b"".join(event.data for event in events if isinstance(event, BytesSent))
    # Every byte written, exactly as the controller received it (once its thread has read all).
    assert fake.wait_for(lambda controller: bytes(controller.raw) == sent)
    received = [event for event in events if isinstance(event, BytesReceived)]
    assert b"".join(event.data for event in received).count(b"$qd.") == 2
    kinds = [type(event).__name__ for event in events]
    assert kinds.index("QueryFailed") < kinds.index("ReplyReceived")
    failed = next(event for event in events if isinstance(event, QueryFailed))
    assert failed.outcome == "corrupt"
    dropped = [event.event for event in events if isinstance(event, Unsolicited)]
    assert any(isinstance(event, BadFrame) and event.reason == "checksum" for event in dropped)
    replies = [event for event in events if isinstance(event, ReplyReceived)]
    assert [reply.query.name for reply in replies] == ["qhe", "qd"]  # the fence, the retry
    assert replies[1].responses[0].values == (123,)
    times = [event.at_s for event in events]
    assert times == sorted(times)
    assert {event.direction for event in events} == {"in", "out", "local"}


def test_dropped_frames_are_debug_lines_with_a_periodic_warning(
    fake: FakeController,
    caplog: pytest.LogCaptureFixture,
) -> None:
    from rovlink.client.unsolicited import DropLog

    caplog.set_level(logging.DEBUG, logger="rovlink")
    log = DropLog(period_s=10.0)
    bad = BadFrame(Reason.MALFORMED, b"$qd.1x!", "x")
    for second in range(30):
        log.report([bad] * 10, None, now=float(second))
    warnings = [record for record in caplog.records if record.levelno == logging.WARNING]
    debug = [record for record in caplog.records if record.levelno == logging.DEBUG]
    assert len(debug) == 300
    assert len(warnings) == 3  # at 0, 10 and 20 s, each with the count since the last
    assert "10 received frame(s)" in warnings[0].getMessage()
    assert "100 received frame(s)" in warnings[1].getMessage()


@pytest.mark.integration
def test_an_unconfigured_program_on_a_noisy_line_prints_nothing() -> None:
    code = (
        "import socket, threading, rovlink\n"
        "from rovlink.client import Client, ClientOptions\n"
        "from rovlink.client.links import SocketLink\n"
        "ours, theirs = socket.socketpair()\n"
        "def controller():\n"
        "    data = b''\n"
        "    while b'#qd!' not in data:\n"
        "        data += ours.recv(100)\n"
        "    ours.sendall(b'#bogus!' * 50 + b'\\xff\\x00 noise\\r\\n' + b'$qd.5!')\n"
        "threading.Thread(target=controller, daemon=True).start()\n"
        "rov = Client(SocketLink(theirs, 'pair'), ClientOptions(boot_timeout_s=None,"
        " keepalive_s=None))\n"
        "print(rov.depth_cm())\n"
        "rov.close()\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    assert result.stdout.strip() == "5"
    assert result.stderr == ""


def test_a_subscriber_that_comes_later_sees_the_events_from_then_on(
    fake_pair: tuple[FakeController, socket.socket],
) -> None:
    _, sock = fake_pair
    options = ClientOptions(
        timeout_s=2.0, keepalive_s=None, boot_timeout_s=None, motion_timeout_s=None
    )
    with Client(SocketLink(sock, "pair"), options) as rov:
        assert rov.depth_cm() == 123
        events: list[ClientEvent] = []
        rov.subscribe(events.append)
        rov.move(0, 20)
        sent = [event for event in events if isinstance(event, BytesSent)]
        assert [event.data for event in sent] == [b"#th.0.20!"]
        assert sent[0].by_session is False


def test_a_hook_failing_on_every_event_is_logged_once_then_counted(
    caplog: pytest.LogCaptureFixture,
) -> None:
    from rovlink.client.unsolicited import HOOK_FAILURE_WARNING_PERIOD_S, HookFailureLog, deliver

    caplog.set_level(logging.DEBUG, logger="rovlink")
    now = [0.0]
    failures = HookFailureLog(clock=lambda: now[0])

    def broken_pipe(event: object) -> None:
        raise BrokenPipeError(32, "Broken pipe")

    events = [LinkState(0.0, "lost", "unplugged")]
    for step in range(100):  # 100 events over 25 s
        now[0] = step * 0.25
        deliver(events, (), broken_pipe, failures)
    tracebacks = [record for record in caplog.records if record.exc_info]
    warnings = [record for record in caplog.records if record.levelno == logging.WARNING]
    assert len(tracebacks) == 1
    assert "on_event callback failed" in tracebacks[0].getMessage()
    # Then at most one warning a period, each with the count since the last said.
    assert len(warnings) == int(24.75 // HOOK_FAILURE_WARNING_PERIOD_S)
    assert "failed 40 more times" in warnings[0].getMessage()
    assert "BrokenPipeError" in warnings[0].getMessage()
    assert failures.unsaid(broken_pipe) == 99 - 80


def test_a_client_whose_hook_fails_on_every_event_logs_one_traceback(
    caplog: pytest.LogCaptureFixture,
) -> None:
    import rovlink

    caplog.set_level(logging.DEBUG, logger="rovlink")

    def broken_pipe(event: object) -> None:
        raise BrokenPipeError(32, "Broken pipe")

    with rovlink.connect("sim://", keepalive=None, on_event=broken_pipe) as rov:
        for _ in range(20):
            rov.depth_cm()
        rov.subscribe(broken_pipe)  # a second registration of it: counted with the first
        rov.depth_cm()
    tracebacks = [record for record in caplog.records if record.exc_info]
    assert len(tracebacks) == 1


def _retry_marks(events: list[ClientEvent], name: str) -> list[bool]:
    return [
        event.retry
        for event in events
        if isinstance(event, BytesSent) and event.command is not None and event.command.name == name
    ]


def test_a_retry_is_marked_as_the_drivers_not_the_programs(
    make_client: Callable[..., Client], fake: FakeController
) -> None:
    # Before, a retry was a BytesSent like the program's query: a recording replayed it twice.
    events: list[ClientEvent] = []
    rov = make_client(drops_time_out_at_once=True, on_event=events.append)
    fake.then("drop")
    assert rov.depth_cm() == 123
    assert _retry_marks(events, "qd") == [False, True]
    assert _retry_marks(events, "qhe") == [False]  # the fence: by the session, no retry
    fence = next(e for e in events if isinstance(e, BytesSent) and e.data == b"#qhe!")
    assert fence.by_session


async def test_the_asyncio_clients_retries_are_marked_too(
    make_async_client: Callable[..., Awaitable[AsyncClient]], fake: FakeController
) -> None:
    events: list[ClientEvent] = []
    rov = await make_async_client(
        max_in_flight=2, timeout_s=NO_REPLY_TIMEOUT_S, on_event=events.append
    )
    fake.then("drop", "drop")
    assert list(await asyncio.gather(rov.depth_cm(), rov.depth_cm())) == [123, 123]
    assert _retry_marks(events, "qd") == [False, False, True, True]


def test_a_retry_held_back_and_never_sent_is_not_counted(
    make_client: Callable[..., Client], fake: FakeController
) -> None:
    """``retries`` counts the attempts sent again, as the events marked ``retry`` do. A ``qsa``
    that timed out makes every name late, so its retry waits for a quiet line (P20); a close
    meanwhile ends it unsent. Before, the client counted it as it asked for it: the counter
    said one more retry than went out (a few a run under stress)."""
    events: list[ClientEvent] = []
    rov = make_client(timeout_s=0.5, retries=1, on_event=events.append)
    fake.then("drop")
    asking = ThreadCall(rov.sensors)
    assert wait_until(lambda: bool(rov._session._held))  # the retry, held back
    rov.close()
    assert asking.done.wait(CONDITION_TIMEOUT_S)
    assert isinstance(asking.error, ConnectionLostError)
    assert _retry_marks(events, "qsa") == [False]
    assert rov.counters.retries == 0


async def test_the_asyncio_client_counts_a_retry_held_back_and_never_sent_neither(
    make_async_client: Callable[..., Awaitable[AsyncClient]], fake: FakeController
) -> None:
    events: list[ClientEvent] = []
    rov = await make_async_client(timeout_s=0.5, retries=1, on_event=events.append)
    fake.then("drop")
    asking = asyncio.ensure_future(rov.sensors())
    assert await wait_until_async(lambda: bool(rov._session._held))
    await rov.close()
    with pytest.raises(ConnectionLostError):
        await asking
    assert _retry_marks(events, "qsa") == [False]
    assert rov.counters.retries == 0


def test_an_on_stray_callback_failing_on_every_line_is_logged_once_then_counted(
    caplog: pytest.LogCaptureFixture,
) -> None:
    from rovlink.client.unsolicited import DropLog
    from rovlink.protocol import Text

    caplog.set_level(logging.DEBUG, logger="rovlink")
    log = DropLog()

    def broken_pipe(event: object) -> None:
        raise BrokenPipeError(32, "Broken pipe")

    for second in range(5):
        log.report([Text("depth pid 1\r\n")] * 10, broken_pipe, now=float(second))
    tracebacks = [record for record in caplog.records if record.exc_info]
    assert len(tracebacks) == 1
    assert "on_stray callback failed" in tracebacks[0].getMessage()


@pytest.mark.parametrize("callback", [None, 42, "print"])
def test_subscribing_what_cannot_be_called_is_refused_at_once(
    make_client: Callable[..., Client], callback: object
) -> None:
    # (Before, it was taken, and every event then failed in it, logged, the program hearing
    # nothing.)
    rov = make_client()
    with pytest.raises(TypeError, match=r"subscribe: callback must be callable .*, got "):
        rov.subscribe(callback)  # type: ignore[arg-type]
    assert rov.depth_cm() == 123


async def test_the_asyncio_client_refuses_it_too(
    make_async_client: Callable[..., Awaitable[AsyncClient]],
) -> None:
    rov = await make_async_client()
    with pytest.raises(TypeError, match=r"subscribe: callback must be callable .*, got None"):
        rov.subscribe(None)  # type: ignore[arg-type]
    assert await rov.depth_cm() == 123


async def _an_async_callback(event: ClientEvent) -> None:
    """A subscriber that would never run: its coroutine is awaited by nobody."""


def test_subscribing_an_async_def_is_refused_at_once(make_client: Callable[..., Client]) -> None:
    rov = make_client()
    with pytest.raises(TypeError, match=r"subscribe: callback must be a plain function, not an"):
        rov.subscribe(_an_async_callback)  # type: ignore[arg-type]
    assert rov.depth_cm() == 123


async def test_the_asyncio_client_refuses_an_async_def_subscriber_too(
    make_async_client: Callable[..., Awaitable[AsyncClient]],
) -> None:
    rov = await make_async_client()
    with pytest.raises(TypeError, match=r"subscribe: callback must be a plain function, not an"):
        rov.subscribe(_an_async_callback)  # type: ignore[arg-type]
    assert await rov.depth_cm() == 123
