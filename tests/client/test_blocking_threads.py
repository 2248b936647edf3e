"""The blocking client shared by threads: callers, the background reader, the reconnecting
thread and the callbacks, each in the way of the others.

Every test waits on conditions with timeouts; none sleeps and hopes. A call that must end is
joined with a bound, and a test that finds a thread still blocked fails rather than hangs.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterator

import pytest

import rovlink
from rovlink.client import Client, ConnectionLostError, QueryTimeoutError
from rovlink.client.events import BytesSent, ClientEvent, LinkState, MotionExpired
from rovlink.client.links import SocketLink
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    NO_REPLY_TIMEOUT_S,
    WatchedLock,
    client_options,
    wait_until,
)
from tests.client.fake_controller import FakeController, FakeControllerServer

pytestmark = pytest.mark.integration

MakeClient = Callable[..., Client]


def _run(target: Callable[[], object]) -> tuple[threading.Thread, list[object]]:
    """Start ``target`` in a thread; its outcome (a result or an exception) lands in the list."""
    outcome: list[object] = []

    def run() -> None:
        try:
            outcome.append(target())
        except BaseException as error:
            outcome.append(error)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, outcome


def _assert_idle(client: Client) -> None:
    """Nobody holds the reader role or counts as active, and the state lock is free."""
    assert wait_until(lambda: client._reader_ident in (None, client._background_ident))
    assert wait_until(lambda: not client._callers)
    assert client._state_lock.acquire(timeout=CONDITION_TIMEOUT_S), "state lock held"
    client._state_lock.release()


# -- P23: motion expiry while other threads keep the client busy ------------------------------


def test_motion_expires_while_another_thread_polls(
    fake: FakeController, make_client: MakeClient
) -> None:
    # A telemetry thread polls without a pause; the thread that commanded the motion has hung.
    # The polling kept the background reader (which expires motion) out for good: the robot
    # went on at 60 % for as long as the polling lasted.
    client = make_client(motion_timeout_s=0.3)
    client.start()
    client.move(45, 60)
    polling = threading.Event()
    polling.set()

    def poll() -> int:
        count = 0
        while polling.is_set():
            assert client.depth_cm() == 123
            count += 1
        return count

    thread, outcome = _run(poll)
    try:
        assert fake.wait_for(lambda f: "#th.45.0!" in f.frames(), CONDITION_TIMEOUT_S)
    finally:
        polling.clear()
        thread.join(CONDITION_TIMEOUT_S)
    assert isinstance(outcome[0], int)  # it polled all along, without an error
    assert outcome[0] > 0
    assert client.counters.motion_expiries == 1
    assert fake.frames().count("#th.45.0!") == 1


def test_motion_expires_while_a_caller_waits_for_a_slow_reply(
    fake: FakeController, make_client: MakeClient
) -> None:
    # A caller waiting for a reply that does not come holds the reader role for its timeout
    # (2 s here): the motion is expired on time all the same.
    client = make_client(motion_timeout_s=0.2, retries=0)
    client.start()
    client.move(90, 30)
    fake.then("drop")
    thread, outcome = _run(client.depth_cm)
    assert fake.wait_for(lambda f: "#qd!" in f.frames())
    assert fake.wait_for(lambda f: "#th.90.0!" in f.frames(), 1.0)
    assert thread.is_alive()  # zero thrust went out while the query was still waiting
    thread.join(CONDITION_TIMEOUT_S)
    assert isinstance(outcome[0], QueryTimeoutError)


def test_stop_goes_out_while_other_threads_wait_for_replies(
    fake: FakeController, make_client: MakeClient
) -> None:
    client = make_client(retries=0)
    fake.then(*["drop"] * 4)
    threads = [_run(method) for method in (client.depth_cm, client.heading_deg, client.sensors)]
    assert fake.wait_for(lambda f: len(f.commands) >= 4)
    started = time.monotonic()
    client.stop()
    assert fake.wait_for(lambda f: f.frames()[-1] == "#stop!", 1.0)
    assert time.monotonic() - started < 1.0  # not after the waiting callers' timeouts
    for thread, outcome in threads:
        thread.join(CONDITION_TIMEOUT_S)
        assert isinstance(outcome[0], QueryTimeoutError)


# -- callbacks that use the client ---------------------------------------------------------------


def test_a_callback_may_query_when_motion_expires(
    fake: FakeController, make_client: MakeClient
) -> None:
    # The background reader reported the expiry while it still held the reader role: the
    # callback's query could never be read, and timed out on every attempt (with suspected
    # resets) while every other caller waited too.
    depths: list[object] = []
    client: Client | None = None

    def on_event(event: ClientEvent) -> None:
        if isinstance(event, MotionExpired) and client is not None:
            try:
                depths.append(client.depth_cm())
            except QueryTimeoutError as error:
                depths.append(error)

    client = make_client(motion_timeout_s=0.1, retries=0, on_event=on_event)
    client.start()
    client.move(0, 20)
    assert wait_until(lambda: bool(depths))
    assert depths == [123]
    assert client.counters.timeouts == 0


def test_a_subscriber_may_query_on_a_keepalive(
    fake: FakeController, make_client: MakeClient
) -> None:
    headings: list[object] = []
    client = make_client(keepalive_s=0.05, retries=0)

    def on_event(event: ClientEvent) -> None:
        if isinstance(event, BytesSent) and event.by_session and not headings:
            try:
                headings.append(client.heading_deg())
            except QueryTimeoutError as error:
                headings.append(error)

    client.subscribe(on_event)
    assert wait_until(lambda: bool(headings))
    assert headings == [275]
    assert client.counters.timeouts == 0


def test_a_raising_callback_with_threads_leaves_the_client_usable(
    fake: FakeController, make_client: MakeClient
) -> None:
    def explode(event: ClientEvent) -> None:
        raise RuntimeError("callback bug")

    client = make_client(on_event=explode, keepalive_s=0.02)
    results: list[object] = []

    def ask() -> None:
        for _ in range(20):
            results.append(client.heading_deg())

    threads = [threading.Thread(target=ask) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(CONDITION_TIMEOUT_S)
    assert results == [275] * 80
    _assert_idle(client)


def test_close_from_a_callback(fake: FakeController, make_client: MakeClient) -> None:
    client: Client | None = None
    closed = threading.Event()

    def on_event(event: ClientEvent) -> None:
        if isinstance(event, BytesSent) and event.by_session and client is not None:
            client.close()  # on the background reader's thread
            client.close()  # and again
            closed.set()

    client = make_client(keepalive_s=0.05, on_event=on_event)
    assert closed.wait(CONDITION_TIMEOUT_S)
    assert client.closed
    with pytest.raises(ConnectionLostError):
        client.depth_cm()


# -- close() while calls are in flight ----------------------------------------------------------


def test_a_second_close_returns_once_the_port_is_released(
    fake_pair: tuple[FakeController, socket.socket], make_client: MakeClient
) -> None:
    # The first close() waits for a query on the wire; a second one from another thread
    # returned at once, with the port still open (a program that then reopened its serial
    # port found it taken, P22).
    fake, host_end = fake_pair
    client = make_client(timeout_s=0.5, retries=0)
    fake.then("drop")
    asking, _ = _run(client.depth_cm)
    assert fake.wait_for(lambda f: "#qd!" in f.frames())
    first, _ = _run(client.close)
    assert wait_until(lambda: client.closed)
    client.close()
    assert host_end.fileno() == -1  # released by the time close() returned
    first.join(CONDITION_TIMEOUT_S)
    asking.join(CONDITION_TIMEOUT_S)
    assert not first.is_alive()
    assert not asking.is_alive()


def test_close_ends_calls_in_flight_on_every_thread(
    fake: FakeController, make_client: MakeClient
) -> None:
    timeout_s = 0.3
    client = make_client(timeout_s=timeout_s, retries=50)
    fake.then(*["drop"] * 1000)
    methods = [client.depth_cm, client.heading_deg, client.sensors, client.roll_deg] * 2
    threads = [_run(method) for method in methods]
    assert fake.wait_for(lambda f: len(f.commands) >= 1 + len(methods))
    started = time.monotonic()
    client.close()
    assert time.monotonic() - started < timeout_s + 2.0
    for thread, outcome in threads:
        thread.join(timeout_s + 2.0)
        assert not thread.is_alive()
        assert isinstance(outcome[0], ConnectionLostError | QueryTimeoutError), outcome
    assert sum(isinstance(outcome[0], ConnectionLostError) for _, outcome in threads) >= 1


# -- the link lost mid-call ---------------------------------------------------------------------


def test_a_lost_link_ends_every_call_in_flight(
    fake: FakeController, make_client: MakeClient
) -> None:
    client = make_client(retries=0)
    fake.then("drop", "drop", "drop", "close")
    methods = [client.depth_cm, client.heading_deg, client.sensors, client.depth_cm]
    threads: list[tuple[threading.Thread, list[object]]] = []
    for method in methods:  # one after the other: the fourth query is the one that closes
        threads.append(_run(method))
        assert fake.wait_for(lambda f: len(f.commands) >= 1 + len(threads))
    for thread, outcome in threads:
        thread.join(CONDITION_TIMEOUT_S)
        assert not thread.is_alive()
        assert isinstance(outcome[0], ConnectionLostError)
    assert client.closed


def test_a_lost_link_mid_calls_with_reconnect(port: FakeControllerServer) -> None:
    rov = rovlink.connect(port.url, reconnect=True, timeout=2.0, keepalive=None, boot_timeout=2.0)
    try:
        assert rov.depth_cm() == 123
        port.fakes[0].then("drop", "drop", "close")
        threads = [_run(method) for method in (rov.depth_cm, rov.heading_deg, rov.sensors)]
        for thread, outcome in threads:
            thread.join(CONDITION_TIMEOUT_S)
            assert not thread.is_alive()
            assert isinstance(outcome[0], ConnectionLostError)
        assert wait_until(lambda: len(port.fakes) == 2)
        results = [_run(method) for method in (rov.depth_cm, rov.heading_deg) * 3]
        for thread, _ in results:
            thread.join(CONDITION_TIMEOUT_S)
        assert sorted(str(outcome[0]) for _, outcome in results) == ["123"] * 3 + ["275"] * 3
        assert not rov.closed
    finally:
        rov.close()


def test_close_while_reconnecting_releases_the_port() -> None:
    # The reconnecting thread was waiting for the reopened controller to boot: close()
    # returned while it kept the new port open (for up to boot_timeout).
    port = FakeControllerServer(boot_s=30.0, first_boot_s=0.0)
    try:
        rov = rovlink.connect(port.url, reconnect=True, timeout=0.5, keepalive=None)
        assert rov.depth_cm() == 123
        port.fakes[0].close()
        assert wait_until(lambda: len(port.fakes) == 2)  # reopened; the controller boots
        rov.close()
        assert port.ended[1].wait(1.0), "the reopened port stayed open after close()"
    finally:
        port.close()


def test_set_checksum_while_reconnecting(port: FakeControllerServer) -> None:
    # set_checksum() waited for the reconnection while holding the state lock, which the
    # reconnecting thread needs: the whole client hung for good.
    rov = rovlink.connect(port.url, reconnect=True, timeout=2.0, keepalive=None, boot_timeout=2.0)
    deadlocked = False
    try:
        assert rov.depth_cm() == 123
        port.refuse = True
        port.fakes[0].close()
        assert wait_until(lambda: rov._reconnecting)
        switch, outcome = _run(lambda: rov.set_checksum(True))
        port.refuse = False
        switch.join(CONDITION_TIMEOUT_S)
        deadlocked = switch.is_alive()
        assert not deadlocked, "set_checksum() hung while the link was being reopened"
        assert outcome[0] is None or isinstance(outcome[0], ConnectionLostError)
        assert wait_until(lambda: not rov._reconnecting)
        rov.set_checksum(True)
        assert rov.heading_deg() == 275
        assert port.fakes[-1].decoder.checksum_enabled
    finally:
        if not deadlocked:  # (close() would wait for the held lock forever)
            rov.close()


# -- checksum switching beside other threads ----------------------------------------------------


@pytest.fixture
def fake_and_host_end() -> Iterator[tuple[FakeController, socket.socket]]:
    fake, host_end = FakeController.on_socketpair()
    yield fake, host_end
    fake.close()


def test_set_checksum_waits_for_the_fence_of_a_query_that_timed_out(
    fake_and_host_end: tuple[FakeController, socket.socket],
) -> None:
    # A query on the wire when set_checksum() began timed out, and its fence went out in the
    # old mode; the switch did not wait for the fence's reply, which then failed its checksum
    # and left the name late: the next query's own reply was discarded and it timed out.
    fake, host_end = fake_and_host_end
    fake.late_delay_s = 0.2
    client = Client(
        SocketLink(host_end, "socket pair"),
        client_options(timeout_s=0.5, retries=0),
    )
    try:
        fake.then("drop", "late")  # the query gets no reply; the fence's comes 0.2 s late
        asking, outcome = _run(client.depth_cm)
        assert fake.wait_for(lambda f: "#qd!" in f.frames())
        client.set_checksum(True)
        asking.join(CONDITION_TIMEOUT_S)
        assert isinstance(outcome[0], QueryTimeoutError)
        assert client.depth_cm() == 123
        assert fake.frames()[1:] == ["#qd!", "#qhe!", "#crcon!", "#qd!"]
        counters = client.counters
        assert (counters.checksum_errors, counters.late_replies) == (0, 0)
    finally:
        client.close()


def test_set_checksum_on_a_silent_line_waits_for_one_fence_at_most(
    fake: FakeController, make_client: MakeClient
) -> None:
    timeout_s = 0.25
    client = make_client(timeout_s=timeout_s, retries=2)
    fake.then(*["drop"] * 50)
    asking, outcome = _run(client.depth_cm)
    assert fake.wait_for(lambda f: "#qd!" in f.frames())
    started = time.monotonic()
    client.set_checksum(True)
    assert time.monotonic() - started < 2 * timeout_s + 0.5  # the query, then its fence
    assert client.checksum_enabled
    asking.join(CONDITION_TIMEOUT_S)
    assert isinstance(outcome[0], QueryTimeoutError)


def test_checksum_switches_while_threads_query(
    fake_and_host_end: tuple[FakeController, socket.socket],
) -> None:
    fake, host_end = fake_and_host_end
    fake.qd_counts_queries = True
    client = Client(
        SocketLink(host_end, "socket pair"),
        client_options(timeout_s=2.0, retries=0),
    )
    wrong: list[str] = []
    switching = threading.Event()
    switching.set()

    def query() -> None:
        while switching.is_set():
            before = fake.query_count
            depth = client.depth_cm()
            if depth <= before:
                wrong.append(f"stale depth {depth} (query count {before} before)")
            if client.heading_deg() != 275:
                wrong.append("heading")

    threads = [_run(query) for _ in range(4)]
    try:
        for round_ in range(20):
            client.set_checksum(round_ % 2 == 0)
            assert client.pitch_deg() == 15
    finally:
        switching.clear()
        for thread, _ in threads:
            thread.join(CONDITION_TIMEOUT_S)
    try:
        assert [outcome for _, outcome in threads] == [[None]] * 4
        assert wrong == []
        counters = client.counters
        assert (counters.timeouts, counters.checksum_errors, counters.bad_frames) == (0, 0, 0)
        assert fake.bad_frames == []
        _assert_idle(client)
    finally:
        client.close()


# -- many threads on a line that drops, corrupts and delays -----------------------------------

_FAULTS = ["reply"] * 10 + ["drop", "corrupt", "late", "debug", "noise"]


@pytest.mark.parametrize("checksum", [False, True])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_threads_on_a_faulty_line_get_fresh_replies_or_errors(
    fake: FakeController, make_client: MakeClient, checksum: bool, seed: int
) -> None:
    """Single-reply queries of several names from six threads: each call returns a reply sent
    after it began (``$qd`` numbers the queries), or raises; none outlasts its attempts."""
    import random

    timeout_s, retries = 0.3, 2
    fake.qd_counts_queries = True
    fake.late_delay_s = 0.1
    rng = random.Random(seed)
    fake.then(*[rng.choice(_FAULTS) for _ in range(600)])
    client = make_client(checksum=checksum, timeout_s=timeout_s, retries=retries, keepalive_s=0.05)
    wrong: list[str] = []
    depths: list[int] = []
    lock = threading.Lock()
    # Each attempt may wait once for a fence (P20) besides its own timeout. (No qsa here: never
    # every name late, so never a quiet-line wait.)
    bound_s = 2 * timeout_s * (retries + 1) + 1.0

    def worker(index: int) -> None:
        choose = random.Random(seed * 100 + index).choice
        for _ in range(30):
            method = choose(["depth_cm", "depth_cm", "heading_deg", "roll_deg"])
            before = fake.query_count
            started = time.monotonic()
            try:
                value = getattr(client, method)()
            except QueryTimeoutError:
                value = None
            took_s = time.monotonic() - started
            with lock:
                if took_s > bound_s:
                    wrong.append(f"{method} took {took_s:.2f} s")
                if method == "depth_cm" and value is not None:
                    if value <= before:
                        wrong.append(f"stale depth {value} (query count {before} before)")
                    depths.append(value)
                elif value is not None and value != {"heading_deg": 275, "roll_deg": -1}[method]:
                    wrong.append(f"{method} → {value}")

    threads = [threading.Thread(target=worker, args=(index,)) for index in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60.0)
    assert not any(thread.is_alive() for thread in threads)
    assert wrong == []
    assert len(depths) == len(set(depths))  # no reply handed to two callers
    _assert_idle(client)
    fake.script.clear()
    assert client.depth_cm() > max(depths, default=0)  # usable afterwards


@pytest.mark.parametrize("seed", [1, 2])
def test_threads_with_qsa_on_a_line_that_drops_corrupts_and_delays(
    fake: FakeController, make_client: MakeClient, seed: int
) -> None:
    """``qsa`` (six replies) among single queries, on a line that drops, corrupts and delays
    replies: a reply that a qsa shares with a single query (``$qd``) never goes stale."""
    import random

    fake.qd_counts_queries = True
    fake.late_delay_s = 0.1
    rng = random.Random(seed)
    fake.then(
        *[
            rng.choice(["reply"] * 8 + ["drop", "corrupt", "late", "debug", "noise"])
            for _ in range(400)
        ]
    )
    # (Short timeouts: the drops are waited out, and the late replies come 0.1 s late.)
    client = make_client(timeout_s=NO_REPLY_TIMEOUT_S, retries=2)
    wrong: list[str] = []
    depths: list[int] = []
    lock = threading.Lock()

    def worker(index: int) -> None:
        choose = random.Random(seed * 100 + index).choice
        for _ in range(25):
            method = choose(["depth_cm", "sensors", "heading_deg"])
            before = fake.query_count
            try:
                value = getattr(client, method)()
            except QueryTimeoutError:
                continue
            depth = value.depth_cm if method == "sensors" else value
            with lock:
                if method == "sensors" and (value.heading_deg, value.roll_deg) != (275, -1):
                    wrong.append(f"sensors → {value}")
                if method == "heading_deg":
                    if value != 275:
                        wrong.append(f"heading → {value}")
                elif depth <= before:
                    wrong.append(f"stale depth {depth} from {method} ({before} before)")
                else:
                    depths.append(depth)

    threads = [threading.Thread(target=worker, args=(index,)) for index in range(5)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60.0)
    assert not any(thread.is_alive() for thread in threads)
    assert wrong == []
    assert len(depths) == len(set(depths))
    _assert_idle(client)


def test_link_state_events_reach_a_subscriber_that_queries(port: FakeControllerServer) -> None:
    """A subscriber that queries on ``lost`` waits for the reconnection, as any caller does."""
    rov = rovlink.connect(port.url, reconnect=True, timeout=2.0, keepalive=0.1, boot_timeout=2.0)
    depths: list[object] = []

    def on_event(event: ClientEvent) -> None:
        if isinstance(event, LinkState) and event.state == "lost":
            try:
                depths.append(rov.depth_cm())
            except ConnectionLostError as error:
                depths.append(error)

    try:
        rov.subscribe(on_event)
        port.fakes[0].close()
        assert wait_until(lambda: bool(depths))
        assert depths == [123]
    finally:
        rov.close()


class _SlowSendLink(SocketLink):
    """A socket link whose ``send_some`` is held, once the gate is shut, until the test opens
    it: a write under way in the kernel call. Notes whether the port was closed meanwhile."""

    def __init__(self, sock: socket.socket, description: str) -> None:
        super().__init__(sock, description)
        self.gate = threading.Event()
        self.gate.set()
        self.sending = threading.Event()
        self.closed_under_a_send = False

    def send_some(self, data: bytes | bytearray | memoryview) -> int:
        if not self.gate.is_set():
            self.sending.set()
            self.gate.wait(CONDITION_TIMEOUT_S)
            self.closed_under_a_send = self._closed
        return super().send_some(data)


def test_close_lets_a_write_under_way_in_another_thread_end_before_it_closes_the_port() -> None:
    # Before, close() closed the descriptor while another thread's write was in its kernel
    # call: a port opened meanwhile could get the same number and be written to.
    fake, host_end = FakeController.on_socketpair()
    link = _SlowSendLink(host_end, "socket pair, slow to send")
    rov = Client(link, client_options())
    wire_lock = WatchedLock(rov._wire_lock)
    rov._wire_lock = wire_lock  # type: ignore[assignment]
    try:
        link.gate.clear()
        stopping, outcome = _run(rov.stop)  # (from another thread, as a safety thread does)
        assert link.sending.wait(CONDITION_TIMEOUT_S)
        closing, _ = _run(rov.close)
        assert wait_until(lambda: wire_lock.waiting == 1 or link._closed)
        assert not link._closed
        link.gate.set()
        closing.join(CONDITION_TIMEOUT_S)
        stopping.join(CONDITION_TIMEOUT_S)
        assert not closing.is_alive()
        assert not link.closed_under_a_send
        assert outcome == [None]
        assert fake.wait_for(lambda f: "#stop!" in f.frames())
    finally:
        link.gate.set()
        rov.close()
        fake.close()
