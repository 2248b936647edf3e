"""Stress: many threads (blocking client) or tasks (asyncio client) on one connection at once,
through ``fault://``, until a close from elsewhere ends them.

The controller is the fake, whose ``$qd`` numbers the queries it has received, so that a reply
can be traced: a depth no greater than the count when the call began was produced for an
earlier query (stale, P20), and a depth handed to two calls was handed to the wrong one. The
fake's script drops, corrupts, delays (``late``) and surrounds replies with debug text and
noise; ``fault://`` delays every chunk with jitter, or also flips, drops and duplicates bytes
with checksums on. Meanwhile the checksum mode switches, the keep-alive runs and an event hook
records everything; then ``close()`` comes from another thread (or task).

What must hold:

* no call returns a stale depth or one another call got (byte damage aside: a damaged frame
  that passes the checksum can carry any value, so the runs with byte damage check the rest);
* every call returns, or raises ``QueryTimeoutError`` or (once closed) ``ConnectionLostError``,
  within a bound that only a hang exceeds;
* ``close()`` sends the ``#stop!`` it owes (the workers unlock and drive), and leaves none of
  the client's threads running;
* the link counters add up to the events the hook received, and the events come in order;
* a controller that answers all the time is never suspected of a reset (P21) on a line that
  damages no bytes: a lost or late reply never leaves a query to time out behind it.
"""

from __future__ import annotations

import asyncio
import collections
import random
import threading
import time
from collections.abc import Iterator

import pytest

import rovlink
import rovlink.aio
from rovlink.aio import AsyncClient
from rovlink.client import (
    Client,
    ConnectionLostError,
    LinkCounters,
    QueryTimeoutError,
    SupersededByStopError,
)
from rovlink.client.events import (
    BytesReceived,
    BytesSent,
    ClientEvent,
    LateReply,
    QueryFailed,
    ReplyReceived,
    ResetSuspected,
)
from rovlink.faults.settings import FaultSettings, fault_url
from tests.client.conftest import wait_until
from tests.client.fake_controller import FakeController, FakeControllerServer

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.realtime]

TIMEOUT_S = 0.5  # (the default: a loaded machine stalls a process for less)
RETRIES = 2
#: Longer than any call takes without a hang: its attempts, a fence or a quiet line before
#: each, a checksum switch waiting for the wire, on a loaded machine.
CALL_BOUND_S = 10.0
_SCRIPT = ["reply"] * 12 + ["drop", "corrupt", "late", "debug", "noise"]
_CALLS = ("depth_cm", "depth_cm", "sensors", "heading_deg", "roll_deg", "move", "set_max_pwm")
#: fault:// settings: a slow line (delay and jitter only), or one that also damages bytes.
_LINES = {
    "delays": FaultSettings(delay_ms=3.0, jitter_ms=2.0),
    "damage": FaultSettings(ber=2e-4, drop=5e-4, dup=5e-4, delay_ms=3.0, jitter_ms=2.0),
}


class _Record:
    """What the workers saw, checked at the end."""

    def __init__(self, fake: FakeController, *, values_checked: bool) -> None:
        self.fake = fake
        self.values_checked = values_checked
        self.wrong: list[str] = []
        self.depths: list[int] = []
        self.outcomes: collections.Counter[str] = collections.Counter()
        self._lock = threading.Lock()

    def took(self, call: str, started: float) -> None:
        took_s = time.monotonic() - started
        if took_s > CALL_BOUND_S:
            with self._lock:
                self.wrong.append(f"{call} took {took_s:.1f} s")

    def result(self, call: str, value: object, count_before: int) -> None:
        with self._lock:
            self.outcomes["ok"] += 1
            depth = getattr(value, "depth_cm", value) if call in ("depth_cm", "sensors") else None
            if not self.values_checked or not isinstance(depth, int):
                return
            if depth <= count_before:
                self.wrong.append(f"{call}: stale depth {depth} (count {count_before} before)")
            self.depths.append(depth)

    def error(self, call: str, error: Exception) -> None:
        with self._lock:
            if isinstance(error, QueryTimeoutError | ConnectionLostError | SupersededByStopError):
                self.outcomes[type(error).__name__] += 1
            else:
                self.wrong.append(f"{call} raised {error!r}")

    def check(self) -> None:
        assert self.wrong == []
        repeated = [depth for depth, n in collections.Counter(self.depths).items() if n > 1]
        assert repeated == [], "a reply handed to two calls"
        assert self.outcomes["ok"] > 50, self.outcomes  # (the run did something)


def _counters_add_up(events: list[ClientEvent], counters: LinkCounters) -> None:
    def count(kind: type) -> int:
        return sum(isinstance(event, kind) for event in events)

    sent = [event for event in events if isinstance(event, BytesSent)]
    assert counters.bytes_sent == sum(len(event.data) for event in sent)
    assert counters.frames_sent == sum(event.data.count(b"!") for event in sent)
    assert counters.retries == sum(event.retry for event in sent)
    assert counters.bytes_received == sum(
        len(event.data) for event in events if isinstance(event, BytesReceived)
    )
    assert counters.replies == count(ReplyReceived)
    assert counters.late_replies == count(LateReply)
    assert counters.resets_suspected == count(ResetSuspected)
    timeouts = sum(
        isinstance(event, QueryFailed) and event.outcome == "timeout" for event in events
    )
    assert counters.timeouts == timeouts
    times = [event.at_s for event in events]
    assert times == sorted(times), "events out of order"


def _stop_owed_was_sent(events: list[ClientEvent], fake: FakeController, line: str) -> None:
    """The last lock command the client wrote is ``#stop!``, and (on a line that damages no
    bytes) the last one the controller got."""
    sent = [event.command for event in events if isinstance(event, BytesSent)]
    locks = [command.name for command in sent if command and command.name in ("start", "stop")]
    assert locks[-1:] == ["stop"], "close() sent no #stop! after the last #start!"
    if line == "delays":
        assert wait_until(lambda: "#stop!" in fake.frames())
        received = [frame for frame in fake.frames() if frame in ("#start!", "#stop!")]
        assert received[-1] == "#stop!"


def _client_threads_end(before: set[int | None]) -> None:
    # (Not the fake's, nor the event loop's executor: it outlives a client, and the loop's
    # end ends it.)
    def ours() -> list[str]:
        return [
            thread.name
            for thread in threading.enumerate()
            if thread.ident not in before
            and not thread.name.startswith(("fake controller", "asyncio_"))
        ]

    assert wait_until(lambda: not ours()), f"threads left: {ours()}"


@pytest.fixture
def served() -> Iterator[FakeControllerServer]:
    server = FakeControllerServer()
    yield server
    server.close()


def _numbering_fake(server: FakeControllerServer, seed: int) -> FakeController:
    assert wait_until(lambda: bool(server.fakes))
    fake = server.fakes[0]
    fake.qd_counts_queries = True
    fake.late_delay_s = 0.1
    rng = random.Random(seed)
    fake.then(*[rng.choice(_SCRIPT) for _ in range(3000)])
    return fake


def _url(server: FakeControllerServer, line: str, seed: int) -> str:
    settings = _LINES[line]
    return fault_url(server.url, FaultSettings(**{**settings.__dict__, "seed": seed}))


def _call(client: Client, call: str, rng: random.Random) -> object:
    if call == "move":
        client.move(rng.randrange(360), rng.randrange(1, 40))
    elif call == "set_max_pwm":
        client.set_max_pwm(rng.randrange(100, 256))
    else:
        return getattr(client, call)()
    return None


@pytest.mark.parametrize("line", ["delays", "damage"])
@pytest.mark.parametrize("seed", [1])
def test_threads_through_a_faulty_line_until_another_thread_closes(
    served: FakeControllerServer, line: str, seed: int
) -> None:
    before = {thread.ident for thread in threading.enumerate()}
    events: list[ClientEvent] = []
    client = rovlink.connect(
        _url(served, line, seed),
        timeout=TIMEOUT_S,
        retries=RETRIES,
        checksum=line == "damage",
        keepalive=0.05,
        boot_timeout=None,
        motion_timeout=None,
        on_event=events.append,
    )
    fake = _numbering_fake(served, seed)
    record = _Record(fake, values_checked=line == "delays")
    client.start()

    def worker(index: int) -> None:
        rng = random.Random(seed * 100 + index)
        while not client.closed:
            call = rng.choice(_CALLS)
            count_before = fake.query_count
            started = time.monotonic()
            try:
                value = _call(client, call, rng)
            except Exception as error:
                record.error(call, error)
            else:
                record.result(call, value, count_before)
            record.took(call, started)

    def switch_checksum() -> None:
        rng = random.Random(seed)
        while not client.closed:
            try:
                client.set_checksum(rng.random() < 0.5)
            except Exception as error:
                record.error("set_checksum", error)
            time.sleep(0.1)

    threads = [threading.Thread(target=worker, args=(index,)) for index in range(6)]
    threads.append(threading.Thread(target=switch_checksum))
    for thread in threads:
        thread.start()
    assert wait_until(lambda: record.outcomes["ok"] >= 300, 60.0), record.outcomes
    closer = threading.Thread(target=client.close)
    closer.start()
    closer.join(CALL_BOUND_S)
    for thread in [*threads, closer]:
        thread.join(CALL_BOUND_S)
    assert not any(thread.is_alive() for thread in [*threads, closer]), "a call hung"
    record.check()
    _stop_owed_was_sent(events, fake, line)
    _counters_add_up(events, client.counters)
    if line == "delays":
        # The controller never resets, and answers all the time. (Damage may lose a #crcon!
        # or #crcoff!: the modes then differ until the client re-asserts its own, P21.)
        assert client.counters.resets_suspected == 0
    _client_threads_end(before)


@pytest.mark.parametrize("line", ["delays", "damage"])
@pytest.mark.parametrize("seed", [1])
async def test_tasks_through_a_faulty_line_until_another_task_closes(
    served: FakeControllerServer, line: str, seed: int
) -> None:
    before = {thread.ident for thread in threading.enumerate()}
    events: list[ClientEvent] = []
    client: AsyncClient = await rovlink.aio.connect(
        _url(served, line, seed),
        timeout=TIMEOUT_S,
        retries=RETRIES,
        checksum=line == "damage",
        keepalive=0.05,
        boot_timeout=None,
        motion_timeout=None,
        on_event=events.append,
    )
    fake = _numbering_fake(served, seed)
    record = _Record(fake, values_checked=line == "delays")
    await client.start()

    async def worker(index: int) -> None:
        rng = random.Random(seed * 100 + index)
        while not client.closed:
            call = rng.choice(_CALLS)
            count_before = fake.query_count
            started = time.monotonic()
            try:
                value: object = None
                if call == "move":
                    await client.move(rng.randrange(360), rng.randrange(1, 40))
                elif call == "set_max_pwm":
                    await client.set_max_pwm(rng.randrange(100, 256))
                else:
                    value = await getattr(client, call)()
            except Exception as error:
                record.error(call, error)
            else:
                record.result(call, value, count_before)
            record.took(call, started)

    async def switch_checksum() -> None:
        rng = random.Random(seed)
        while not client.closed:
            try:
                await client.set_checksum(rng.random() < 0.5)
            except Exception as error:
                record.error("set_checksum", error)
            await asyncio.sleep(0.1)

    tasks = [asyncio.create_task(worker(index)) for index in range(12)]
    tasks.append(asyncio.create_task(switch_checksum()))
    for _ in range(6000):
        if record.outcomes["ok"] >= 300 or all(task.done() for task in tasks):
            break
        await asyncio.sleep(0.01)
    await asyncio.wait_for(asyncio.create_task(client.close()), CALL_BOUND_S)
    await asyncio.wait_for(asyncio.gather(*tasks), CALL_BOUND_S)
    record.check()
    _stop_owed_was_sent(events, fake, line)
    _counters_add_up(events, client.counters)
    if line == "delays":
        # The controller never resets, and answers all the time. (Damage may lose a #crcon!
        # or #crcoff!: the modes then differ until the client re-asserts its own, P21.)
        assert client.counters.resets_suspected == 0
    _client_threads_end(before)
