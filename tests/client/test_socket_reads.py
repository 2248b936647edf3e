"""A caller waiting for its own reply on TCP sleeps in ``recv`` (``SocketLink.read_reply``):
it gets the reply, gives up at its deadline, and is woken by the other end or by ``close``."""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from rovlink.client import ConnectionLostError, QueryTimeoutError
from rovlink.client.blocking import Client
from rovlink.client.links import SocketLink
from rovlink.client.options import ClientOptions
from rovlink.client.session import PendingQuery, Received
from tests.client.conftest import CONDITION_TIMEOUT_S, wait_until
from tests.client.fake_controller import FakeController

pytestmark = pytest.mark.integration


@pytest.fixture
def pair() -> Iterator[tuple[SocketLink, socket.socket]]:
    ours, theirs = socket.socketpair()
    link = SocketLink(ours, "socket pair")
    yield link, theirs
    link.close()
    theirs.close()


def test_the_reply_is_read_as_it_arrives(pair: tuple[SocketLink, socket.socket]) -> None:
    link, controller = pair
    link.send_some(b"#qd!")
    assert controller.recv(64) == b"#qd!"
    controller.sendall(b"$qd.5!")
    assert link.read_reply(CONDITION_TIMEOUT_S) == b"$qd.5!"


def test_silence_ends_the_read_at_its_deadline(pair: tuple[SocketLink, socket.socket]) -> None:
    link, _ = pair
    started = time.monotonic()
    assert link.read_reply(0.05) == b""
    assert time.monotonic() - started >= 0.045  # (the receive timeout rounds up, never down)
    assert link.read_reply(0.0005) == b""  # shorter than the kernel's timer: polled instead


def test_the_other_end_closing_is_a_lost_connection(
    pair: tuple[SocketLink, socket.socket],
) -> None:
    link, controller = pair
    controller.close()
    with pytest.raises(ConnectionLostError, match="closed by the other end"):
        link.read_reply(CONDITION_TIMEOUT_S)


def test_close_wakes_a_read_asleep_in_another_thread(
    pair: tuple[SocketLink, socket.socket],
) -> None:
    link, _ = pair
    outcome: list[BaseException | bytes] = []

    def read() -> None:
        try:
            outcome.append(link.read_reply(30.0))
        except ConnectionLostError as error:
            outcome.append(error)

    reader = threading.Thread(target=read)
    reader.start()
    assert wait_until(lambda: _asleep(reader))
    link.close()
    reader.join(CONDITION_TIMEOUT_S)
    assert not reader.is_alive()
    assert len(outcome) == 1
    assert isinstance(outcome[0], ConnectionLostError)


def _asleep(thread: threading.Thread) -> bool:
    """Whether ``thread`` is asleep in the kernel (Linux: its state in /proc)."""
    stat = Path(f"/proc/self/task/{thread.native_id}/stat").read_text()
    return stat[stat.rindex(")") + 2] == "S"


def test_the_descriptor_blocks_but_no_other_call_does(
    pair: tuple[SocketLink, socket.socket],
) -> None:
    link, _ = pair
    assert link.recv_some() == b""  # nothing waiting: at once
    sent = 0
    while (written := link.send_some(b"x" * 65536)) > 0:  # until the buffers are full
        sent += written
    assert sent > 0
    assert link.read_available(0.01) == b""


def test_ctrl_c_in_a_callers_read_leaves_the_client_usable() -> None:
    fake, sock = FakeController.on_socketpair()
    link = SocketLink(sock, "socket pair")
    with Client(link, ClientOptions(keepalive_s=None, timeout_s=0.3, retries=0)) as client:
        assert client.depth_cm() == 123
        real_read = link.read_reply
        interrupted = threading.Event()

        def read_then_interrupt(timeout_s: float) -> bytes:
            if not interrupted.is_set():
                interrupted.set()
                raise KeyboardInterrupt
            return real_read(timeout_s)

        link.read_reply = read_then_interrupt  # type: ignore[method-assign]
        client._read_reply = read_then_interrupt
        with pytest.raises(KeyboardInterrupt):
            client.depth_cm()
        assert client._reader_ident is None
        assert client._active_callers == 0
        # The interrupted query's reply is late now; the next query gets its own.
        assert wait_until(lambda: not client._session.pending)
        assert client.depth_cm() == 123
    fake.close()


def test_ctrl_c_while_the_reply_is_settled_inline_releases_the_state_lock() -> None:
    """Ctrl-C while the first attempt settles its reply (a signal handler can run there as
    anywhere in the main thread) releases the state lock and stops counting the caller as
    active: later calls, the background reader and close() go on."""
    fake, sock = FakeController.on_socketpair()
    link = SocketLink(sock, "socket pair")
    client = Client(
        link, ClientOptions(keepalive_s=None, timeout_s=0.5, retries=0, boot_timeout_s=None)
    )
    lock = client._state_lock
    try:
        assert client.depth_cm() == 123
        session = client._session
        real_receive_reply = session.receive_reply
        interrupted = threading.Event()

        def interrupt_once(data: bytes, now: float) -> PendingQuery | Received:
            if not interrupted.is_set():
                interrupted.set()
                raise KeyboardInterrupt  # as if Ctrl-C landed while the reply is decoded
            return real_receive_reply(data, now)

        session.receive_reply = interrupt_once  # type: ignore[method-assign]
        with pytest.raises(KeyboardInterrupt):
            client.depth_cm()
        acquired = lock.acquire(timeout=CONDITION_TIMEOUT_S)
        if acquired:
            stuck_reader = client._reader_ident not in (None, client._background_ident)
            lock.release()
        else:
            lock.release()  # (held by nobody alive: let the client close)
            client._reader_ident = None
        assert acquired, "the state lock stayed held after Ctrl-C: the client is deadlocked"
        assert not stuck_reader
        assert wait_until(lambda: client._active_callers == 0)
        # The bytes the interrupted caller had read went with it, so the next reply answers
        # the interrupted query (the oldest, P20) and the query after it may time out; then the
        # client goes on as before.
        with contextlib.suppress(QueryTimeoutError):
            client.depth_cm()
        assert client.depth_cm() == 123
    finally:
        client.close()
        fake.close()
