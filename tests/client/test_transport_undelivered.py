"""What the asyncio client's descriptor transport counts as undelivered when the link is lost:
the frames not wholly written, however long the line has been short of room."""

from __future__ import annotations

import asyncio
import itertools
import socket
import threading

from rovlink.aio.transport import transport_for
from rovlink.client.links import SocketLink
from tests.client.conftest import wait_until_async


class _NarrowLink(SocketLink):
    """A socket link that takes only as many bytes as the test allows (a line short of room)."""

    def __init__(self, sock: socket.socket, description: str) -> None:
        super().__init__(sock, description)
        self._allowance = 0
        self._allowance_lock = threading.Lock()

    def allow(self, count: int) -> None:
        with self._allowance_lock:
            self._allowance += count

    @property
    def allowance(self) -> int:
        with self._allowance_lock:
            return self._allowance

    def send_some(self, data: bytes | bytearray | memoryview) -> int:
        with self._allowance_lock:
            count = min(self._allowance, len(data))
            self._allowance -= count
        return super().send_some(memoryview(data)[:count]) if count else 0


async def test_frames_wholly_written_are_not_undelivered_while_the_buffer_never_drains() -> None:
    # Before, every frame written since the buffer last drained stayed "undelivered": on a line
    # that never quite drained they piled up without end, and a lost link took them all for
    # frames that may not have gone.
    far_end, ours = socket.socketpair()
    link = _NarrowLink(ours, "socket pair, narrow")
    transport = transport_for(link, asyncio.get_running_loop())
    transport.start(lambda data: None, lambda error: None)
    try:
        frames = [f"#th.90.{power}!".encode() for power in range(10, 30)]
        transport.write(frames[0])
        for previous, frame in itertools.pairwise(frames):
            transport.write(frame)
            link.allow(len(previous))  # the line takes one frame's worth: the next stays
            assert await wait_until_async(lambda: link.allowance == 0)
        # The last frame is still waiting, whole; everything before it went.
        assert transport.undelivered == frames[-1]
        link.allow(3)  # part of it goes: it still counts, whole
        assert await wait_until_async(lambda: link.allowance == 0)
        assert transport.undelivered == frames[-1]
        link.allow(len(frames[-1]))
        assert await wait_until_async(lambda: transport.undelivered == b"")
    finally:
        await transport.close()
        far_end.close()


async def test_a_write_cut_short_counts_only_the_frame_it_cut_as_undelivered() -> None:
    far_end, ours = socket.socketpair()
    link = _NarrowLink(ours, "socket pair, narrow")
    transport = transport_for(link, asyncio.get_running_loop())
    transport.start(lambda data: None, lambda error: None)
    try:
        link.allow(len(b"#th.90.40!") + 3)  # the first frame and part of the second
        transport.write(b"#th.90.40!#mvs.+20!")
        assert transport.undelivered == b"#mvs.+20!"
    finally:
        link.allow(100)
        await transport.close()
        far_end.close()
