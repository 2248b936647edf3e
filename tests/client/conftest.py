"""Fixtures: a scripted fake controller on a socket pair, and clients connected to it."""

from __future__ import annotations

import asyncio
import itertools
import os
import socket
import threading
import time
import tty
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from types import TracebackType
from typing import Any

import pytest

from rovlink.aio import AsyncClient
from rovlink.client import Client, ClientOptions, links
from rovlink.client.links import FdLink, SocketLink
from tests.client.fake_controller import FakeController, FakeControllerServer

#: The timeout of queries that are meant to be answered: long enough for a reply on a loaded
#: machine. A passing test never waits it out.
REPLY_TIMEOUT_S = 2.0
#: The timeout of queries that are meant to go unanswered: short, so those tests are quick.
NO_REPLY_TIMEOUT_S = 0.25
#: How long a test waits for something that is bound to happen: it returns as soon as it does,
#: so only a failing test waits this out.
CONDITION_TIMEOUT_S = 5.0


class JumpingClock:
    """``time.monotonic()`` plus the jumps a test makes; read from any thread."""

    def __init__(self) -> None:
        self._offset_s = 0.0

    def __call__(self) -> float:
        return time.monotonic() + self._offset_s

    def jump(self, seconds: float) -> None:
        self._offset_s += seconds


def wait_until(predicate: Callable[[], bool], timeout_s: float = CONDITION_TIMEOUT_S) -> bool:
    """Poll a condition that has no notification of its own, until it holds or time runs out."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)
    return True


async def wait_until_async(
    predicate: Callable[[], bool], timeout_s: float = CONDITION_TIMEOUT_S
) -> bool:
    """:func:`wait_until` for coroutines: checks between turns of the event loop."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while not predicate():
        if loop.time() > deadline:
            return False
        await asyncio.sleep(0.005)
    return True


class ThreadCall:
    """A program thread that makes one call and keeps what became of it."""

    def __init__(self, call: Callable[[], object]) -> None:
        self.error: BaseException | None = None
        self.done = threading.Event()
        threading.Thread(target=self._run, args=(call,), daemon=True).start()

    def _run(self, call: Callable[[], object]) -> None:
        try:
            call()
        except BaseException as error:  # (kept for the test to look at)
            self.error = error
        finally:
            self.done.set()


class WatchedLock:
    """One of a client's locks, counting the threads waiting for it (put in its place)."""

    def __init__(self, lock: threading.RLock) -> None:
        self._lock = lock
        self._count = threading.Lock()
        self.waiting = 0

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        with self._count:
            self.waiting += 1
        try:
            return self._lock.acquire(blocking, timeout)
        finally:
            with self._count:
                self.waiting -= 1

    def release(self) -> None:
        self._lock.release()

    def __enter__(self) -> bool:
        return self.acquire()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.release()

    def _is_owned(self) -> bool:
        return bool(self._lock._is_owned())  # type: ignore[attr-defined]


@pytest.fixture
def fake_pair() -> Iterator[tuple[FakeController, socket.socket]]:
    fake, sock = FakeController.on_socketpair()
    yield fake, sock
    fake.close()


@pytest.fixture
def fake(fake_pair: tuple[FakeController, socket.socket]) -> FakeController:
    return fake_pair[0]


def client_options(**overrides: Any) -> ClientOptions:
    """The tests' connection settings: no readiness probe, no keep-alive and no motion expiry
    unless a test asks (the fake answers at once, and the frames a test expects are then
    exactly the ones it caused), with ``overrides``."""
    settings: dict[str, Any] = {
        "timeout_s": REPLY_TIMEOUT_S,
        "keepalive_s": None,
        "boot_timeout_s": None,
        "motion_timeout_s": None,
    }
    settings.update(overrides)
    return ClientOptions(**settings)


@pytest.fixture
def make_client(
    fake_pair: tuple[FakeController, socket.socket],
) -> Iterator[Callable[..., Client]]:
    """Connect a blocking client to the fake: ``make_client(checksum=True, ...)``.

    With ``drops_time_out_at_once=True`` the client's clock jumps past the timeout whenever the
    fake drops a query: the dropped attempt times out at once, whatever the machine's load,
    while the answered ones keep all of :data:`REPLY_TIMEOUT_S`.
    """
    fake, host_end = fake_pair
    clients: list[Client] = []

    def make(*, drops_time_out_at_once: bool = False, **overrides: Any) -> Client:
        options = client_options(**overrides)
        link = SocketLink(host_end, "socket pair")
        clock: Callable[[], float] = time.monotonic
        if drops_time_out_at_once:
            jumping = JumpingClock()

            def time_out_now() -> None:
                jumping.jump(options.timeout_s)
                link.wake()  # a reader blocked on the link looks at the clock again

            fake.on_drop = time_out_now
            clock = jumping
        client = Client(link, options, clock=clock)
        clients.append(client)
        return client

    yield make
    for client in clients:
        client.close()


@pytest.fixture
async def make_async_client(
    fake_pair: tuple[FakeController, socket.socket],
) -> AsyncIterator[Callable[..., Awaitable[AsyncClient]]]:
    """Connect an asyncio client to the fake: ``await make_async_client(checksum=True)``."""
    clients: list[AsyncClient] = []

    async def make(max_in_flight: int = 8, **overrides: Any) -> AsyncClient:
        client = AsyncClient(
            SocketLink(fake_pair[1], "socket pair"),
            client_options(**overrides),
            max_in_flight=max_in_flight,
        )
        clients.append(client)
        return await client.open()

    yield make
    for client in clients:
        await client.close()


@pytest.fixture
def port() -> Iterator[FakeControllerServer]:
    """A TCP port where a fake controller answers each connection (see the class)."""
    served = FakeControllerServer()
    yield served
    served.close()


@pytest.fixture
def pty_fake() -> Iterator[tuple[FakeController, str]]:
    """A fake controller on a pseudo-terminal; yields it and the terminal's path."""
    master, slave = os.openpty()
    tty.setraw(slave)  # no echo, no line editing, before the client opens it
    fake = FakeController(master)
    yield fake, os.ttyname(slave)
    fake.close()
    os.close(slave)


@pytest.fixture
def reopened() -> Iterator[list[FakeController]]:
    """The controllers of the reopened links, in order (closed after the test)."""
    fakes: list[FakeController] = []
    yield fakes
    for fake in fakes:
        fake.close()


async def longest_loop_stall_s(call: Callable[[], Awaitable[object]]) -> float:
    """Await ``call()`` while a task ticks every 10 ms; the longest the event loop went without
    running that task, s (a loop blocked by a call stands still for as long as it blocks)."""
    loop = asyncio.get_running_loop()
    ticks: list[float] = []

    async def tick() -> None:
        while True:
            ticks.append(loop.time())
            await asyncio.sleep(0.01)

    ticker = asyncio.ensure_future(tick())
    try:
        await asyncio.sleep(0.02)
        await call()
        ticks.append(loop.time())
    finally:
        ticker.cancel()
    return max(later - earlier for earlier, later in itertools.pairwise(ticks))


def fill_line(link: FdLink) -> None:
    """Fill the kernel's buffers towards a far end that does not read: the next write waits."""
    while link.send_some(b"\r\n" * 32768):
        pass


@pytest.fixture
def long_write_timeout(monkeypatch: pytest.MonkeyPatch) -> None:
    """A write waiting for room gives up only after the write timeout: made far longer than a
    test waits, so that a call that waits for such a write is told from one that does not."""
    monkeypatch.setattr(links, "WRITE_TIMEOUT_S", CONDITION_TIMEOUT_S * 10)
