"""P21: a controller that boots slowly after its port opens, or resets during a session."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import pytest

from rovlink.aio import AsyncClient
from rovlink.client import Client, ClientOptions
from rovlink.client.errors import ConnectError, ConnectionLostError
from rovlink.client.events import ClientEvent, ModeChanged, ResetSuspected
from rovlink.client.links import SocketLink
from tests.client.fake_controller import FakeController

BOOT_S = 1.0  # the fake ignores its input this long after it starts, as a booting board does


@pytest.fixture
def booting() -> Iterator[tuple[FakeController, socket.socket]]:
    fake, sock = FakeController.on_socketpair(boot_s=BOOT_S)
    yield fake, sock
    fake.close()


def _options(**overrides: object) -> ClientOptions:
    settings: dict[str, object] = {"timeout_s": 0.25, "keepalive_s": None, "motion_timeout_s": None}
    settings.update(overrides)
    return ClientOptions(**settings)  # type: ignore[arg-type]


def test_the_blocking_client_waits_for_a_booting_controller(
    booting: tuple[FakeController, socket.socket],
) -> None:
    fake, sock = booting
    started = time.monotonic()
    with Client(SocketLink(sock, "booting"), _options(checksum=True)) as rov:
        assert time.monotonic() - started >= BOOT_S * 0.9
        assert fake.ignored.startswith(b"#crcoff!#qd!")  # probes lost while it booted
        assert rov.depth_cm() == 123  # in checksum mode: the mode frame was not lost
        assert fake.decoder.checksum_enabled


async def test_the_asyncio_client_waits_for_a_booting_controller(
    booting: tuple[FakeController, socket.socket],
) -> None:
    fake, sock = booting
    rov = await AsyncClient(SocketLink(sock, "booting"), _options(checksum=True)).open()
    try:
        assert fake.ignored.startswith(b"#crcoff!#qd!")
        assert await rov.depth_cm() == 123
        assert fake.decoder.checksum_enabled
    finally:
        await rov.close()


def test_a_controller_that_never_answers_is_a_connect_error(
    booting: tuple[FakeController, socket.socket],
) -> None:
    _, sock = booting
    with pytest.raises(ConnectError, match=r"did not answer within 0\.3 s") as raised:
        Client(SocketLink(sock, "silent"), _options(boot_timeout_s=0.3))
    assert "is this its address?" in str(raised.value)  # (no baud rate on a socket)
    assert "said" not in str(raised.value)


def _saying(text: bytes, *, then_close: bool) -> tuple[socket.socket, socket.socket]:
    """A controller end that sends ``text`` and answers nothing (then closes, if asked)."""
    ours, theirs = socket.socketpair()
    theirs.sendall(text)
    if then_close:
        theirs.shutdown(socket.SHUT_WR)
    return ours, theirs


@pytest.mark.parametrize("then_close", [False, True])
def test_what_a_controller_said_instead_of_answering_is_in_the_error(then_close: bool) -> None:
    ours, theirs = _saying(
        b"busy: the controller already has a client\x07\r\n", then_close=then_close
    )
    # A failure to connect either way, as the docs promise, closed or not (it was a
    # ConnectionLostError when closed: a program catching ConnectError around connect missed it).
    with theirs, pytest.raises(ConnectError) as raised:
        Client(SocketLink(ours, "refusing"), _options(boot_timeout_s=0.5))
    assert str(raised.value).endswith('; it said: "busy: the controller already has a client\\x07"')


@pytest.mark.parametrize("then_close", [False, True])
async def test_the_asyncio_client_says_what_the_controller_said_too(then_close: bool) -> None:
    ours, theirs = _saying(b"boot: no sensors\r\n", then_close=then_close)
    with theirs, pytest.raises(ConnectError, match=r'; it said: "boot: no sensors"$'):
        await AsyncClient(SocketLink(ours, "refusing"), _options(boot_timeout_s=0.5)).open()


def test_a_reset_mid_session_is_noticed_and_the_checksum_mode_restored(
    fake_pair: tuple[FakeController, socket.socket],
) -> None:
    fake, sock = fake_pair
    events: list[ClientEvent] = []
    with Client(
        SocketLink(sock, "pair"), _options(checksum=True, retries=3, on_event=events.append)
    ) as rov:
        assert rov.depth_cm() == 123
        fake.reset()  # back with checksum mode off: every checksummed frame is now dropped
        assert rov.heading_deg() == 275  # retried until the mode is re-asserted
        assert fake.decoder.checksum_enabled
        assert rov.counters.resets_suspected >= 1
    suspected = [event for event in events if isinstance(event, ResetSuspected)]
    assert len(suspected) >= 1
    assert suspected[0].consecutive_timeouts >= 2
    assert any(isinstance(event, ModeChanged) for event in events)


async def test_the_asyncio_client_notices_a_reset_too(
    fake_pair: tuple[FakeController, socket.socket],
) -> None:
    fake, sock = fake_pair
    events: list[ClientEvent] = []
    rov = await AsyncClient(
        SocketLink(sock, "pair"),
        _options(checksum=True, retries=3, boot_timeout_s=None, on_event=events.append),
    ).open()
    try:
        assert await rov.depth_cm() == 123
        fake.reset()
        assert await rov.heading_deg() == 275
        assert fake.decoder.checksum_enabled
        assert rov.counters.resets_suspected >= 1
        assert any(isinstance(event, ResetSuspected) for event in events)
    finally:
        await rov.close()


def test_a_last_line_without_its_line_end_is_said_too() -> None:
    ours, theirs = _saying(b"busy", then_close=True)
    with theirs, pytest.raises(ConnectError, match=r'; it said: "busy"$'):
        Client(SocketLink(ours, "refusing"), _options(boot_timeout_s=0.5))


def test_a_link_closed_before_the_controller_answered_is_a_failure_to_connect() -> None:
    ours, theirs = _saying(b"", then_close=True)
    with theirs, pytest.raises(ConnectError, match=r"closed by the other end$") as raised:
        Client(SocketLink(ours, "refusing"), _options(boot_timeout_s=0.5))
    assert isinstance(raised.value.__cause__, ConnectionLostError)


async def test_the_asyncio_client_fails_to_connect_on_a_closed_link_too() -> None:
    ours, theirs = _saying(b"", then_close=True)
    with theirs, pytest.raises(ConnectError, match=r"closed by the other end$"):
        await AsyncClient(SocketLink(ours, "refusing"), _options(boot_timeout_s=0.5)).open()


#: A line slower than the probe's interval (0.25 s): each probe's reply comes after the next
#: probe went out, and the replies come that far apart. (Not 0.3 s: the second probe then went
#: out only if the client's thread was not 50 ms late for it, on a loaded machine too.)
SLOW_LINE_S = 0.45


@pytest.mark.parametrize("client", ["blocking", "asyncio"])
async def test_a_probes_reply_on_a_slow_line_answers_no_query_of_the_program(client: str) -> None:
    # Before, the client took the line for quiet 0.1 s after the first probe's reply, and the
    # second probe's reply, 0.25 s later, answered the program's first #qd!: a value from before
    # it was asked (P20).
    fake, sock = FakeController.on_socketpair(latency_s=SLOW_LINE_S)
    fake.qd_counts_queries = True  # each $qd carries the number of its #qd! on the line
    options = _options(timeout_s=2.0, boot_timeout_s=3.0)
    try:
        if client == "blocking":
            with Client(SocketLink(sock, "slow socket pair"), options) as rov:
                probes = fake.query_count
                assert probes >= 2  # (else the line was not slow enough to show anything)
                assert rov.depth_cm() == probes + 1  # its own reply
        else:
            arov = await AsyncClient(SocketLink(sock, "slow socket pair"), options).open()
            try:
                probes = fake.query_count
                assert probes >= 2
                assert await arov.depth_cm() == probes + 1
            finally:
                await arov.close()
    finally:
        fake.close()


@pytest.mark.parametrize("client", ["blocking", "asyncio"])
async def test_a_probes_reply_on_a_line_whose_delay_varies_answers_no_query_of_the_program(
    client: str,
) -> None:
    # The first probe's reply takes 0.45 s, every later one 0.7 s: the second probe (sent
    # 0.25 s after the first) gets its reply 0.5 s after the first's, later than any quiet the
    # client waited for before (0.35 s), and it answered the program's first #qd! with a value
    # from before it was asked (P20). The fence (#qr!) after the probes ends the wait behind
    # every probe's reply, whatever the delays. (With 0.3 s for the first reply, a thread held
    # up for 50 ms on a loaded machine sent the second probe after it: nothing to show.)
    fake, sock = FakeController.on_socketpair(latency_s=0.7)
    fake.latencies_s.append(0.45)
    fake.qd_counts_queries = True  # each $qd carries the number of its #qd! on the line
    options = _options(timeout_s=2.0, boot_timeout_s=3.0)
    try:
        if client == "blocking":
            with Client(SocketLink(sock, "varying socket pair"), options) as rov:
                depth_cm = rov.depth_cm()
        else:
            arov = await AsyncClient(SocketLink(sock, "varying socket pair"), options).open()
            try:
                depth_cm = await arov.depth_cm()
            finally:
                await arov.close()
        assert depth_cm == fake.query_count  # its own reply: its #qd! is the last query
        assert fake.frames().count("#qd!") >= 3  # two probes at least (else nothing to show)
        assert "#qr!" in fake.frames()
    finally:
        fake.close()
