"""Ctrl-C (or any exception) in the middle of a blocking query: wherever it lands, the client
stays usable and no later query gets a reply meant for the interrupted one (P20).

A signal handler runs between any two bytecodes of the main thread, so these tests raise
``KeyboardInterrupt`` from each step of a query in turn: before its frame is written, while its
reply is awaited, and after its reply was read but before it was settled (those bytes are then
gone with the caller).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from typing import TypeVar

import pytest

from rovlink.client.blocking import Client
from rovlink.client.links import SocketLink
from rovlink.client.session import Outcome, PendingQuery, Session
from rovlink.protocol import Command
from tests.client.conftest import CONDITION_TIMEOUT_S, client_options, wait_until
from tests.client.fake_controller import FakeController

pytestmark = pytest.mark.integration

Result = TypeVar("Result")


@pytest.fixture
def counting() -> Iterator[tuple[FakeController, Client]]:
    """A client of a fake controller whose ``$qd.N!`` numbers the queries it received, with
    the background reader kept from reading (see :func:`_keep_the_background_reader_out`)."""
    fake, sock = FakeController.on_socketpair()
    fake.qd_counts_queries = True
    client = Client(SocketLink(sock, "socket pair"), client_options(retries=0))
    try:
        _keep_the_background_reader_out(client)
        yield fake, client
    finally:
        with client._state_lock:
            del client._callers[_PHANTOM_CALLER]
        client.close()
        fake.close()


#: The caller that never leaves (see :func:`_keep_the_background_reader_out`): no thread's
#: identifier is negative.
_PHANTOM_CALLER = -1


def _keep_the_background_reader_out(client: Client) -> None:
    """Count a caller that never leaves, so that the background reader never takes the port:
    every step of a query then runs in the test's thread, where the interrupt is raised (a
    reply read by the background reader would settle the query before the step is reached)."""
    with client._state_lock:
        client._callers[_PHANTOM_CALLER] = None
    client._link.wake()  # (a read already under way ends now, and is not taken up again)
    assert wait_until(lambda: client._reader_ident is None)


def _interrupt_once(real: Callable[..., Result]) -> Callable[..., Result]:
    """``real``, except that its first call raises KeyboardInterrupt (before doing anything)."""
    interrupted = threading.Event()

    def call(*arguments: object) -> Result:
        if not interrupted.is_set():
            interrupted.set()
            raise KeyboardInterrupt
        return real(*arguments)

    return call


def _the_next_query_gets_its_own_reply(fake: FakeController, client: Client) -> None:
    """Without a timeout, and with the reply to the query it sent (not an earlier one)."""
    depth = client.depth_cm()
    assert depth == fake.query_count  # the last query the controller answered is this one
    assert client.counters.timeouts == 0
    assert client._reader_ident is None
    assert list(client._callers) == [_PHANTOM_CALLER]
    assert not client._state_lock._is_owned(), "the state lock stayed held after Ctrl-C"  # type: ignore[attr-defined]


def test_ctrl_c_before_the_frame_is_written(counting: tuple[FakeController, Client]) -> None:
    fake, client = counting
    assert client.depth_cm() == 1
    assert client._send_now is not None
    client._send_now = _interrupt_once(client._send_now)
    with pytest.raises(KeyboardInterrupt):
        client.depth_cm()
    # The query never reached the wire: before the fix it stayed first in the queue, took the
    # next query's reply, and the next query timed out.
    _the_next_query_gets_its_own_reply(fake, client)


def test_ctrl_c_while_the_reply_is_awaited(counting: tuple[FakeController, Client]) -> None:
    fake, client = counting
    assert client.depth_cm() == 1
    client._read_reply = _interrupt_once(client._read_reply)
    with pytest.raises(KeyboardInterrupt):
        client.depth_cm()
    # Its reply comes anyway, and is late: it goes to no later query.
    _the_next_query_gets_its_own_reply(fake, client)
    assert client.depth_cm() == fake.query_count


def test_ctrl_c_after_the_reply_was_read_before_it_was_settled(
    counting: tuple[FakeController, Client], monkeypatch: pytest.MonkeyPatch
) -> None:
    fake, client = counting
    assert client.depth_cm() == 1
    # (On the class: a Session has slots. The fake controller's own decoder is no Session.)
    monkeypatch.setattr(Session, "receive_reply", _interrupt_once(Session.receive_reply))
    with pytest.raises(KeyboardInterrupt):
        client.depth_cm()
    # The reply went with the interrupted caller: before the fix the next reply answered the
    # interrupted query (the oldest, P20) and the next query timed out.
    _the_next_query_gets_its_own_reply(fake, client)


def test_ctrl_c_in_the_general_path_after_the_reply_was_read(
    counting: tuple[FakeController, Client], monkeypatch: pytest.MonkeyPatch
) -> None:
    fake, client = counting
    assert client.depth_cm() == 1
    client._send_now = None  # (a link that may block on writing: every query waits in _wait)
    monkeypatch.setattr(Session, "receive", _interrupt_once(Session.receive))
    with pytest.raises(KeyboardInterrupt):
        client.depth_cm()
    _the_next_query_gets_its_own_reply(fake, client)


def test_the_interrupted_query_is_settled_as_abandoned(
    counting: tuple[FakeController, Client], monkeypatch: pytest.MonkeyPatch
) -> None:
    _, client = counting
    session = client._session
    queued: list[PendingQuery] = []
    real_fast_query = Session.fast_query

    def remember(self: Session, command: Command, now: float) -> tuple[bytes, PendingQuery] | None:
        ready = real_fast_query(self, command, now)
        if ready is not None:
            queued.append(ready[1])
        return ready

    monkeypatch.setattr(Session, "fast_query", remember)
    client._read_reply = _interrupt_once(client._read_reply)
    with pytest.raises(KeyboardInterrupt):
        client.depth_cm()
    assert [query.outcome for query in queued] == [Outcome.ABANDONED]
    assert session.resynchronising  # its reply, if it comes, is late


def test_ctrl_c_while_the_general_path_writes(counting: tuple[FakeController, Client]) -> None:
    fake, client = counting
    assert client.depth_cm() == 1
    client._send_now = None
    client._write = _interrupt_once(client._write)  # type: ignore[method-assign]
    with pytest.raises(KeyboardInterrupt):
        client.depth_cm()
    # Before the fix the caller still counted as active, so the background reader never read
    # again, and the query took the next query's reply.
    _the_next_query_gets_its_own_reply(fake, client)


def test_close_after_ctrl_c_does_not_wait_for_a_fence_it_never_wrote() -> None:
    """The fence for the interrupted query is due but unwritten when the program closes the
    client on its way out: close() waits only for queries on the wire (it used to wait out
    the fence's whole timeout, as if it had been sent)."""
    fake, sock = FakeController.on_socketpair()
    client = Client(SocketLink(sock, "socket pair"), client_options(retries=0, timeout_s=60.0))
    _keep_the_background_reader_out(client)  # (which would write the fence, given time)
    try:
        assert client._send_now is not None
        client._send_now = _interrupt_once(client._send_now)
        with pytest.raises(KeyboardInterrupt):
            client.depth_cm()
        closer = threading.Thread(target=client.close)
        closer.start()
        closer.join(CONDITION_TIMEOUT_S)
        assert not closer.is_alive(), "close() waits for a fence that was never written"
    finally:
        with client._state_lock:
            del client._callers[_PHANTOM_CALLER]
        client.close()
        fake.close()


def test_ctrl_c_while_the_rest_of_a_frame_waits_for_room(
    counting: tuple[FakeController, Client],
) -> None:
    fake, client = counting
    assert client.depth_cm() == 1
    send_now = client._send_now
    assert send_now is not None
    client._send_now = lambda data: send_now(data[:2])  # the kernel took only "#q"
    client._write = _interrupt_once(client._write)  # type: ignore[method-assign]
    with pytest.raises(KeyboardInterrupt):
        client.depth_cm()
    client._send_now = send_now
    # "#q" is on the wire: the next frame's "#" starts over at the controller (P1).
    _the_next_query_gets_its_own_reply(fake, client)


def test_a_checksum_switch_after_ctrl_c_writes_the_fence_in_the_old_mode_first(
    counting: tuple[FakeController, Client],
) -> None:
    fake, client = counting
    assert client._send_now is not None
    client._send_now = _interrupt_once(client._send_now)
    with pytest.raises(KeyboardInterrupt):
        client.depth_cm()
    client.set_checksum(True)
    _the_next_query_gets_its_own_reply(fake, client)
    assert client.counters.checksum_errors == 0
    assert [command.name for command in fake.commands][-3:] == ["qhe", "crcon", "qd"]
