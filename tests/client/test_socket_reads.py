"""A caller waiting for its own reply on TCP sleeps in ``poll`` (``SocketLink.read_available``):
it gets the reply, gives up at its deadline, and is woken by the other end or by ``close``."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from rovlink.client import ConnectionLostError
from rovlink.client.links import SocketLink
from tests.client.conftest import CONDITION_TIMEOUT_S, wait_until

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
    assert link.read_available(CONDITION_TIMEOUT_S) == b"$qd.5!"


def test_silence_ends_the_read_at_its_deadline(pair: tuple[SocketLink, socket.socket]) -> None:
    link, _ = pair
    started = time.monotonic()
    assert link.read_available(0.05) == b""
    assert time.monotonic() - started >= 0.045  # (poll rounds up, never down)


def test_the_other_end_closing_is_a_lost_connection(
    pair: tuple[SocketLink, socket.socket],
) -> None:
    link, controller = pair
    controller.close()
    with pytest.raises(ConnectionLostError, match="closed by the other end"):
        link.read_available(CONDITION_TIMEOUT_S)


def test_close_wakes_a_read_asleep_in_another_thread(
    pair: tuple[SocketLink, socket.socket],
) -> None:
    link, _ = pair
    outcome: list[BaseException | bytes] = []

    def read() -> None:
        try:
            outcome.append(link.read_available(30.0))
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


def test_no_call_blocks(
    pair: tuple[SocketLink, socket.socket],
) -> None:
    link, _ = pair
    assert link.recv_some() == b""  # nothing waiting: at once
    sent = 0
    while (written := link.send_some(b"x" * 65536)) > 0:  # until the buffers are full
        sent += written
    assert sent > 0
    assert link.read_available(0.01) == b""
