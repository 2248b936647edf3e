"""A ``stop()`` supersedes the unlock and motion commands already waiting to be written when it
is called: they are not sent after the ``#stop!`` (a ``start()`` would unlock the robot just
stopped) and raise SupersededByStopError; queries and other commands still go."""

from __future__ import annotations

import asyncio
import socket
import threading

import pytest

from rovlink.aio import AsyncClient
from rovlink.client import Client, SupersededByStopError
from rovlink.client.links import SocketLink
from rovlink.protocol import Command
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    ThreadCall,
    WatchedLock,
    client_options,
    wait_until,
    wait_until_async,
)
from tests.client.fake_controller import FakeController


class _GatedLink(SocketLink):
    """A socket link whose ``write`` waits, while the gate is shut, until the test opens it."""

    def __init__(self, sock: socket.socket, description: str) -> None:
        super().__init__(sock, description)
        self.gate = threading.Event()
        self.gate.set()
        self.held = threading.Event()  # a write is waiting at the shut gate

    def write(self, data: bytes) -> None:
        if not self.gate.is_set():
            self.held.set()
            self.gate.wait(CONDITION_TIMEOUT_S)
        super().write(data)


@pytest.fixture
def gated() -> tuple[FakeController, _GatedLink]:
    fake, host_end = FakeController.on_socketpair()
    return fake, _GatedLink(host_end, "socket pair, gated")


def test_a_start_waiting_behind_a_slow_write_is_not_sent_after_a_stop_called_meanwhile(
    gated: tuple[FakeController, _GatedLink],
) -> None:
    # Before, the start() waiting for the wire lock and the stop() called after it went out in
    # either order: a #start! after the #stop! unlocked the robot the program had just stopped.
    fake, link = gated
    rov = Client(link, client_options())
    watched = WatchedLock(rov._wire_lock)
    rov._wire_lock = watched  # type: ignore[assignment]
    try:
        link.gate.clear()
        slow = ThreadCall(lambda: rov.set_max_pwm(180))  # thread A: its write waits at the gate
        assert link.held.wait(CONDITION_TIMEOUT_S)
        starting = ThreadCall(rov.start)  # thread B: waits for the wire lock
        assert wait_until(lambda: watched.waiting == 1)
        debugging = ThreadCall(lambda: rov.set_debug(True))  # neither moves nor unlocks
        assert wait_until(lambda: watched.waiting == 2)
        stopping = ThreadCall(rov.stop)  # thread C, after both
        assert wait_until(lambda: watched.waiting == 3)
        link.gate.set()
        for call in (slow, starting, debugging, stopping):
            assert call.done.wait(CONDITION_TIMEOUT_S)
        assert slow.error is None
        assert debugging.error is None
        assert stopping.error is None
        assert isinstance(starting.error, SupersededByStopError)
        assert starting.error.command == Command("start")
        assert "#start!" in str(starting.error)
        assert "stop" in str(starting.error)
        assert fake.wait_for(lambda f: {"#stop!", "#debug1!"} <= set(f.frames()))
        frames = fake.frames()
        assert "#start!" not in frames
        assert frames.index("#mgmp.180!") < frames.index("#stop!")
        # The client goes on: a start() called after the stop is sent.
        rov.start()
        assert fake.wait_for(lambda f: f.frames()[-1] == "#start!")
    finally:
        link.gate.set()
        rov.close()
        fake.close()


def test_a_raw_start_waiting_behind_a_slow_write_is_not_sent_after_a_stop(
    gated: tuple[FakeController, _GatedLink],
) -> None:
    # The same for a raw frame (which may also wait for a checksum switch to end).
    fake, link = gated
    rov = Client(link, client_options())
    watched = WatchedLock(rov._wire_lock)
    rov._wire_lock = watched  # type: ignore[assignment]
    try:
        link.gate.clear()
        slow = ThreadCall(lambda: rov.set_max_pwm(180))  # its write waits at the gate
        assert link.held.wait(CONDITION_TIMEOUT_S)
        starting = ThreadCall(lambda: rov.send_raw("#start!"))  # waits for the wire lock
        assert wait_until(lambda: watched.waiting == 1)
        stopping = ThreadCall(rov.stop)
        assert wait_until(lambda: watched.waiting == 2)
        link.gate.set()
        for call in (slow, starting, stopping):
            assert call.done.wait(CONDITION_TIMEOUT_S)
        assert slow.error is None
        assert stopping.error is None
        assert isinstance(starting.error, SupersededByStopError)
        assert fake.wait_for(lambda f: "#stop!" in f.frames())
        assert "#start!" not in fake.frames()
        assert rov.depth_cm() == 123
    finally:
        link.gate.set()
        rov.close()
        fake.close()


async def test_asyncio_a_raw_start_waiting_for_a_checksum_switch_is_not_sent_after_a_stop() -> None:
    # Before, the raw #start! waiting for the switch went out after the #stop! another task
    # sent meanwhile. (The asyncio client's own command methods wait for nothing but a slow
    # serial line, test_line_pacing; here they are written, or queued for the port in call
    # order, before they return.)
    fake, host_end = FakeController.on_socketpair(script=("hold",))
    options = client_options(checksum=True)
    rov = await AsyncClient(SocketLink(host_end, "socket pair"), options).open()
    try:
        held = asyncio.ensure_future(rov.depth_cm())
        assert await wait_until_async(lambda: "#qd!" in fake.frames())
        switching = asyncio.ensure_future(rov.set_checksum(False))
        starting = asyncio.ensure_future(rov.send_raw("#start!"))
        await asyncio.sleep(0)  # (each task runs up to its wait: the switch's, the raw frame's)
        assert rov._switching_mode
        assert not starting.done()
        await rov.stop()
        fake.release()
        assert await asyncio.wait_for(held, CONDITION_TIMEOUT_S) == 123
        await asyncio.wait_for(switching, CONDITION_TIMEOUT_S)
        with pytest.raises(SupersededByStopError, match="#start!"):
            await asyncio.wait_for(starting, CONDITION_TIMEOUT_S)
        assert await rov.depth_cm() == 123
        assert "#start!" not in fake.frames()
        assert fake.frames().index("#stop!") < fake.frames().index("#crcoff!")
    finally:
        await rov.close()
        fake.close()


class _StalledSocketLink(SocketLink):
    """A socket link that takes nothing while the gate is shut (a line with no room)."""

    def __init__(self, sock: socket.socket, description: str) -> None:
        super().__init__(sock, description)
        self.gate = threading.Event()
        self.gate.set()
        #: The thread whose writes the shut gate holds (any thread's if None).
        self.stalled_thread: int | None = None

    def send_some(self, data: bytes | bytearray | memoryview) -> int:
        stalled = self.stalled_thread in (None, threading.get_ident())
        if stalled and not self.gate.is_set():
            return 0
        return super().send_some(data)


async def test_asyncio_a_start_queued_behind_a_stalled_write_goes_before_a_later_stop() -> None:
    # The asyncio client queues each command for the port as it is called: a start() behind a
    # write the line has not taken goes out before a stop() called after it, never after.
    fake, host_end = FakeController.on_socketpair()
    link = _StalledSocketLink(host_end, "socket pair, stalled")
    rov = await AsyncClient(link, client_options()).open()
    try:
        link.gate.clear()
        await rov.set_max_pwm(180)  # task A: waits in the port's buffer
        await rov.start()  # task B
        await rov.stop()  # task C
        link.gate.set()  # (the line has room again)
        assert await wait_until_async(lambda: "#stop!" in fake.frames())
        assert fake.frames()[-3:] == ["#mgmp.180!", "#start!", "#stop!"]
    finally:
        await rov.close()
        fake.close()


async def test_asyncio_a_start_queued_before_an_emergency_stop_is_followed_by_a_stop() -> None:
    # Before, emergency_stop() (from another thread) wrote #stop! at once, and the #start! the
    # loop had queued behind a line slow to take it went out after it: the robot was unlocked.
    fake, host_end = FakeController.on_socketpair()
    link = _StalledSocketLink(host_end, "socket pair, stalled")
    rov = await AsyncClient(link, client_options()).open()
    try:
        link.gate.clear()
        link.stalled_thread = threading.get_ident()  # (the loop's writes wait; others go)
        await rov.start()  # queued for the port
        assert await asyncio.to_thread(rov.emergency_stop)
        assert await wait_until_async(lambda: "#stop!" in fake.frames())
        link.gate.set()
        assert await wait_until_async(lambda: "#start!" in fake.frames())
        assert await wait_until_async(lambda: fake.frames()[-1] == "#stop!")
        frames = fake.frames()
        assert frames.index("#stop!") < frames.index("#start!") < len(frames) - 1
    finally:
        link.gate.set()
        await rov.close()
        fake.close()
