"""``close()`` (or ``stop()``) from inside an event callback: the events it makes — the ``#stop!``
a recorder must end with — reach every callback once the callback returns, in the thread that
was delivering, in order, and no callback runs inside itself or beside itself.

Before, the blocking client's close() gave up the delivery its thread held: the reader thread
delivered the ``#stop!`` meanwhile, to a callback still running in the closing thread; the
asyncio client handed a callback the events made inside it from inside it (a stop() or a close()
started as an eager task).
"""

from __future__ import annotations

import asyncio
import socket
import threading
from collections.abc import Callable, Coroutine
from typing import Any

import pytest

from rovlink.aio import AsyncClient
from rovlink.client import Client
from rovlink.client.events import BytesSent, ClientEvent
from rovlink.client.links import SocketLink
from tests.client.conftest import client_options, wait_until
from tests.client.fake_controller import FakeController


class _Recorder:
    """A callback that records each event with the thread that handed it over, notes any call
    made while another call is still running, and runs ``action`` on the ``#th`` frame."""

    def __init__(self) -> None:
        self.events: list[tuple[ClientEvent, int]] = []
        self.overlapping: list[ClientEvent] = []
        self.action: Callable[[], None] = lambda: None
        self.acted_in: int | None = None
        self._running = 0
        self._lock = threading.Lock()

    def __call__(self, event: ClientEvent) -> None:
        with self._lock:
            self._running += 1
            if self._running > 1:
                self.overlapping.append(event)
        try:
            self.events.append((event, threading.get_ident()))
            if isinstance(event, BytesSent) and event.data.startswith(b"#th") and not self.acted_in:
                self.acted_in = threading.get_ident()
                self.action()
        finally:
            with self._lock:
                self._running -= 1

    def sent(self) -> list[bytes]:
        return [event.data for event, _ in self.events if isinstance(event, BytesSent)]

    def stop_delivered_by(self) -> int:
        return next(
            thread
            for event, thread in self.events
            if isinstance(event, BytesSent) and event.data == b"#stop!"
        )


@pytest.mark.parametrize("hook", ["on_event", "subscribe"])
def test_close_in_a_callback_of_the_blocking_client_delivers_its_stop_after_it(
    fake_pair: tuple[FakeController, socket.socket], hook: str
) -> None:
    fake, sock = fake_pair
    recorder = _Recorder()
    extra: dict[str, Any] = {"on_event": recorder} if hook == "on_event" else {}
    rov = Client(SocketLink(sock, "socket pair"), client_options(keepalive_s=0.05, **extra))
    if hook == "subscribe":
        rov.subscribe(recorder)
    recorder.action = rov.close
    # The reader thread reads meanwhile (keep-alives): before, it took over the delivery.
    assert wait_until(lambda: "#qd!" in fake.frames())
    rov.start()
    rov.move(90, 40)
    assert rov.closed
    assert wait_until(lambda: "#stop!" in fake.frames())
    assert recorder.sent()[-2:] == [b"#th.90.40!", b"#stop!"]
    assert recorder.overlapping == []
    assert recorder.stop_delivered_by() == recorder.acted_in


def _run_now(coroutine: Coroutine[Any, Any, None]) -> None:
    """Run ``coroutine`` up to its first wait, here, as a task of ``asyncio.eager_task_factory``
    (Python 3.12) starts; the rest (if any) as a task."""
    try:
        future = coroutine.send(None)
    except StopIteration:
        return
    coroutine.close()
    raise AssertionError(f"the coroutine waits for {future!r}: not one that ends at once")


@pytest.mark.parametrize("hook", ["on_event", "subscribe"])
async def test_stop_in_a_callback_of_the_asyncio_client_is_delivered_after_it(
    fake_pair: tuple[FakeController, socket.socket], hook: str
) -> None:
    fake, sock = fake_pair
    recorder = _Recorder()
    extra: dict[str, Any] = {"on_event": recorder} if hook == "on_event" else {}
    rov = await AsyncClient(SocketLink(sock, "socket pair"), client_options(**extra)).open()
    if hook == "subscribe":
        rov.subscribe(recorder)
    recorder.action = lambda: _run_now(rov.stop())
    try:
        await rov.start()
        await rov.move(90, 40)
        assert wait_until(lambda: "#stop!" in fake.frames())
    finally:
        await rov.close()
    # Before, the #stop! was handed to the callback from inside the call for the #th frame.
    assert recorder.overlapping == []
    assert recorder.sent()[-2:] == [b"#th.90.40!", b"#stop!"]


async def test_close_started_in_a_callback_of_the_asyncio_client_ends_with_its_stop(
    fake_pair: tuple[FakeController, socket.socket],
) -> None:
    fake, sock = fake_pair
    recorder = _Recorder()
    rov = await AsyncClient(SocketLink(sock, "socket pair"), client_options()).open()
    rov.subscribe(recorder)
    closing: list[asyncio.Task[None]] = []
    recorder.action = lambda: closing.append(asyncio.get_running_loop().create_task(rov.close()))
    await rov.start()
    await rov.move(90, 40)
    await closing[0]
    assert rov.closed
    assert wait_until(lambda: "#stop!" in fake.frames())
    assert recorder.overlapping == []
    assert recorder.sent()[-2:] == [b"#th.90.40!", b"#stop!"]
