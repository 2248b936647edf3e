"""``emergency_stop()`` called in the asyncio client's own event loop (a signal handler of the
loop, a callback) never blocks the loop, and its ``#stop!`` goes out ahead of everything the loop
had queued, then a stop behind it. It wrote to the port directly before: on a line with no room
the loop stood still for the write timeout (2 s), and the stop was not sent at all."""

from __future__ import annotations

import asyncio
import socket
import threading
from typing import Any

import pytest

from rovlink.aio import AsyncClient
from rovlink.client.links import PortLink, SocketLink
from tests.client.conftest import CONDITION_TIMEOUT_S, client_options, wait_until_async

pytestmark = pytest.mark.integration

#: Half the write timeout (2 s) that the loop was held for: the call takes microseconds, and
#: a loaded machine may not run the test for a while.
_AT_ONCE_S = 1.0


async def _read_until(sock: socket.socket, ending: bytes) -> bytes:
    """What arrives on ``sock`` until it ends with ``ending`` (the loop runs meanwhile)."""
    loop = asyncio.get_running_loop()
    received = bytearray()
    while not received.endswith(ending):
        received += await asyncio.wait_for(loop.sock_recv(sock, 65536), CONDITION_TIMEOUT_S)
    return bytes(received)


async def test_in_the_loop_on_a_line_with_no_room_it_returns_at_once_and_goes_first() -> None:
    ours, theirs = socket.socketpair()
    theirs.setblocking(False)
    link = SocketLink(ours, "socket pair")
    rov = await AsyncClient(link, client_options()).open()
    try:
        while link.send_some(b"x" * 65536):  # the line takes nothing more (nobody reads)
            pass
        await rov.set_max_pwm(180)  # queued in the client's buffer, behind the full line
        loop = asyncio.get_running_loop()
        started = loop.time()
        assert rov.emergency_stop()
        assert loop.time() - started < _AT_ONCE_S
        received = await _read_until(theirs, b"#mgmp.180!#stop!")
        assert received.removeprefix(b"#crcoff!").lstrip(b"x") == b"#stop!#mgmp.180!#stop!"
    finally:
        await rov.close()
        theirs.close()


class _PortWithAStuckWrite:
    """A pyserial-like port without a descriptor (as ``rfc2217://``) whose writes wait while
    the gate is shut: a network that stopped taking bytes."""

    writes_may_wait = True

    def __init__(self) -> None:
        self.timeout: float | None = None
        self.is_open = True
        self.in_waiting = 0
        self.gate = threading.Event()
        self.gate.set()
        self.writing = threading.Event()
        self.written = bytearray()
        self._lock = threading.Lock()

    def read(self, size: int) -> bytes:
        self.gate.wait(self.timeout)  # (nothing ever comes: a read waits its timeout)
        return b""

    def write(self, data: Any) -> int:
        self.writing.set()
        assert self.gate.wait(CONDITION_TIMEOUT_S)
        with self._lock:
            self.written += data
        return len(data)

    def close(self) -> None:
        self.is_open = False
        self.gate.set()


async def test_in_the_loop_behind_a_stuck_write_it_returns_at_once_and_goes_next() -> None:
    port = _PortWithAStuckWrite()
    rov = await AsyncClient(PortLink(port, "stuck port"), client_options()).open()
    try:
        assert await wait_until_async(lambda: bytes(port.written) == b"#crcoff!")
        port.gate.clear()
        port.writing.clear()
        await rov.set_max_pwm(10)  # the writing thread is held in its write of this
        assert await wait_until_async(port.writing.is_set)
        await rov.set_max_pwm(180)  # queued behind it
        loop = asyncio.get_running_loop()
        started = loop.time()
        assert rov.emergency_stop()
        assert loop.time() - started < _AT_ONCE_S
        port.gate.set()
        assert await wait_until_async(lambda: port.written.endswith(b"#mgmp.180!#stop!"))
        assert bytes(port.written) == b"#crcoff!#mgmp.10!#stop!#mgmp.180!#stop!"
    finally:
        port.gate.set()
        await rov.close()
