"""The blocking client where a program's threads, signals and callbacks meet it at awkward
moments: a Ctrl-C in a write or in ``close()``, a command racing ``close()``, a callback that
calls ``sys.exit``, several threads whose events the hook must see in the order they happened.
"""

from __future__ import annotations

import contextlib
import re
import sys
import threading
import time
from collections.abc import Callable

import pytest

import rovlink
import rovlink.aio
from rovlink.client.blocking import Client
from rovlink.client.errors import ConnectionLostError
from rovlink.client.events import BytesReceived, BytesSent, ClientEvent, ReplyReceived
from rovlink.client.links import SocketLink
from tests.client.conftest import CONDITION_TIMEOUT_S, ThreadCall, client_options, wait_until
from tests.client.fake_controller import FakeController

pytestmark = pytest.mark.integration


def test_a_ctrl_c_in_the_write_of_zero_thrust_leaves_the_thrust_to_expire(
    make_client: Callable[..., Client], fake: FakeController
) -> None:
    rov = make_client(motion_timeout_s=0.3)
    rov.start()
    rov.move(90, 60)
    link = rov._link
    real_write = link.write

    def interrupted(data: bytes) -> None:  # a Ctrl-C while the write blocks: nothing went
        link.write = real_write  # type: ignore[method-assign]
        raise KeyboardInterrupt

    link.write = interrupted  # type: ignore[method-assign]
    with pytest.raises(KeyboardInterrupt):
        rov.move(90, 0)
    # The controller may still have 60 %: the client zeroes it when the motion expires (P23)
    # instead of believing it zero, while the keep-alive fed a robot that drove on.
    assert fake.wait_for(lambda f: "#th.90.0!" in f.frames())
    assert fake.frames().count("#th.90.60!") == 1
    assert rov.counters.motion_expiries == 1


def test_a_command_while_another_thread_closes_is_refused_but_a_stop_is_not(
    make_client: Callable[..., Client], fake: FakeController
) -> None:
    fake.late_delay_s = 0.5
    fake.then("late")  # the next reply comes 0.5 s late: close() waits for it
    rov = make_client(timeout_s=1.0)
    rov.start()
    querying = threading.Thread(target=rov.depth_cm)
    querying.start()
    assert fake.wait_for(lambda f: "#qd!" in f.frames())
    closing = threading.Thread(target=rov.close)
    closing.start()
    assert wait_until(lambda: rov.closed)
    with pytest.raises(ConnectionLostError, match="closed"):
        rov.move(0, 60)
    rov.stop()  # (a stop still goes while the port is open: it can only help)
    closing.join()
    querying.join()
    assert "#th.0.60!" not in fake.frames()
    assert fake.frames()[-1] == "#stop!"


def _query_until_closed(rov: Client) -> None:
    with contextlib.suppress(ConnectionLostError):
        rov.depth_cm()


def test_a_ctrl_c_while_close_waits_for_a_reply_still_releases_the_port(
    make_client: Callable[..., Client], fake: FakeController
) -> None:
    already_running = set(threading.enumerate())  # (another test's may still be ending)
    fake.late_delay_s = 0.5
    fake.then("late")
    rov = make_client(timeout_s=1.0)
    querying = threading.Thread(target=_query_until_closed, args=(rov,))
    querying.start()
    assert fake.wait_for(lambda f: "#qd!" in f.frames())
    real_wait = rov._wait

    def interrupted_wait(*args: object, **kwargs: bool) -> object:
        if kwargs.get("owned") is False:  # close()'s wait for the query on the wire
            raise KeyboardInterrupt
        return real_wait(*args, **kwargs)  # type: ignore[arg-type]

    rov._wait = interrupted_wait  # type: ignore[method-assign,assignment]
    with pytest.raises(KeyboardInterrupt):
        rov.close()
    querying.join()
    assert rov._link._closed  # type: ignore[attr-defined]  # (P22: the port can be opened again)
    rov.close()  # (returns: the port is released)
    assert not [
        thread
        for thread in set(threading.enumerate()) - already_running
        if thread.name.startswith("rovlink") and thread.is_alive()
    ]


def test_a_callback_calling_sys_exit_is_logged_and_the_client_goes_on(
    fake_pair: tuple[FakeController, object], caplog: pytest.LogCaptureFixture
) -> None:
    fake, sock = fake_pair

    def leave(event: ClientEvent) -> None:
        if isinstance(event, ReplyReceived):
            sys.exit("a hook that ends the program on a bad reading")

    rov = Client(
        SocketLink(sock, "pair"),  # type: ignore[arg-type]
        client_options(keepalive_s=0.05, motion_timeout_s=0.3, on_event=leave),
    )
    try:
        assert rov.depth_cm() == 123  # in the caller's thread: not raised out of the query
        rov.start()
        rov.move(0, 50)
        # In the background reader's thread it ended the thread: no keep-alive, no expiry.
        assert fake.wait_for(lambda f: "#th.0.0!" in f.frames())
        keepalives = rov.counters.keepalives
        assert wait_until(lambda: rov.counters.keepalives >= keepalives + 2)
        assert rov._background.is_alive()
    finally:
        rov.close()
    assert "on_event callback failed" in caplog.text


def test_threads_events_reach_the_hook_in_wire_order_one_at_a_time(
    make_client: Callable[..., Client], fake: FakeController
) -> None:
    events: list[ClientEvent] = []
    inside = threading.Lock()
    overlapping: list[ClientEvent] = []

    def hook(event: ClientEvent) -> None:
        if not inside.acquire(blocking=False):
            overlapping.append(event)
            return
        try:
            events.append(event)
            time.sleep(0)  # a hook doing a little work (a log line) lets other threads run
        finally:
            inside.release()

    fake.qd_counts_queries = True
    rov = make_client(on_event=hook)

    def poll() -> None:
        for _ in range(200):
            rov.depth_cm()

    threads = [threading.Thread(target=poll) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not overlapping
    times = [event.at_s for event in events]
    assert times == sorted(times)
    sent = b"".join(event.data for event in events if isinstance(event, BytesSent))
    assert sent == bytes(fake.raw)  # the bytes sent, in the order the controller read them
    replies = b"".join(event.data for event in events if isinstance(event, BytesReceived))
    numbers = [int(number) for number in re.findall(rb"\$qd\.(\d+)!", replies)]
    assert numbers == list(range(1, 801))  # the controller numbers its replies
    answered = [event for event in events if isinstance(event, ReplyReceived)]
    assert len(answered) == 800


def test_a_callback_that_queries_while_another_thread_switches_checksum_does_not_deadlock(
    make_client: Callable[..., Client],
) -> None:
    # The switching thread must not wait for the callback to see its events: the callback's
    # query waits for the switch to end (before: both waited for ever, reader thread included).
    switching: list[threading.Thread] = []
    switched = threading.Event()
    in_callback = threading.Event()
    answered: list[int] = []

    def query_during_the_switch(event: ClientEvent) -> None:
        elsewhere = switching and threading.current_thread() is not switching[0]
        if elsewhere and not in_callback.is_set():
            in_callback.set()
            # Once the switch holds its role (and, before, waited here), or is over.
            assert wait_until(lambda: rov._mode_switcher is not None or switched.is_set())
            answered.append(rov.depth_cm())

    def switch() -> None:
        rov.set_checksum(True)
        switched.set()

    rov = make_client(on_event=query_during_the_switch)
    switcher = threading.Thread(target=switch, daemon=True)
    switching.append(switcher)
    querying = threading.Thread(target=rov.depth_cm, daemon=True)
    querying.start()
    assert in_callback.wait(CONDITION_TIMEOUT_S)
    switcher.start()
    assert switched.wait(CONDITION_TIMEOUT_S)
    assert wait_until(lambda: answered == [123])  # (the callback may run in the reader thread)
    assert rov.checksum_enabled


def test_stray_lines_reach_on_stray_in_wire_order_whichever_thread_reads_them(
    make_client: Callable[..., Client], fake: FakeController
) -> None:
    # Before, each thread that read stray text reported it after letting the state go: a slow
    # callback in one thread was overtaken by another's report (debug lines out of order).
    from rovlink.protocol import Text

    seen: list[str] = []

    def slow_stray(event: object) -> None:
        if isinstance(event, Text):
            seen.append(event.text.strip())
            time.sleep(0.001)  # a callback that logs to a slow terminal

    rov = make_client(on_stray=slow_stray, keepalive_s=0.01)
    lines = 150
    done = threading.Event()

    def query() -> None:
        while not done.is_set():
            rov.depth_cm()

    threads = [threading.Thread(target=query) for _ in range(3)]
    for thread in threads:
        thread.start()
    try:
        for number in range(lines):
            fake.send(f"line {number}\r\n".encode())
        assert wait_until(lambda: len(seen) >= lines)
    finally:
        done.set()
        for thread in threads:
            thread.join(CONDITION_TIMEOUT_S)
        rov.close()
    assert seen == [f"line {number}" for number in range(lines)]


def test_a_client_prints_as_what_it_is_connected_to_and_its_state() -> None:
    # (Before: <rovlink.client.blocking.Client object at 0x7f…>, the same open or closed.)
    rov = rovlink.connect("sim://")
    assert repr(rov) == "<rovlink.client.Client simulated controller: open>"
    rov.close()
    assert str(rov) == "<rovlink.client.Client simulated controller: closed>"


async def test_an_asyncio_client_prints_so_too() -> None:
    rov = await rovlink.aio.connect("sim://")
    assert repr(rov) == "<rovlink.aio.AsyncClient simulated controller: open>"
    await rov.close()
    assert repr(rov) == "<rovlink.aio.AsyncClient simulated controller: closed>"


def test_a_call_while_close_settles_the_wire_names_the_port(
    fake: FakeController, make_client: Callable[..., Client]
) -> None:
    # (Before: "connection lost: closed", which of a program's clients not said.)
    rov = make_client()
    fake.then("hold")
    held = ThreadCall(rov.depth_cm)
    assert fake.wait_for(lambda f: "#qd!" in f.frames())
    closing = ThreadCall(rov.close)
    assert wait_until(lambda: rov.closed)
    with pytest.raises(ConnectionLostError, match=r"^connection lost: socket pair: closed$"):
        rov.depth_cm()
    fake.release()
    assert closing.done.wait(CONDITION_TIMEOUT_S)
    assert held.done.wait(CONDITION_TIMEOUT_S)
    assert held.error is None
